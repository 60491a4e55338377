#!/usr/bin/env bash
# session 31 call 6: a store's RGB colours computed straight from the stream bytes
# (`PartedSource::stored_colors`, new) against decoding the part into a batch and colouring it
# (old = call 4's binary, the commit 3f59c2b plus an unset switch), alternated, 1 G lean store.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-b4.gz > /tmp/pointlet-old && gunzip -c .dev/pointlet-c6.gz > /tmp/pointlet-new && chmod +x /tmp/pointlet-*
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 /tmp/pointlet-$bin bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-150) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
timeout 150 /tmp/pointlet-new generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
for r in 1 2 3; do
  B s1g-old-$r old $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
  B s1g-new-$r new $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
done
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt *.json.gz
rm -rf $W
