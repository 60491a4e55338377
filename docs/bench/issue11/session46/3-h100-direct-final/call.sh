#!/usr/bin/env bash
# Session 46, call 3: the committed form of call 2's finding. head = 03b0de3 (the whole buffer
# through wgpu before the first frame); new4 = point memory made by Vulkan directly
# (Capabilities::direct_memory), every chunk before the first frame, a store's pointlets
# interleaved over the whole buffer again. Stores (200 M, 1 G lean) and a 50 M LAS with
# `bench --progressive --realtime --target-fps 60`, and the 200 M store's virtualized path
# (`bench S.pointlet --frames 300`), alternated, two rounds.
# Run: run(command="bash docs/bench/issue11/session46/3-h100-direct-final/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c3; exec > >(tee "$OUT/c3/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="head new4"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^while loading:|^loading:|^opening:|after the first frame|fill [(]GPU[)]|^upload memory' $T/$name.txt | tr '\n' ' ' | cut -c1-1100)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
P() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^  (residency|raster)' $T/$name.txt | tr '\n' ' ' | cut -c1-600)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-head generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
  P v200-$v-$r /tmp/p-$v $W/s200.pointlet --frames 300
done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
/tmp/p-head generate --points 50M -o $W/g50.las 2>&1 | tail -1
sync; sleep 1; cat $W/g50.las > /dev/null
for r in 1 2; do for v in $V; do B l50-$v-$r /tmp/p-$v $W/g50.las --orbit-seconds 2 --vram-budget 8GiB; done; done
rm -f $W/g50.las
echo "at $SECONDS s"
timeout 180 /tmp/p-head generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
done; done
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
cd $T && tar czf $OUT/c3/runs.tgz *.txt *.json
rm -rf $W
