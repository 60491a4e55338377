#!/usr/bin/env bash
# Session 39, issue 15, out of core at 1 GiB and LAZ's tail. Session 38's calls found the
# out-of-core reading stage at ~9.5 of 16 cores for 2.8 s (docs/bench/issue15/h100-session38/
# 2-zeroed/cpu-ooc-z2.txt): two spilling threads write 7 GB of runs through `write`, one thread
# a run, 4.2 s in all. Two binaries, both with `experiment.diff` (XP_SPILLERS sets the number of
# spilling threads; the budget is shared by the filling run and those spilling):
#   s3 = 474e833 (runs written through `write`), s4 = s3 + runs gathered straight into a mapping
#   of their file in 2 MiB pages (runs::RunMaps).
# 200 M LAS: in memory, then out of core at 1 GiB, s3/s4 with 2 and 4 spillers (s4 also 6),
# alternated, two rounds; every store compared byte for byte with the first. Then s4 out of
# core and LAZ in memory under perf record, flat by symbol and by thread, split at the end of
# the reading stage.
# Binaries, built here (x86-64), stripped and carried as xz (the tracked tree is ~28 MB of the
# 64 MiB that travels): for each, the tree in that state + experiment.diff (by hand where it
# does not apply), `cargo build --release -p pointlet`, `objcopy --strip-debug
# target/release/pointlet /tmp/p && xz -9 -c /tmp/p > .dev/pointlet-sN.xz` (the symbol table
# stays, for perf); with the Debian `time` .deb (`apt-get download time`) and perf with its
# libraries in .dev/ (`mkdir -p /tmp/perfpk/lib && cp /usr/bin/perf /tmp/perfpk/ && ldd
# /usr/bin/perf | awk '/=>/ {print $3} /ld-linux/ {print $1}' | xargs -I{} cp -L {}
# /tmp/perfpk/lib/ && tar czf .dev/perfpk.tgz -C /tmp perfpk`), which a fresh checkout must
# ignore first: `mkdir -p .git/info && echo /.dev/ >> .git/info/exclude`.
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-s3.xz",
#   ".dev/pointlet-s4.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/perfpk.tgz"]) -- about 5 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 3 4; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; free -g | head -2; df -h /tmp | tail -1; uname -r
L=$W/g.las
/tmp/ps3 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
C mem /tmp/ps3 $M --ram-budget 24GiB
for r in 1 2; do
  for vs in 3:2 4:2 3:4 4:4 4:6; do
    v=${vs%:*} s=${vs#*:}
    if [ $r = 1 ]; then S ooc-s$v-sp$s env XP_SPILLERS=$s /tmp/ps$v $M --ram-budget 1GiB --tmp $W
    else C ooc-s$v-sp$s-$r env XP_SPILLERS=$s /tmp/ps$v $M --ram-budget 1GiB --tmp $W; fi
  done
  C mem-$r /tmp/ps4 $M --ram-budget 24GiB
done
echo "at $SECONDS s"
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
# perf record of a command; reports for the whole run, before and after the reading stage ends.
P() { local name=$1; shift; $PERF record -F 999 -o $W/$name.data "$@" > /tmp/cb/$name.txt 2>&1; rm -f $W/s.pointlet; sync
  grep -E '^wrote' /tmp/cb/$name.txt
  local rd=$(grep -oE 'reading [0-9.]+ s' /tmp/cb/$name.txt | grep -oE '[0-9.]+')
  local t0=$($PERF script -i $W/$name.data -F time 2>/dev/null | head -1 | tr -d ' :')
  $PERF report -i $W/$name.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -45 > /tmp/cb/$name-all.txt
  if [ -n "$rd" ] && [ -n "$t0" ]; then local t1=$(awk "BEGIN{printf \"%.6f\", $t0 + $rd}")
    for part in read:",$t1" write:"$t1,"; do
      $PERF report -i $W/$name.data --no-children --sort sym --time "${part#*:}" 2>/dev/null | grep -v '^#' | grep '%' | head -45 > /tmp/cb/$name-${part%%:*}.txt
      $PERF report -i $W/$name.data --no-children --sort comm --time "${part#*:}" 2>/dev/null | grep -v '^#' | grep '%' | head -12 > /tmp/cb/$name-${part%%:*}-comm.txt
    done
  fi; rm -f $W/$name.data; }
P perf-ooc /tmp/ps4 $M --ram-budget 1GiB --tmp $W
rm -f $L $W/ref.pointlet; /tmp/ps3 generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
C laz-read /tmp/ps4 bench-read $W/g.laz
S laz-s4 /tmp/ps4 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
P perf-laz /tmp/ps4 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
for f in perf-ooc-read perf-ooc-read-comm perf-ooc-write perf-ooc-write-comm perf-laz-write perf-laz-write-comm; do echo "== $f"; head -25 /tmp/cb/$f.txt; done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
