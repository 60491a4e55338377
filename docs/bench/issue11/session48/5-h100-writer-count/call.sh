#!/usr/bin/env bash
# Session 48, call 5: how many threads should copy into the BAR at once while a store loads:
# BUS_WRITERS = 4 (w4 = .dev/pointlet-dir.xz, call 4's build), 6 (.dev/pointlet-w6.xz) and 8
# (.dev/pointlet-w8.xz), each with direct BAR batches. The 1 G lean store with
# `bench --progressive --realtime --target-fps 60`, alternated, two rounds. Prepared, not run:
# no device time was left. Binaries: `cargo build --release -p pointlet` of 53dcdda or later
# with `pub const BUS_WRITERS` in crates/gpu/src/shuffle.rs set to 4, 6 and 8, each
# `objcopy --strip-debug`, `xz -3`; .gl as in the device README.
# Run: run(command="bash docs/bench/issue11/session48/5-h100-writer-count/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c5; exec > >(tee "$OUT/c5/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-dir.xz > /tmp/p-w4 && X .dev/pointlet-w6.xz > /tmp/p-w6 && X .dev/pointlet-w8.xz > /tmp/p-w8 && chmod +x /tmp/p-*
V="w4 w6 w8"
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; nvidia-smi --query-gpu=name,driver_version,pcie.link.gen.current,pcie.link.width.current --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^while loading:|^loading:|after the first frame|^upload memory|^from host' $T/$name.txt | tr '\n' ' ' | cut -c1-900)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
timeout 180 /tmp/p-w4 generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB; done; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/c5/runs.tgz *.txt *.json
rm -rf $W
