#!/usr/bin/env bash
# session 31 call 1: a store's pointlets interleaved in the shuffled buffer (point j of every
# pointlet before point j+1 of any: a batch lands in runs of neighbouring slots) against the
# prime permutation (XP_PERMUTED=1, the committed behaviour before), and more batches per frame
# (XP_BATCHES, default 8). Experiment switches: experiment.diff.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-i1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 file=$2; shift 2; timeout 100 /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-90) | $(grep -E '^upload path' $OUT/$name.txt | cut -c1-150) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do
  XP_PERMUTED=1 B s200-perm-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
  B s200-inter-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
  XP_BATCHES=32 B s200-inter-b32-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
XP_PERMUTED=1 B s1g-perm-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
B s1g-inter-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
XP_BATCHES=16 B s1g-inter-b16-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
XP_BATCHES=32 B s1g-inter-b32-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
B s1g-inter-2 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
XP_BATCHES=32 B s1g-inter-b32-2 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
echo "at $SECONDS s"
B s1g-8g-inter-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 8GiB
XP_PERMUTED=1 B s1g-8g-perm-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 8GiB
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt *.json.gz
rm -rf $W
