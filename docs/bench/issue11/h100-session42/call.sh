#!/usr/bin/env bash
# Session 42: issue 11's loading figures with the committed code (its loader unchanged since
# session 38), on the H100 host of issue 15's calls (decoding faster than session 38's): 50 M
# LAZ decoded alone and loaded while drawing, alternated; the 200 M store and the 1 G lean store
# read as point files (--progressive). Binary: .dev/pointlet-cur.xz (51b5955, debug info
# stripped; its loader and renderer are those of the final commit).
# Run: run(command="bash docs/bench/issue11/h100-session42/call.sh", carry=[
#   ".dev/pointlet-cur.xz", ".gl"])
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-cur.xz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
B() { local name=$1 file=$2; shift 2; timeout 100 /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) | $(grep -E '^while loading' $OUT/$name.txt | cut -c1-150) | $(grep -E '^upload path' $OUT/$name.txt | cut -c1-150) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
/tmp/pointlet generate --points 50M -o $W/p50.laz 2>&1 | tail -1
sync; sleep 1; cat $W/p50.laz > /dev/null
echo "at $SECONDS s"
for r in 1 2 3; do
  /tmp/pointlet bench-read $W/p50.laz 2>&1 | tail -2
  B laz50-$r $W/p50.laz --orbit-seconds 4 --vram-budget 8GiB
done
rm -f $W/p50.laz
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do
  B s200-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
for r in 1 2 3; do
  B s1g-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
done
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt laz*.txt *.json.gz
rm -rf $W
