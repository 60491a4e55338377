#!/usr/bin/env bash
# session 28 call 6: where a store's load begins (experiment build: XP_TRACE timestamps of the
# scene's creation, the load thread and the first frames), and a deeper hand-over queue
# (XP_QUEUE=64 batches instead of 4) so that the loader does not wait while the scene is made.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-xp.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --realtime --target-fps 60 --progressive --json $OUT/$name.json "$@" > $OUT/$name.txt 2>$OUT/$name.err; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
SECONDS=0
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
XP_TRACE=1 B s200-trace $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
grep XP $OUT/s200-trace.err | head -40
for r in 1 2; do B s200-q4-$r $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB; XP_QUEUE=64 B s200-q64-$r $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
echo "at $SECONDS s"
cd $OUT && gzip -f *.json *.err; tar czf runs.tgz *.txt *.json.gz *.err.gz && rm -f s*.txt *.json.gz *.err.gz
rm -rf $W
