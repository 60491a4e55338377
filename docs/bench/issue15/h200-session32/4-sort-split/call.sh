#!/usr/bin/env bash
# session 32 call 4 (issue 15): is the bucket sort slow on this machine or starved? The
# store crate's ignored `sort_time_of_surface_points` (5 M surface keys, 16 threads) with the
# radix-recursive bucket sort and with comparison sorts only (XL=100000); then the 200 M LAS in
# memory with XP_TRACE (the writing stage split into bucket sorting and block packing) twice,
# and out of core once.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t4.gz > /tmp/pointlet && chmod +x /tmp/pointlet
gunzip -c .dev/storetest-t4.gz > /tmp/storetest && chmod +x /tmp/storetest
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
grep -m1 "model name" /proc/cpuinfo; nproc
for v in "" "XL=100000"; do echo "sort test $v"; env $v /tmp/storetest sort_time --ignored --nocapture 2>&1 | grep round; done
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
C() { local name=$1; shift; XP_TRACE=1 /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1
  echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; grep "XP in" /tmp/cb/$name.txt
  grep "XP spill" /tmp/cb/$name.txt | awk '{s+=$(NF-4); w+=$(NF-1)} END {if (NR) printf "   spill: sort %.1f ms, write_run %.1f ms (%d runs)\n", s/NR, w/NR, NR}'; rm -f $W/s.pointlet; sync; }
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
XL=100000 C mem-cmp /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
C ooc-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
