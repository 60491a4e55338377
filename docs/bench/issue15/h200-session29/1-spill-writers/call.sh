#!/usr/bin/env bash
# session 29 call 4 (issue 15): out-of-core conversion with each run file written by 1 / 2 / 4
# threads (XP_SPILL_WRITERS; positioned writes of contiguous shares), alternated, 200 M generated LAS,
# page cache warm; XP_SPILL_TRACE prints the spiller's sort / gather+write time and how long filling
# waited for it. In-memory conversion once for the ratio; perf of one out-of-core build.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-s1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
W=/tmp/w; mkdir -p $W; SECONDS=0
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 2; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' $OUT/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-160) | $(grep xp-spill $OUT/$name.txt) | $(tail -1 $OUT/$name.txt)"; rm -f $W/s.pointlet; }
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2; do for w in 1 2 4; do
  XP_SPILL_TRACE=1 XP_SPILL_WRITERS=$w C ooc-w$w-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done; done
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
XP_SPILL_TRACE=1 XP_SPILL_WRITERS=2 LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf record -F 999 -g -o $W/p.data /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W > $OUT/perf-run.txt 2>&1
grep -E "^wrote|xp-spill" $OUT/perf-run.txt
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf report -i $W/p.data --no-children --sort comm,dso,sym 2>/dev/null | grep -v '^#' | grep '%' | grep -v "^ *|\|--" | head -60 > $OUT/perf-comm-sym.txt
echo "at $SECONDS s"
rm -rf $W
