#!/usr/bin/env bash
# session 28 call 3: each batch in flight on a thread of its own, its parts queued as flat tasks (new) against
# session 27's loader (s27), alternated: 50 M LAZ and LAS, 200 M store, 1 G lean store.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for b in s27 new; do gunzip -c .dev/pointlet-$b.gz > /tmp/pointlet-$b && chmod +x /tmp/pointlet-$b; done
W=/tmp/w; mkdir -p $W
B() { local name=$1 bin=$2 file=$3; shift 3; /tmp/pointlet-$bin bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
SECONDS=0
/tmp/pointlet-new generate --points 50M -o $W/p50.laz 2>&1 | tail -1
/tmp/pointlet-new generate --points 50M -o $W/p50.las 2>&1 | tail -1
sync; cat $W/p50.laz $W/p50.las > /dev/null
/tmp/pointlet-new bench-read $W/p50.laz 2>&1 | tail -1
/tmp/pointlet-new bench-read $W/p50.las 2>&1 | tail -1
for r in 1 2 3; do for b in s27 new; do B laz50-$b-$r $b $W/p50.laz --orbit-seconds 3 --vram-budget 8GiB; done; done
for r in 1 2; do for b in s27 new; do B las50-$b-$r $b $W/p50.las --orbit-seconds 2 --vram-budget 8GiB; done; done
/tmp/pointlet-new bench-read $W/p50.laz 2>&1 | tail -1
rm -f $W/p50.laz $W/p50.las
echo "at $SECONDS s"
/tmp/pointlet-new generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do for b in s27 new; do B s200-$b-$r $b $W/s200.pointlet --progressive --orbit-seconds 2 --vram-budget 16GiB; done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 150 /tmp/pointlet-new generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
if [ -f $W/s1g.pointlet ]; then
  sync; cat $W/s1g.pointlet > /dev/null
  for r in 1; do for b in new s27; do B s1g-$b-$r $b $W/s1g.pointlet --progressive --orbit-seconds 4 --vram-budget 24GiB; done; done
fi
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f l*.txt s*.txt *.json.gz
rm -rf $W
