#!/usr/bin/env bash
# session 31 call 2: the candidate (interleaved store pointlets; each frame scatters 8 ready
# batches, then more while its uploads took less than upload_share = 1/4 of the target frame
# time, at most 64). XP_SHARE overrides the share (0: 8 batches a frame, as before); XP_TRACE
# timestamps the start of a load (experiment.diff). 1 G lean store, 200 M store, 50 M LAS.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-i2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 file=$2; shift 2; timeout 100 /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>$OUT/$name.err; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-150) | $(grep -E '^upload path' $OUT/$name.txt | cut -c1-150) $(grep -iE 'error' $OUT/$name.txt $OUT/$name.err | head -2)"; }
/tmp/pointlet generate --points 50M -o $W/p50.las 2>&1 | tail -1
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet $W/p50.las > /dev/null
for r in 1 2; do
  B s200-share25-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
  XP_SHARE=0 B s200-share0-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
  B las50-share25-$r $W/p50.las --orbit-seconds 1 --vram-budget 8GiB
  XP_SHARE=0 B las50-share0-$r $W/p50.las --orbit-seconds 1 --vram-budget 8GiB
done
XP_TRACE=1 B s200-trace $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
rm -f $W/s200.pointlet $W/p50.las
echo "at $SECONDS s"
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
XP_TRACE=1 B s1g-trace $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
for r in 1 2; do
  B s1g-share25-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
  XP_SHARE=0 B s1g-share0-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
  XP_SHARE=0.5 B s1g-share50-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
done
B s1g-8g-share25-1 $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 8GiB
echo "at $SECONDS s"
grep -h "^XP" $OUT/s200-trace.err | head -60 > $OUT/trace-s200.txt
grep -h "^XP" $OUT/s1g-trace.err | head -60 > $OUT/trace-s1g.txt
cat $OUT/trace-s1g.txt
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.err *.json.gz && rm -f s*.txt las*.txt *.err *.json.gz
rm -rf $W
