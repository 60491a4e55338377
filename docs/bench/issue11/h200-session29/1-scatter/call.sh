#!/usr/bin/env bash
# session 29 call 1: the shuffle scatter with Montgomery products (new) and the per-frame upload cap
# (8 batches, or beyond them half the fill budget's points; XP_CAP=1: 8 batches only), against
# session 28's committed loader (old = its experiment build with XP_QUEUE=64).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-xp.gz > /tmp/pointlet-old && gunzip -c .dev/pointlet-n1.gz > /tmp/pointlet-new && chmod +x /tmp/pointlet-*
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 bin=$2 file=$3; shift 3; XP_QUEUE=64 /tmp/pointlet-$bin bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-80) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
/tmp/pointlet-new generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
/tmp/pointlet-new generate --points 50M -o $W/p50.las 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet $W/p50.las > /dev/null
for r in 1 2; do
  B s200-old-$r old $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
  XP_CAP=1 B s200-cap8-$r new $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
  B s200-new-$r new $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
done
for r in 1 2; do
  B las50-old-$r old $W/p50.las --orbit-seconds 1 --vram-budget 8GiB
  B las50-new-$r new $W/p50.las --orbit-seconds 1 --vram-budget 8GiB
done
rm -f $W/s200.pointlet $W/p50.las
echo "at $SECONDS s"
timeout 150 /tmp/pointlet-new generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
B s1g-old-1 old $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
XP_CAP=1 B s1g-cap8-1 new $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
B s1g-new-1 new $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
B s1g-new-2 new $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f l*.txt s*.txt *.json.gz
rm -rf $W
