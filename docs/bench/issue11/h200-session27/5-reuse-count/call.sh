#!/usr/bin/env bash
# Device call (session 27, 5): how often a batch finds recycled upload memory (bench now
# prints new / reused staged batches), 200 M store and 1 G-point lean store.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-new.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W
lscpu | grep -iE "numa|socket|model name"
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --progressive --realtime --target-fps 60 --orbit-seconds 3 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|^upload memory' $OUT/$name.txt | tr '\n' ' ') $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
SECONDS=0
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do B s200-$r $W/s200.pointlet --vram-budget 16GiB; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 120 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
for r in 1 2; do B s1g-$r $W/s1g.pointlet --vram-budget 24GiB; done
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz s*.txt *.json.gz && rm -f s*.txt *.json.gz
rm -rf $W
