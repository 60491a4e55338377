#!/usr/bin/env bash
# session 30 call 2 (issue 15): out of core (--ram-budget 1GiB), 200 M generated LAS: the spillers'
# sorting and gathering in a rayon pool of their own (XP_SPILL_POOL=N threads) instead of the
# decoders' pool, with 2 / 3 / 4 runs spilling at once (XP_SPILLERS), the merge releasing
# read run pages (default) or not (XP_NO_RELEASE=1); three rounds alternated; in memory
# before and after.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-r2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 2; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2 3; do
  C ooc-base-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  XP_SPILL_POOL=16 C ooc-pool16-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  XP_SPILL_POOL=16 XP_SPILLERS=3 C ooc-pool16-s3-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  XP_SPILL_POOL=16 XP_SPILLERS=4 C ooc-pool16-s4-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  XP_SPILL_POOL=8 C ooc-pool8-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  XP_NO_RELEASE=1 XP_SPILL_POOL=16 C ooc-pool16-keep-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
