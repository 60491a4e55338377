#!/usr/bin/env bash
# Session 45: a store read as a point file, its shuffled buffer made chunk by chunk while the
# first chunk is drawn (the chunked interleave: each 2 GiB buffer holds whole pointlets in
# file order, a thread makes the next ones) against the committed loader that makes the
# whole buffer before the first frame (head = 03b0de3). 200 M store (16 GiB budget) and 1 G
# lean store (24 GiB), `bench --progressive --realtime --target-fps 60`, alternated, ROUNDS
# rounds. Binaries: .dev/pointlet-{head,chunks}.xz (`cargo build --release -p pointlet`,
# `objcopy --strip-debug`, `xz -9`).
# Run: run(command="bash docs/bench/issue11/session45/1-h100-chunks/call.sh 2",
#   carry=[".dev/pointlet-head.xz", ".dev/pointlet-chunks.xz", ".gl"])
set -uo pipefail
ROUNDS=${1:-2}; mkdir -p $OUT/chunks; exec > >(tee "$OUT/chunks/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="head chunks"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|^opening:|after the first frame|^upload|first frame|1 % low|avg' $T/$name.txt | tr '\n' ' ' | cut -c1-900)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-head generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in $(seq $ROUNDS); do for v in $V; do
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 180 /tmp/p-head generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
for r in $(seq $ROUNDS); do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
done; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/chunks/runs.tgz *.txt
rm -rf $W
