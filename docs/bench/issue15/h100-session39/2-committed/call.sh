#!/usr/bin/env bash
# Session 39, call 2 (issue 15): the committed code (11aa57f: runs gathered into a mapping of
# their file, keys eight at a time with BMI2) against 474e833, alternated: 200 M LAS in memory
# and out of core at 1 GiB, two rounds each; 200 M LAZ `bench-read` and convert, two rounds;
# every store compared byte for byte with the first of its input. Then 11aa57f's in-memory LAS
# build under perf record, split at the end of the reading stage.
# Binaries built here (x86-64), stripped and carried as xz (the tracked tree is ~28 MB of the
# 64 MiB that travels): `git checkout C && cargo build --release -p pointlet && objcopy
# --strip-debug target/release/pointlet /tmp/p && xz -9 -c /tmp/p > .dev/pointlet-sN.xz`
# (s3 = 474e833 + the XP_SPILLERS experiment.diff, which changes nothing unset; s5 = 11aa57f);
# the Debian `time` .deb and perf with its libraries as in session 38's call
# (docs/bench/issue15/h100-session38/2-zeroed/call.sh), in .dev/, which a fresh checkout must
# ignore first: `mkdir -p .git/info && echo /.dev/ >> .git/info/exclude`.
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-s3.xz",
#   ".dev/pointlet-s5.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/perfpk.tgz"]) -- about 4 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 3 5; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; grep -o -m1 -w bmi2 /proc/cpuinfo; uname -r
L=$W/g.las
/tmp/ps3 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
C las-read /tmp/ps5 bench-read $L
for r in 1 2; do
  C mem-s3-$r /tmp/ps3 $M --ram-budget 24GiB
  S mem-s5-$r /tmp/ps5 $M --ram-budget 24GiB
  C ooc-s3-$r /tmp/ps3 $M --ram-budget 1GiB --tmp $W
  S ooc-s5-$r /tmp/ps5 $M --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
P() { local name=$1; shift; $PERF record -F 999 -o $W/$name.data "$@" > /tmp/cb/$name.txt 2>&1; rm -f $W/s.pointlet; sync
  grep -E '^wrote' /tmp/cb/$name.txt
  local rd=$(grep -oE 'reading [0-9.]+ s' /tmp/cb/$name.txt | grep -oE '[0-9.]+')
  local t0=$($PERF script -i $W/$name.data -F time 2>/dev/null | head -1 | tr -d ' :')
  if [ -n "$rd" ] && [ -n "$t0" ]; then local t1=$(awk "BEGIN{printf \"%.6f\", $t0 + $rd}")
    for part in read:",$t1" write:"$t1,"; do
      $PERF report -i $W/$name.data --no-children --sort sym --time "${part#*:}" 2>/dev/null | grep -v '^#' | grep '%' | head -45 > /tmp/cb/$name-${part%%:*}.txt
    done
  fi; rm -f $W/$name.data; }
P perf-mem /tmp/ps5 $M --ram-budget 24GiB
rm -f $L $W/ref.pointlet; /tmp/ps3 generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in 1 2; do
  C laz-read-$r /tmp/ps5 bench-read $W/g.laz
  C laz-s3-$r /tmp/ps3 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  S laz-s5-$r /tmp/ps5 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
for f in perf-mem-read perf-mem-write; do echo "== $f"; head -25 /tmp/cb/$f.txt; done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
