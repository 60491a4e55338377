#!/usr/bin/env bash
# session 29 call 5 (issue 15): out-of-core conversion (--ram-budget 1GiB) with 1 / 2 / 3 runs spilling
# at once (XP_SPILLERS; runs of budget / (spillers + 1)), each run written by 1 or 2 threads
# (XP_SPILL_WRITERS), the radix pass's second array kept from run to run; alternated, 200 M LAS.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-s2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 2; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' $OUT/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(grep xp-spill $OUT/$name.txt | cut -c10-) | $(tail -1 $OUT/$name.txt)"; rm -f $W/s.pointlet; sync; }
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2; do for sp in 1 2 3; do
  XP_SPILL_TRACE=1 XP_SPILLERS=$sp XP_SPILL_WRITERS=1 C ooc-s$sp-w1-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done; done
for sp in 2 3; do XP_SPILL_TRACE=1 XP_SPILLERS=$sp XP_SPILL_WRITERS=2 C ooc-s$sp-w2-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W; done
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd $OUT && tar czf runs.tgz *.txt && rm -f ooc-*.txt mem-*.txt
rm -rf $W
