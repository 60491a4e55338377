#!/usr/bin/env bash
# As run in session 41 from docs/bench/issue15/next-call/, beside offcpu.py (now ../../offcpu.py).
# Prepared in session 40 for the next lent GPU machine (issue 15), not yet run. s7 = 1467bd6
# (session 39's final code: cheaper keys, a group's run pages given back once per piece), s7fp
# = the same built with frame pointers for stacks. The out-of-core build keeps ~11.5 of 16
# cores busy in both stages (session 39's CPU samples) and the in-memory writing stage drops to
# 3-5 busy cores for a tenth of a second several times: this call finds out where the threads
# wait, with a system-wide `perf record -e sched:sched_switch -g` read back by offcpu.py (waits
# by stack, and a timeline of idle pool threads against waits in the kernel), and an on-CPU
# profile with call stacks. Then the figures the acceptance needs, as in session 39: 200 M LAS
# in memory and out of core at 1 GiB, two rounds, PotreeConverter once; 200 M LAZ
# `bench-read` and convert, two rounds. Every store compared byte for byte with the first.
# Binaries built here (x86-64), stripped and carried as xz: for s7 `git checkout 1467bd6 &&
# cargo build --release -p pointlet`, for s7fp the same with RUSTFLAGS="-C
# force-frame-pointers=yes" and `--target-dir /tmp/fpt`; then `objcopy --strip-debug BIN
# /tmp/p && xz -9 -c /tmp/p > .dev/pointlet-s7.xz` (and -s7fp); the Debian `time` .deb (`apt-get
# download time`), perf with its libraries (.dev/perfpk.tgz, as in session 38's call) and
# PotreeConverter (`cp -r ../shared/tools/potree-converter .dev/potree`), in .dev/, which a
# fresh checkout must ignore first: `mkdir -p .git/info && echo /.dev/ >> .git/info/exclude`.
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-s7.xz",
#   ".dev/pointlet-s7fp.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/perfpk.tgz", ".dev/potree"])
#   -- about 5 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
HERE=$(cd "$(dirname "$0")" && pwd)
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 7 7fp; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; uname -r; command -v python3
cat /proc/sys/vm/dirty_ratio /proc/sys/vm/dirty_background_ratio /proc/sys/vm/dirty_bytes 2>/dev/null | tr '\n' ' '; echo
L=$W/g.las
/tmp/ps7 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
# Off the CPU: the switches of every thread, kept for this program's threads only.
OFF() { local name=$1; shift; $PERF record -a -g -e sched:sched_switch -o $W/$name.data -- "$@" > /tmp/cb/$name.txt 2>&1
  rm -f $W/s.pointlet; sync; grep -E '^wrote' /tmp/cb/$name.txt
  local rd=$(grep -oE 'reading [0-9.]+ s' /tmp/cb/$name.txt | grep -oE '[0-9.]+')
  $PERF script -i $W/$name.data -F comm,tid,time,event,trace,ip,sym --max-stack 24 2>/dev/null \
    | awk 'NF == 0 { if (keep) print ""; keep = 0; next } /sched:sched_switch:/ { keep = /comm=ps7fp/ } keep' > $W/$name.txt
  gzip -c $W/$name.txt > $OUT/$name.txt.gz
  command -v python3 > /dev/null && python3 $HERE/offcpu.py ps7fp 10 ${rd:-0} < $W/$name.txt > $OUT/$name-waits.txt
  rm -f $W/$name.data $W/$name.txt; }
# On the CPU, with call stacks, split at the end of the reading stage.
ON() { local name=$1; shift; $PERF record -F 499 -g -o $W/$name.data -- "$@" > /tmp/cb/$name.txt 2>&1
  rm -f $W/s.pointlet; sync
  local rd=$(grep -oE 'reading [0-9.]+ s' /tmp/cb/$name.txt | grep -oE '[0-9.]+')
  local t0=$($PERF script -i $W/$name.data -F time 2>/dev/null | head -1 | tr -d ' :')
  if [ -n "$rd" ] && [ -n "$t0" ]; then local t1=$(awk "BEGIN{printf \"%.6f\", $t0 + $rd}")
    for part in read:",$t1" write:"$t1,"; do
      $PERF report -i $W/$name.data --children --sort sym --time "${part#*:}" -g none 2>/dev/null | grep -v '^#' | grep '%' | head -70 > $OUT/$name-${part%%:*}.txt
    done
  fi; rm -f $W/$name.data; }
M="convert $L -o $W/s.pointlet"
C las-read /tmp/ps7 bench-read $L
for r in 1 2; do
  S mem-s7-$r /tmp/ps7 $M --ram-budget 24GiB
  S ooc-s7-$r /tmp/ps7 $M --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
OFF off-ooc /tmp/ps7fp $M --ram-budget 1GiB --tmp $W
OFF off-mem /tmp/ps7fp $M --ram-budget 24GiB
ON on-ooc /tmp/ps7fp $M --ram-budget 1GiB --tmp $W
echo "at $SECONDS s"
S potree bash .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/ps7 generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in 1 2; do
  C laz-read-$r /tmp/ps7 bench-read $W/g.laz
  S laz-s7-$r /tmp/ps7 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
OFF off-laz /tmp/ps7fp convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
for f in $OUT/off-*-waits.txt; do echo "== $f"; head -40 "$f" | cut -c1-220; done
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
