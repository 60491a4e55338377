#!/usr/bin/env bash
# session 30 call 4 (issue 15): the radix pass's bucket count chosen for the number of pairs
# (~4096 pairs a bucket, at most 2^16; default) against a fixed 2^16 (XP_RADIX_FIXED=1, the
# committed way), with the merge releasing read run pages; 200 M generated LAS, in memory
# and out of core (--ram-budget 1GiB), alternated; then scripts/convert-bench.sh with
# PotreeConverter on the same LAS (and a LAZ of it) with the new default.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-r4.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/gen-200M.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
for r in 1 2; do
  XP_RADIX_FIXED=1 C mem-fixed-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 24GiB
  C mem-bits-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 24GiB
done
for r in 1 2 3; do
  XP_RADIX_FIXED=1 C ooc-fixed-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  C ooc-bits-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
POINTLET=/tmp/pointlet POINTS=200M ROUNDS=2 POTREE_ROUNDS=1 POTREE=.dev/potree/run.sh bash scripts/convert-bench.sh /tmp/cb/bench $W > /dev/null 2>&1
cat /tmp/cb/bench/summary.txt; echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt bench
rm -rf $W
