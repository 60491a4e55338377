#!/usr/bin/env bash
# session 29 call 2: where a 1 G store's per-batch upload cost goes. XP_ST: each scatter waits for
# the GPU before and after it and reports recording, submit and GPU time per batch (n2 build = n1 +
# that switch); 1 G and 200 M stores, cap 8 batches (XP_CAP=1). Then perf of the render thread.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-n2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
tar xzf .dev/perfpk.tgz -C /tmp
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>$OUT/$name.err; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-80) $(grep -iE 'error' $OUT/$name.txt | head -2)"; grep xp-scatter $OUT/$name.err | sed -n '1p;4p;12p;$p'; }
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
XP_ST=1 XP_CAP=1 B s200-st $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
rm -f $W/s200.pointlet
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
XP_ST=1 XP_CAP=1 B s1g-st $W/s1g.pointlet --progressive --orbit-seconds 1 --vram-budget 24GiB
XP_ST=1 XP_CAP=1 B s1g-st-8g $W/s1g.pointlet --progressive --orbit-seconds 1 --vram-budget 8GiB
XP_CAP=1 LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf record -F 1999 -g -o $W/p.data /tmp/pointlet bench $W/s1g.pointlet --progressive --realtime --target-fps 60 --orbit-seconds 1 --vram-budget 24GiB > $OUT/perf-run.txt 2>&1
grep -E '^loading' $OUT/perf-run.txt
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf report -i $W/p.data --no-children --sort comm,dso,sym 2>/dev/null | grep -v '^#' | grep '%' | head -80 > $OUT/perf-comm-sym.txt
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf report -i $W/p.data --no-children --comm pointlet --sort dso,sym 2>/dev/null | grep -v '^#' | grep '%' | head -60 > $OUT/perf-main.txt
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf report -i $W/p.data --children --comm pointlet --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -80 > $OUT/perf-main-children.txt
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.err *.json.gz && rm -f s*.txt *.err *.json.gz perf-run.txt
rm -rf $W
