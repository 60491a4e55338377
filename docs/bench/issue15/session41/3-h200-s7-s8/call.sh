#!/usr/bin/env bash
# Session 41, third call: s7 (1467bd6) against s8 (this session's build: big buckets' sub-buckets
# sorted in parallel, the radix pass's offsets summed in parallel, records staged whole before the
# streams are split out of them, run files gathered a 2 MiB page per task), alternated in the same
# run: 200 M LAS in memory and out of core (1 GiB), two rounds each; 200 M LAZ bench-read and
# convert, two rounds; every store compared byte for byte with s7's first. Then where s8's
# out-of-core build waits (system-wide sched_switch, offcpu.py; s8 has no frame pointers, so the
# user part of each stack is only its innermost frame).
# Binaries: `cargo build --release -p pointlet`, `objcopy --strip-debug`, `xz -9` into .dev/.
# Run: run(command="bash docs/bench/issue15/session41/3-h200-s7-s8/call.sh", carry=[".dev/pointlet-s7.xz",
#   ".dev/pointlet-s8.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/perfpk.tgz"]) -- about 4 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
HERE=$(cd "$(dirname "$0")" && pwd)
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 7 8; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
L=$W/g.las
/tmp/ps8 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.05; done) > $R/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
C las-read /tmp/ps8 bench-read $L
for r in 1 2; do
  S mem-s7-$r /tmp/ps7 $M --ram-budget 24GiB
  S mem-s8-$r /tmp/ps8 $M --ram-budget 24GiB
  S ooc-s7-$r /tmp/ps7 $M --ram-budget 1GiB --tmp $W
  S ooc-s8-$r /tmp/ps8 $M --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
$PERF record -a -g -e sched:sched_switch -o $W/off.data -- /tmp/ps8 $M --ram-budget 1GiB --tmp $W > $R/off-ooc.txt 2>&1
rm -f $W/s.pointlet; sync; grep -E '^wrote' $R/off-ooc.txt
rd=$(grep -oE 'reading [0-9.]+ s' $R/off-ooc.txt | grep -oE '[0-9.]+')
$PERF script -i $W/off.data -F comm,tid,time,event,trace,ip,sym --max-stack 24 2>/dev/null \
  | awk 'NF == 0 { if (keep) print ""; keep = 0; next } /sched:sched_switch:/ { keep = /comm=ps8/ } keep' > $W/off.txt
python3 $HERE/../../offcpu.py ps8 12 ${rd:-0} < $W/off.txt > $OUT/off-ooc-waits.txt
rm -f $W/off.data $W/off.txt
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/ps8 generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in 1 2; do
  C laz-read-$r /tmp/ps8 bench-read $W/g.laz
  S laz-s7-$r /tmp/ps7 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  S laz-s8-$r /tmp/ps8 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
echo "at $SECONDS s"
head -40 $OUT/off-ooc-waits.txt | cut -c1-250
cd $R && tar czf $OUT/runs.tgz *
rm -rf $W
