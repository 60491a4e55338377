#!/usr/bin/env bash
# session 34 call 2 (issue 15): out of core through mappings (run files gathered into by every
# core, the store written by the merge's key ranges into a mapping; pointlet-u2) against dd278fc
# (pointlet-u1), alternated; in memory for the ratio. (No perf: the carry limit.)
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-u1.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-u2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-190) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
M="convert $L -o $W/s.pointlet"
C mem-1 /tmp/pointlet $M --ram-budget 24GiB
for r in 1 2 3; do
  C ooc-new-$r /tmp/pointlet $M --ram-budget 1GiB --tmp $W
  C ooc-old-$r /tmp/pold $M --ram-budget 1GiB --tmp $W
done
C mem-2 /tmp/pointlet $M --ram-budget 24GiB
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
