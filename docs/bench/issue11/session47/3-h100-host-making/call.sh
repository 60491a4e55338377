#!/usr/bin/env bash
# Prepared in session 47 (no device time left), not run: how fast the driver makes host memory the GPU can read (the upload probe
# of `bench --progressive` now times making its 2 GiB in 64 MiB buffers), against call 2's
# ~20 ms per 16 MB staged batch: per byte (pinning) or per buffer? A 20 M store, two runs.
# Binary: .dev/pointlet-head.xz (a build with `UploadBandwidth::host_make_gbs`).
# Run: run(command="bash docs/bench/issue11/session47/3-h100-host-making/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c3; exec > >(tee "$OUT/c3/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-head.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/wt; mkdir -p $W; SECONDS=0
nproc; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
/tmp/p generate --points 20M -o $W/s20.pointlet 2>&1 | tail -1
for r in 1 2; do timeout 60 /tmp/p bench $W/s20.pointlet --progressive --realtime --orbit-seconds 1 2>&1 | grep -E '^loading:|^upload path|^from host|^upload memory'; done
echo "at $SECONDS s"
rm -rf $W
