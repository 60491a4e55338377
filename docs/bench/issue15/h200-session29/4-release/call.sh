#!/usr/bin/env bash
# session 29 call 7 (issue 15): the candidate (two runs spilling at once, the radix scratch kept) with
# the merge punching out the run pages it has read (default) or not (XP_NO_RELEASE=1), alternated,
# out of core (--ram-budget 1GiB), 200 M generated LAS; in memory before and after.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-s4.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 2; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' $OUT/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 $OUT/$name.txt)"; rm -f $W/s.pointlet; sync; }
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2 3; do
  C ooc-release-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  XP_NO_RELEASE=1 C ooc-keep-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd $OUT && tar czf runs.tgz *.txt && rm -f ooc-*.txt mem-*.txt
rm -rf $W
