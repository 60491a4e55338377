#!/usr/bin/env bash
# session 31 call 3: the committed code (interleaved store pointlets with blocks of up to 64
# neighbouring pointlets permuted within each row; a frame takes 8 ready batches, then more of
# a store's while its uploads take less than a quarter of the target frame time, at most 64).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-f3.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 file=$2; shift 2; timeout 100 /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-150) | $(grep -E '^upload path' $OUT/$name.txt | cut -c1-150) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
/tmp/pointlet generate --points 50M -o $W/p50.las 2>&1 | tail -1
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet $W/p50.las > /dev/null
for r in 1 2 3; do
  B s200-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
done
B las50-1 $W/p50.las --orbit-seconds 1 --vram-budget 8GiB
rm -f $W/s200.pointlet $W/p50.las
echo "at $SECONDS s"
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
for r in 1 2 3; do
  B s1g-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
done
B s1g-8g-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 8GiB
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt las*.txt *.json.gz
rm -rf $W
