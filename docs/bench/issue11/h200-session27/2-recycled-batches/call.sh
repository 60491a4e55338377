#!/usr/bin/env bash
# Device call (session 27, 2): staged batches recycled (mapped again once copied, no
# allocation and zero-fill per batch) plus stored positions dequantized on the GPU (new)
# against the committed loader (head), alternated: a 200 M-point store with --progressive,
# a 50 M-point LAS and LAZ; then a 1 G-point lean store.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for b in head new; do gunzip -c .dev/pointlet-$b.gz > /tmp/pointlet-$b && chmod +x /tmp/pointlet-$b; done
W=/tmp/w; mkdir -p $W
uname -r; nproc; free -g | head -2; df -h /tmp | tail -1
B() { local name=$1 bin=$2 file=$3; shift 3; /tmp/pointlet-$bin bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -E '^upload path' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
SECONDS=0
/tmp/pointlet-new generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 2; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do
  for b in head new; do B s200-$b-$r $b $W/s200.pointlet --progressive --orbit-seconds 4 --vram-budget 16GiB; done
done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
/tmp/pointlet-new generate --points 50M -o $W/p50.las 2>&1 | tail -1
/tmp/pointlet-new generate --points 50M -o $W/p50.laz 2>&1 | tail -1
sync; cat $W/p50.las $W/p50.laz > /dev/null
/tmp/pointlet-new bench-read $W/p50.las 2>&1 | tail -1
/tmp/pointlet-new bench-read $W/p50.laz 2>&1 | tail -1
for r in 1 2; do
  for b in head new; do B las50-$b-$r $b $W/p50.las --orbit-seconds 4 --vram-budget 8GiB; done
  for b in head new; do B laz50-$b-$r $b $W/p50.laz --orbit-seconds 6 --vram-budget 8GiB; done
done
rm -f $W/p50.las $W/p50.laz
echo "at $SECONDS s"
timeout 150 /tmp/pointlet-new generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
ls -la $W
if [ -f $W/s1g.pointlet ]; then
  sync; cat $W/s1g.pointlet > /dev/null
  for r in 1 2; do
    for b in new head; do B s1g-$b-$r $b $W/s1g.pointlet --progressive --orbit-seconds 6 --vram-budget 24GiB; done
  done
fi
echo "at $SECONDS s"
cd $OUT && gzip -f *.json && tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt s*.json.gz l*.txt l*.json.gz
rm -rf $W
