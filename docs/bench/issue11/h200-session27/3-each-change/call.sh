#!/usr/bin/env bash
# Device call (session 27, 3): what each change gives. new = recycled staged batches + stored
# positions dequantized on the GPU; cpu = the same binary with POINTLET_CPU_POSITIONS=1
# (recycled batches, positions dequantized and encoded on the CPU: experiment switch, not in
# the tree); head = committed loader. 200 M-point store with --progressive, alternated.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for b in head new; do gunzip -c .dev/pointlet-$b.gz > /tmp/pointlet-$b && chmod +x /tmp/pointlet-$b; done
W=/tmp/w; mkdir -p $W
B() { local name=$1 bin=$2 file=$3; shift 3; /tmp/pointlet-$bin bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
/tmp/pointlet-new generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 2; cat $W/s200.pointlet > /dev/null
for r in 1 2 3 4; do
  B s200-new-$r new $W/s200.pointlet --progressive --orbit-seconds 3 --vram-budget 16GiB
  export POINTLET_CPU_POSITIONS=1; B s200-cpu-$r new $W/s200.pointlet --progressive --orbit-seconds 3 --vram-budget 16GiB; unset POINTLET_CPU_POSITIONS
  B s200-head-$r head $W/s200.pointlet --progressive --orbit-seconds 3 --vram-budget 16GiB
done
cd $OUT && gzip -f *.json && tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt s*.json.gz
rm -rf $W
