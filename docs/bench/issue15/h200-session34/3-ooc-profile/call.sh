#!/usr/bin/env bash
# session 34 call 3 (issue 15): where out of core through mappings (pointlet-u2) spends its
# time: perf record, flat by symbol, split at the end of the reading stage (dd278fc's profile is
# call 1's); a second run with call graphs for the kernel's share.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-u2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
M="convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W"
P() { local name=$1; shift; $PERF record "$@" -o $W/$name.data /tmp/pointlet $M > /tmp/cb/$name.txt 2>&1; rm -f $W/s.pointlet; sync
  grep -E '^wrote' /tmp/cb/$name.txt
  local rd=$(grep -oE 'reading [0-9.]+ s' /tmp/cb/$name.txt | grep -oE '[0-9.]+')
  local t0=$($PERF script -i $W/$name.data -F time 2>/dev/null | head -1 | tr -d ' :')
  local t1=$(awk "BEGIN{printf \"%.6f\", $t0 + $rd}")
  $PERF report -i $W/$name.data --no-children --sort sym --time ",$t1" 2>/dev/null | grep -v '^#' | grep '%' | head -60 > /tmp/cb/$name-read.txt
  $PERF report -i $W/$name.data --no-children --sort sym --time "$t1," 2>/dev/null | grep -v '^#' | grep '%' | head -60 > /tmp/cb/$name-write.txt
  $PERF report -i $W/$name.data --no-children --sort dso --time ",$t1" 2>/dev/null | grep -v '^#' | grep '%' | head -5 > /tmp/cb/$name-read-dso.txt
  $PERF report -i $W/$name.data --no-children --sort dso --time "$t1," 2>/dev/null | grep -v '^#' | grep '%' | head -5 > /tmp/cb/$name-write-dso.txt
  if [ "$name" = graph ]; then $PERF report -i $W/$name.data --children --sort sym -g caller,0.5,callee --percent-limit 3 2>/dev/null | grep -v '^#' | head -300 > /tmp/cb/$name-tree.txt; fi
  rm -f $W/$name.data; }
P flat -F 999
P graph -F 499 -g
echo "at $SECONDS s"
for f in flat-read-dso flat-read flat-write-dso flat-write; do echo "== $f"; head -32 /tmp/cb/$f.txt; done
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
