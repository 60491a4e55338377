#!/usr/bin/env bash
# Session 44, call 2: the records gathered with prefetches (emitting pointlets and spilling
# runs read records from all over gigabytes of memory), 32 records ahead (pf32; a 16-ahead
# build was dropped to save device time), against the same commit without (base: the keys-in-runs commit). 200 M LAS in memory and out
# of core (1 GiB), two rounds alternated; then a 200 M LAZ: bench-read and convert with each
# build, two rounds (the device time left allowed no more). Every store compared with the first written.
# Binaries: .dev/pointlet-{base,pf32}.xz (`cargo build --release -p pointlet`,
# `objcopy --strip-debug`, `xz -9`).
# Run: run(command="bash docs/bench/issue15/session44/1-h100-prefetch/call.sh", carry=[
#   ".dev/pointlet-base.xz", ".dev/pointlet-pf32.xz",
#   ".dev/time_1.9-0.2_amd64.deb"])
set -uo pipefail
mkdir -p $OUT/pf; exec > >(tee "$OUT/pf/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="base pf32"; ROUNDS=${1:-2}
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
/tmp/p-base generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
M="convert $L -o $W/s.pointlet"
for r in $(seq $ROUNDS); do for v in $V; do
  C mem-$v-$r /tmp/p-$v $M --ram-budget 24GiB
  C ooc-$v-$r /tmp/p-$v $M --ram-budget 1GiB --tmp $W
done; done
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/p-base generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
echo "at $SECONDS s"
for r in $(seq $ROUNDS); do for v in $V; do
  C laz-read-$v-$r /tmp/p-$v bench-read $W/g.laz
  C laz-$v-$r /tmp/p-$v convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done; done
echo "at $SECONDS s"
cd $R && tar czf $OUT/pf/runs.tgz *
rm -rf $W
