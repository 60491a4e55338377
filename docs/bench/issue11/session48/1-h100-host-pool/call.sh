#!/usr/bin/env bash
# Session 48, call 1: batches staged in a pool of host memory made once per load (on a thread
# of its own; batches go through wgpu's mapped memory until it is there and whenever it is
# all in flight) against wgpu's mapped upload memory only (the BAR's). Session 47's call 3
# found the driver makes host memory at 5.2-5.6 GB/s in 64 MiB buffers (call 2 had made it
# per batch). base = .dev/pointlet-head.xz (d3de81e: the loading code of 4f76a7d), pool =
# .dev/pointlet-pool.xz (the host pool). The 200 M store and the 1 G lean store with
# `bench --progressive --realtime --target-fps 60`, alternated, two rounds.
# Run: run(command="bash docs/bench/issue11/session48/1-h100-host-pool/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c1; exec > >(tee "$OUT/c1/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-head.xz > /tmp/p-base && X .dev/pointlet-pool.xz > /tmp/p-pool && chmod +x /tmp/p-*
V="base pool"
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version,pcie.link.gen.current,pcie.link.width.current --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^while loading:|^loading:|^opening:|after the first frame|fill [(]GPU[)]|^upload memory|^upload path|^from host' $T/$name.txt | tr '\n' ' ' | cut -c1-1500)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-base generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB; done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 180 /tmp/p-base generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB; done; done
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
cd $T && tar czf $OUT/c1/runs.tgz *.txt *.json
rm -rf $W
