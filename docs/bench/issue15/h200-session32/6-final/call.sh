#!/usr/bin/env bash
# session 32 call 6 (issue 15): the final code (code.diff against 40576b9: the buckets of a
# spilled run sorted with the radix pass's first array as their second, so no memory beyond
# the two arrays the budget counts) against call 5's build, alternated, 200 M generated LAS,
# page cache warm, `sync` after each run: in memory and out of core (--ram-budget 1GiB).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t5.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-t6.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; sync; }
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
O="convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W"
C mem-new-1 /tmp/pointlet $M; mv $W/s.pointlet $W/ref.pointlet; sync
C mem-old-1 /tmp/pold $M; cmp $W/s.pointlet $W/ref.pointlet && echo "   identical"; rm -f $W/s.pointlet; sync
for r in 1 2; do
  C ooc-new-$r /tmp/pointlet $O; cmp $W/s.pointlet $W/ref.pointlet && echo "   identical"; rm -f $W/s.pointlet; sync
  C ooc-old-$r /tmp/pold $O; rm -f $W/s.pointlet; sync
done
C mem-new-2 /tmp/pointlet $M; rm -f $W/s.pointlet; sync
C mem-old-2 /tmp/pold $M; rm -f $W/s.pointlet
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
