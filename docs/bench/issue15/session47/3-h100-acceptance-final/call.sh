#!/usr/bin/env bash
# Session 47, call 3: issue 15's acceptance on one instance with the session's final code
# (803c858: the part cells, within the run budget) alone, ROUNDS rounds (4 unless given):
# 200 M LAS in memory and out of core (1 GiB); PotreeConverter once on the same LAS; then a
# 200 M LAZ: bench-read and convert. Every store compared with the first written.
# Binaries: .dev/pointlet-head.xz (`cargo build --release -p pointlet`, `objcopy
# --strip-debug`, `xz -6`); .dev/potree = ../shared/tools/potree-converter.
# Run: run(command="bash docs/bench/issue15/session47/3-h100-acceptance-final/call.sh 4",
#   carry=[".dev"])
set -uo pipefail
mkdir -p $OUT/acc; exec > >(tee "$OUT/acc/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="head"; ROUNDS=${1:-4}
X .dev/pointlet-head.xz > /tmp/p-head && chmod +x /tmp/p-head && ln -sf /tmp/p-head /tmp/p-base
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; free -g | head -2
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
/tmp/p-base generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
C las-read-head /tmp/p-head bench-read $L
M="convert $L -o $W/s.pointlet"
for r in $(seq $ROUNDS); do for v in $V; do
  C mem-$v-$r /tmp/p-$v $M --ram-budget 24GiB
  C ooc-$v-$r /tmp/p-$v $M --ram-budget 1GiB --tmp $W
done; done
echo "at $SECONDS s"
if [ -x .dev/potree/run.sh ]; then
  cat $L > /dev/null; sync
  /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" .dev/potree/run.sh $L -o $W/potree > $R/potree.txt 2>&1
  echo "potree: $(tail -1 $R/potree.txt)"; rm -rf $W/potree
fi
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/p-base generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
echo "at $SECONDS s"
for r in $(seq $ROUNDS); do for v in $V; do
  C laz-read-$v-$r /tmp/p-$v bench-read $W/g.laz
  C laz-$v-$r /tmp/p-$v convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done; done
echo "at $SECONDS s"
cd $R && tar czf $OUT/acc/runs.tgz *
rm -rf $W
