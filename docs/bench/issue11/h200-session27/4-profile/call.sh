#!/usr/bin/env bash
# Device call (session 27, 4): where loading a store with --progressive spends its time, the
# 1 G-point lean store (loads at ~400 M pts/s) against the 200 M-point store (~600 M pts/s):
# the committed candidate, timed, then under perf record.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-new.gz > /tmp/pointlet && chmod +x /tmp/pointlet
tar xzf .dev/perfpk.tgz -C /tmp
PERF="env LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; mkdir -p $W
cat /sys/kernel/mm/transparent_hugepage/enabled
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --progressive --realtime --target-fps 60 --orbit-seconds 4 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
P() { local name=$1 file=$2; shift 2; $PERF record -F 1999 -o $W/$name.data /tmp/pointlet bench $file --progressive --realtime --target-fps 60 --orbit-seconds 4 "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt)"; $PERF report -i $W/$name.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -50 > $OUT/$name-sym.txt; $PERF report -i $W/$name.data --no-children --sort comm,dso 2>/dev/null | grep -v '^#' | grep '%' | head -30 > $OUT/$name-comm.txt; rm -f $W/$name.data; }
SECONDS=0
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
B s200-1 $W/s200.pointlet --vram-budget 16GiB
B s200-2 $W/s200.pointlet --vram-budget 16GiB
P perf-s200 $W/s200.pointlet --vram-budget 16GiB
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
B s1g-1 $W/s1g.pointlet --vram-budget 24GiB
P perf-s1g $W/s1g.pointlet --vram-budget 24GiB
B s1g-2 $W/s1g.pointlet --vram-budget 24GiB
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz s*.txt *.json.gz && rm -f s*.txt *.json.gz
rm -rf $W
