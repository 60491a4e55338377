#!/usr/bin/env bash
# Session 49, call 2: what the load's threads do while a store streams to the GPU (call 1 found
# the bus writers starved: 2.1-3.3 copies at once of the 4 allowed, no copy 13-27 % of the time).
# The state of every thread every 5 ms (states.py) through `bench s1g.pointlet --progressive
# --realtime --target-fps 60 --orbit-seconds 2` (the 1 G lean store), two runs; the samples
# come back whole (states-N.tsv) beside the bench output.
# Binary: .dev/pointlet-w4.xz (e25bc28, `strip --strip-all`, `xz -9e`); .gl as in the device
# README.
# Run: run(command="bash docs/bench/issue11/session49/2-h100-thread-states/call.sh", carry=[".dev", ".gl"])
set -uo pipefail
D=docs/bench/issue11/session49/2-h100-thread-states
mkdir -p $OUT/c2; exec > >(tee "$OUT/c2/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-w4.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/wt; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
timeout 180 /tmp/p generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2 3; do
  timeout 100 python3 $D/states.py $W/states-$r.tsv /tmp/p bench $W/s1g.pointlet --progressive --realtime --target-fps 60 --orbit-seconds 2 --vram-budget 24GiB --json $OUT/c2/bench-$r.json > $OUT/c2/bench-$r.txt 2>&1
  grep -E '^loading:|after the first frame|^upload bus|^opening' $OUT/c2/bench-$r.txt
  gzip -c $W/states-$r.tsv > $OUT/c2/states-$r.tsv.gz
done
echo "at $SECONDS s"
rm -rf $W
