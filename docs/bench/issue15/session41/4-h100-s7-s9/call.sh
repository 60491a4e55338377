#!/usr/bin/env bash
# Session 41, fourth call: the acceptance figures of s9 against s7 (1467bd6), alternated in one
# run, three rounds each. s9 = this session's code: big buckets' sub-buckets sorted in
# parallel, the radix pass's offsets summed in parallel, records staged whole before the streams
# are split out of them, run files gathered a 2 MiB page per task, temporary files unlinked
# outside the registry's lock. 200 M LAS in memory and out of core (1 GiB); PotreeConverter
# once; 200 M LAZ bench-read and convert. Every store compared byte for byte with s7's first.
# Binaries: `cargo build --release -p pointlet`, `objcopy --strip-debug`, `xz -9` into .dev/.
# Run: run(command="bash docs/bench/issue15/session41/4-h100-s7-s9/call.sh", carry=[
#   ".dev/pointlet-s7.xz", ".dev/pointlet-s9.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/potree"])
#   -- about 5 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 7 9; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
L=$W/g.las
/tmp/ps9 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.05; done) > $R/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
C las-read /tmp/ps9 bench-read $L
for r in 1 2 3; do
  S mem-s7-$r /tmp/ps7 $M --ram-budget 24GiB
  S mem-s9-$r /tmp/ps9 $M --ram-budget 24GiB
  S ooc-s7-$r /tmp/ps7 $M --ram-budget 1GiB --tmp $W
  S ooc-s9-$r /tmp/ps9 $M --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
S potree bash .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/ps9 generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in 1 2 3; do
  C laz-read-$r /tmp/ps9 bench-read $W/g.laz
  S laz-s7-$r /tmp/ps7 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  S laz-s9-$r /tmp/ps9 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
echo "at $SECONDS s"
cd $R && tar czf $OUT/runs.tgz *
rm -rf $W
