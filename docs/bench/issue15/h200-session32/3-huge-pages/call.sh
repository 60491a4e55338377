#!/usr/bin/env bash
# session 32 call 3 (issue 15): 2 MiB pages under the build's run buffers and radix scratch
# (madvise MADV_HUGEPAGE) against 4 KiB pages (XP_NOHUGE=1), alternated: the 200 M LAS in
# memory (--ram-budget 24GiB) three rounds, out of core (--ram-budget 1GiB) two; AnonHugePages
# sampled once a second into each in-memory build.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t3.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
grep -H . /sys/kernel/mm/transparent_hugepage/enabled /sys/kernel/mm/transparent_hugepage/defrag
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1 & local pid=$!
  sleep 1.5; local h=$(pgrep -f "pointlet convert" | head -1); [ -n "$h" ] && grep AnonHuge /proc/$h/smaps_rollup 2>/dev/null | tr -s ' '; wait $pid
  echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
M="convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB"
O="convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W"
for r in 1 2 3; do
  XP_NOHUGE=1 C mem-4k-$r /tmp/pointlet $M
  C mem-2m-$r /tmp/pointlet $M
done
for r in 1 2; do
  XP_NOHUGE=1 C ooc-4k-$r /tmp/pointlet $O
  C ooc-2m-$r /tmp/pointlet $O
done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
