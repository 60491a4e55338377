#!/usr/bin/env bash
# session 33 call 2 (issue 15): in-memory builds write the store through a mapping of 2 MiB
# pages (code.diff against bc066cd; pointlet-t7) against bc066cd (pointlet-t6), alternated,
# 200 M generated LAS, page cache warm, `sync` after each run; byte-identical stores checked;
# PotreeConverter in the same call; out of core (1 GiB) once; LAZ: decode and convert.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t6.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-t7.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-170) | $(tail -1 /tmp/cb/$name.txt)"; sync; }
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2 3; do
  C mem-new-$r /tmp/pointlet $M; mv $W/s.pointlet $W/ref.pointlet; sync
  C mem-old-$r /tmp/pold $M; cmp $W/s.pointlet $W/ref.pointlet && echo "   identical"; rm -f $W/s.pointlet; sync
done
C potree .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree; sync
C ooc-new-1 /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W; cmp $W/s.pointlet $W/ref.pointlet && echo "   identical"; rm -f $W/s.pointlet $W/ref.pointlet; sync
C mem-new-4 /tmp/pointlet $M; rm -f $W/s.pointlet; sync
echo "at $SECONDS s"
/tmp/pointlet generate --points 200M -o $Z 2>&1 | tail -1
rm -f $L; sync; cat $Z > /dev/null
C laz-read /tmp/pointlet bench-read $Z; tail -3 /tmp/cb/laz-read.txt
C laz-new /tmp/pointlet convert $Z -o $W/s.pointlet --ram-budget 24GiB; rm -f $W/s.pointlet; sync
C laz-old /tmp/pold convert $Z -o $W/s.pointlet --ram-budget 24GiB; rm -f $W/s.pointlet; sync
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
