#!/usr/bin/env bash
# Session 45, call 2 (issues 11 and 15 in one call): head = 03b0de3 (the committed loader
# and conversion of the session's start) against new = 34b4ff6 (a store's buffer in chunks of
# at most 512 MiB of positions, made by the render thread one a frame while the first ones
# are drawn; out-of-core groups reading their keys straight into place). Issue 11: 200 M
# store (16 GiB budget) and 1 G lean store (24 GiB), `bench --progressive --realtime
# --target-fps 60`, alternated, two rounds. Issue 15: 200 M LAS in memory and out of core
# (1 GiB), alternated, ROUNDS rounds, every store compared with the first written.
# Binaries: .dev/pointlet-{head,new}.xz (`cargo build --release -p pointlet`,
# `objcopy --strip-debug`, `xz -9`).
# Run: run(command="bash docs/bench/issue11/session45/2-h100-frame-chunks/call.sh 2",
#   carry=[".dev/pointlet-head.xz", ".dev/pointlet-new.xz", ".gl", ".dev/time_1.9-0.2_amd64.deb"])
set -uo pipefail
ROUNDS=${1:-2}; mkdir -p $OUT/fc; exec > >(tee "$OUT/fc/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="head new"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^while loading:|^loading:|^opening:|after the first frame' $T/$name.txt | tr '\n' ' ' | cut -c1-700)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-head generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 180 /tmp/p-head generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
done; done
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' $T/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $T/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
/tmp/p-head generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
M="convert $L -o $W/s.pointlet"
for r in $(seq $ROUNDS); do for v in $V; do
  C mem-$v-$r /tmp/p-$v $M --ram-budget 24GiB
  C ooc-$v-$r /tmp/p-$v $M --ram-budget 1GiB --tmp $W
done; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/fc/runs.tgz *.txt
rm -rf $W
