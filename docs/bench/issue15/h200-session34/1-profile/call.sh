#!/usr/bin/env bash
# session 34 call 1 (issue 15): where out-of-core (1 GiB) and LAZ conversion spend their time:
# dd278fc (pointlet-u1) under perf record, flat by symbol, split at the end of the reading stage;
# LAZ decode (bench-read) under perf for comparison; one plain in-memory and out-of-core run.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-u1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-190) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
# perf record of a command; reports for the whole run, before and after the reading stage ends.
P() { local name=$1; shift; $PERF record -F 999 -o $W/$name.data "$@" > /tmp/cb/$name.txt 2>&1; rm -f $W/s.pointlet; sync
  grep -E '^wrote|^decoded' /tmp/cb/$name.txt
  local rd=$(grep -oE 'reading [0-9.]+ s' /tmp/cb/$name.txt | grep -oE '[0-9.]+')
  local t0=$($PERF script -i $W/$name.data -F time 2>/dev/null | head -1 | tr -d ' :')
  $PERF report -i $W/$name.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -45 > /tmp/cb/$name-all.txt
  $PERF report -i $W/$name.data --no-children --sort comm 2>/dev/null | grep -v '^#' | grep '%' | head -12 > /tmp/cb/$name-comm.txt
  if [ -n "$rd" ] && [ -n "$t0" ]; then local t1=$(awk "BEGIN{printf \"%.6f\", $t0 + $rd}")
    $PERF report -i $W/$name.data --no-children --sort sym --time ",$t1" 2>/dev/null | grep -v '^#' | grep '%' | head -45 > /tmp/cb/$name-read.txt
    $PERF report -i $W/$name.data --no-children --sort sym --time "$t1," 2>/dev/null | grep -v '^#' | grep '%' | head -45 > /tmp/cb/$name-write.txt
    $PERF report -i $W/$name.data --no-children --sort comm --time ",$t1" 2>/dev/null | grep -v '^#' | grep '%' | head -12 > /tmp/cb/$name-read-comm.txt
    $PERF report -i $W/$name.data --no-children --sort comm --time "$t1," 2>/dev/null | grep -v '^#' | grep '%' | head -12 > /tmp/cb/$name-write-comm.txt
  fi; rm -f $W/$name.data; }
C mem-1 /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 24GiB
C ooc-1 /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
P perf-ooc /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
echo "at $SECONDS s"
rm -f $L; /tmp/pointlet generate --points 200M -o $Z 2>&1 | tail -1
sync; cat $Z > /dev/null
C laz-read /tmp/pointlet bench-read $Z; tail -n 2 /tmp/cb/laz-read.txt | head -1
C laz-1 /tmp/pointlet convert $Z -o $W/s.pointlet --ram-budget 24GiB
P perf-laz /tmp/pointlet convert $Z -o $W/s.pointlet --ram-budget 24GiB
P perf-lazread /tmp/pointlet bench-read $Z
echo "at $SECONDS s"
for f in perf-ooc-read perf-ooc-read-comm perf-ooc-write perf-ooc-write-comm perf-laz-read perf-laz-write perf-laz-write-comm perf-lazread-all; do echo "== $f"; head -25 /tmp/cb/$f.txt; done
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
