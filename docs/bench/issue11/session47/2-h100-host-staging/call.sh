#!/usr/bin/env bash
# Session 47, call 2: staged batches in host memory (UploadMemory: made by Vulkan, mapped for
# good, copied by the GPU over the bus) against wgpu's mapped upload memory (the BAR's, which
# call 1's loading threads wrote at 33.7 GB/s while the GPU pulls host memory at 50 GB/s).
# base = 2ca97d0, new9 = host staging. The 200 M store, a 50 M LAS and the 1 G lean store with
# `bench --progressive --realtime --target-fps 60`, alternated, two rounds.
# Run: run(command="bash docs/bench/issue11/session47/2-h100-host-staging/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c2; exec > >(tee "$OUT/c2/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet.xz > /tmp/p-base && X .dev/pointlet-new9.xz > /tmp/p-new9 && chmod +x /tmp/p-*
V="base new9"
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^while loading:|^loading:|^opening:|after the first frame|fill [(]GPU[)]|^upload memory' $T/$name.txt | tr '\n' ' ' | cut -c1-1100)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-base generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB; done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
/tmp/p-base generate --points 50M -o $W/g50.las 2>&1 | tail -1
sync; sleep 1; cat $W/g50.las > /dev/null
for r in 1 2; do for v in $V; do B l50-$v-$r /tmp/p-$v $W/g50.las --orbit-seconds 2 --vram-budget 8GiB; done; done
rm -f $W/g50.las
echo "at $SECONDS s"
timeout 180 /tmp/p-base generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB; done; done
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
cd $T && tar czf $OUT/c2/runs.tgz *.txt *.json
rm -rf $W
