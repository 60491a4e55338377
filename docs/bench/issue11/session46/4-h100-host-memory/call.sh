#!/usr/bin/env bash
# Session 46, call 4: how fast the GPU pulls host memory (system RAM made by Vulkan directly,
# not the resizable BAR) over the bus, against threads writing the BAR's upload memory.
# new5 = a452e80 + `UploadBandwidth::host_*`; `bench S.pointlet --progressive --realtime`
# prints both paths after its flight (2 GiB each, 64 MiB buffers, median of 3 runs).
# Run: run(command="bash docs/bench/issue11/session46/4-h100-host-memory/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c4; exec > >(tee "$OUT/c4/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-new5.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/wt; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version,pcie.link.gen.current,pcie.link.width.current --format=csv,noheader 2>/dev/null
/tmp/p generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do
  timeout 100 /tmp/p bench $W/s200.pointlet --progressive --realtime --target-fps 60 --orbit-seconds 1 --vram-budget 16GiB > $W/b$r.txt 2>&1
  grep -E '^loading:|after the first frame|^upload path|^from host' $W/b$r.txt; grep -iE 'error|panick' $W/b$r.txt | head -3
done
echo "at $SECONDS s"
rm -rf $W
