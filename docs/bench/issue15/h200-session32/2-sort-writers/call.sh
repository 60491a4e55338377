#!/usr/bin/env bash
# session 32 call 2 (issue 15): the 200 M LAS out of core (--ram-budget 1GiB), alternated:
# call 1's build (old bucket sort: rayon's parallel merge sort for buckets > 64 Ki pairs) against
# this build's radix-recursive bucket sort (defaults, and XL=1024 XD=16: leaves of 1024, ~16
# pairs a sub-bucket), each run written by 4 threads (XP_WRITERS=4), and with 3 spillers
# (XP_SPILLERS=3); XP_TRACE on (per-run sort / write times). In memory before and after.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t1.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-t2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
C() { local name=$1; shift; XP_TRACE=1 /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; grep "XP spill" /tmp/cb/$name.txt | awk '{s+=$(NF-4); w+=$(NF-1)} END {if (NR) printf "   spill: sort %.1f ms, write_run %.1f ms (%d runs)\n", s/NR, w/NR, NR}'; grep "XP write_run" /tmp/cb/$name.txt | awk '{s+=$4; w+=$7} END {if (NR) printf "   write %.1f ms, gather %.1f ms\n", s/NR, w/NR}'; grep "XP fill" /tmp/cb/$name.txt | awk '{s+=$(NF-1)} END {if (NR) printf "   fill waited %.2f s\n", s/1000}'; rm -f $W/s.pointlet; sync; }
O="convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W"
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2; do
  C old-$r /tmp/pold $O
  C new-$r /tmp/pointlet $O
  XL=1024 XD=16 C new1024-$r /tmp/pointlet $O
  XP_WRITERS=4 C w4-$r /tmp/pointlet $O
  XP_WRITERS=4 XP_SPILLERS=3 C w4s3-$r /tmp/pointlet $O
done
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
