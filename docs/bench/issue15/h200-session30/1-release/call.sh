#!/usr/bin/env bash
# session 30 call 1 (issue 15): the merge punching out the run pages it has read
# (experiment.diff; XP_NO_RELEASE=1 keeps them until the runs are removed, the committed way).
# scripts/convert-bench.sh with PotreeConverter on a 200 M generated LAS (and LAZ), then
# out of core (--ram-budget 1GiB) with and without the release, alternated.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-r1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W; SECONDS=0
POINTLET=/tmp/pointlet POINTS=200M ROUNDS=2 POTREE_ROUNDS=1 POTREE=.dev/potree/run.sh bash scripts/convert-bench.sh /tmp/cb $W
cat /tmp/cb/summary.txt; echo "at $SECONDS s"
L=$W/gen-200M.las; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
for r in 1 2; do
  XP_NO_RELEASE=1 C ooc-keep-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
  C ooc-release-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done
C mem-3 /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
