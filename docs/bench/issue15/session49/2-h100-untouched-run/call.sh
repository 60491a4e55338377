#!/usr/bin/env bash
# Session 49: the in-memory run decoded into without zeroing it first (its spare room is the
# allocator's zero pages), against the same code zeroing each part first. base = 9ede154's
# conversion code, new = the change; 200 M LAS in memory and out of core (1 GiB), ROUNDS rounds
# alternated; then a 200 M LAZ: bench-read and convert with each build, ROUNDS rounds. Every
# store compared with the first written (session 47's call without PotreeConverter).
# Binaries: .dev15b/pointlet-base.xz and .dev15b/pointlet-new.xz (`cargo build --release -p
# pointlet`, `strip --strip-all`, `xz -9e`).
# Run: run(command="bash docs/bench/issue15/session49/2-h100-untouched-run/call.sh 3",
#   carry=[".dev15b"])
set -uo pipefail
mkdir -p $OUT/untouched; exec > >(tee "$OUT/untouched/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="base new"; ROUNDS=${1:-3}
X .dev15b/pointlet-base.xz > /tmp/p-base && X .dev15b/pointlet-new.xz > /tmp/p-new && chmod +x /tmp/p-*
[ -x /usr/bin/time ] || dpkg -x .dev15b/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; free -g | head -2
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
/tmp/p-base generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
C las-read-new /tmp/p-new bench-read $L
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
cd $R && tar czf $OUT/untouched/runs.tgz *
rm -rf $W
