#!/usr/bin/env bash
# session 32 call 5 (issue 15): the committed code (code.diff against afe15bb: buckets sized by
# the keys' occupied cells, radix-recursive bucket sorts, 2 MiB pages under the run buffers, the
# in-memory writing stage sorting stretches of buckets while the previous stretch is written)
# against call 4's build (per-block bucket sorting), the 200 M generated LAS, page cache warm,
# `sync` after each run: in memory alternated, PotreeConverter in the same call, out of core
# (--ram-budget 1GiB) twice; byte-identical stores checked.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t4.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-t5.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; sync; }
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2; do
  C mem-new-$r /tmp/pointlet $M; mv $W/s.pointlet $W/ref.pointlet
  C mem-old-$r /tmp/pold $M; cmp $W/s.pointlet $W/ref.pointlet && echo "   identical"; rm -f $W/s.pointlet $W/ref.pointlet; sync
done
C potree .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree; sync
C mem-new-3 /tmp/pointlet $M; mv $W/s.pointlet $W/ref.pointlet; sync
for r in 1 2; do C ooc-new-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W; cmp $W/s.pointlet $W/ref.pointlet && echo "   identical"; rm -f $W/s.pointlet; sync; done
C mem-new-4 /tmp/pointlet $M; rm -f $W/s.pointlet
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
