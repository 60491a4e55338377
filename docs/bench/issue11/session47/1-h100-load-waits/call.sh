#!/usr/bin/env bash
# Session 47 (prepared in session 46): what the threads loading a
# 1 G lean store do while it streams at 26-27 GB/s against the bus's ~33 (issue 11, PCIe
# speed). Every thread's state and kernel wait function every 10 ms
# (docs/bench/issue15/session46/1-h100-cpu-timeline/waits.py; the pool's threads are `pool-N`,
# the loader's `point-load` / `point-batch`), cut at 30 % of the run (about the load's end: adjust from the bench output),
# two rounds, then the CPU share timeline (sample.py).
# Binary: .dev/pointlet.xz, a build of 26584e6 or later (`cargo build --release -p pointlet`,
# `objcopy --strip-debug`, `xz -6`).
# Run: run(command="bash docs/bench/issue11/session47/1-h100-load-waits/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
T=docs/bench/issue15/session46/1-h100-cpu-timeline
mkdir -p $OUT/lw; exec > >(tee "$OUT/lw/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/wt; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
timeout 180 /tmp/p generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
B="/tmp/p bench $W/s1g.pointlet --progressive --realtime --target-fps 60 --orbit-seconds 2 --vram-budget 24GiB"
echo "== bench"; timeout 100 $B 2>&1 | tail -25
for r in 1 2; do
  echo "== waits-$r"; timeout 100 python3 $T/waits.py 0.3 $B
done
echo "== cpu"; timeout 100 python3 $T/sample.py $B
echo "at $SECONDS s"
rm -rf $W
