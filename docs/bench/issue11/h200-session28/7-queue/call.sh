#!/usr/bin/env bash
# session 28 call 7: the hand-over queue at 4 (committed) and 64 batches (XP_QUEUE), alternated,
# 200 M store and 50 M LAS (same experiment build as call 6).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-xp.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
/tmp/pointlet generate --points 50M -o $W/p50.las 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet $W/p50.las > /dev/null
for r in 1 2 3; do B s200-q4-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB; XP_QUEUE=64 B s200-q64-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB; done
for r in 1 2; do B las50-q4-$r $W/p50.las --orbit-seconds 1 --vram-budget 8GiB; XP_QUEUE=64 B las50-q64-$r $W/p50.las --orbit-seconds 1 --vram-budget 8GiB; done
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt l*.txt *.json.gz
rm -rf $W
