#!/usr/bin/env bash
# session 28 call 1: LAZ/store progressive loader timeline and decode window (experiment build)
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-xp.gz > /tmp/pointlet && chmod +x /tmp/pointlet
cp /lib/x86_64-linux-gnu/libc.so.6 $OUT/ 2>/dev/null; cat /etc/os-release | head -2
W=/tmp/w; mkdir -p $W
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>$OUT/$name.err; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt $OUT/$name.err | head -2)"; }
SECONDS=0
/tmp/pointlet generate --points 50M -o $W/p50.laz 2>&1 | tail -1
sync; cat $W/p50.laz > /dev/null
/tmp/pointlet bench-read $W/p50.laz 2>&1 | tail -1
/tmp/pointlet bench-read $W/p50.laz 2>&1 | tail -1
XP_TRACE=1 B laz-w3-trace $W/p50.laz --orbit-seconds 3 --vram-budget 8GiB
for r in 1 2; do for w in 3 6 12 24; do XP_W=$w B laz-w$w-$r $W/p50.laz --orbit-seconds 3 --vram-budget 8GiB; done; done
XP_W=12 XP_TRACE=1 B laz-w12-trace $W/p50.laz --orbit-seconds 3 --vram-budget 8GiB
rm -f $W/p50.laz
echo "at $SECONDS s"
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
XP_TRACE=1 B s200-w3-trace $W/s200.pointlet --progressive --orbit-seconds 2 --vram-budget 16GiB
for r in 1 2; do for w in 3 6 12; do XP_W=$w B s200-w$w-$r $W/s200.pointlet --progressive --orbit-seconds 2 --vram-budget 16GiB; done; done
echo "at $SECONDS s"
cd $OUT && gzip -f *.json *.err; tar czf runs.tgz *.txt *.json.gz *.err.gz && rm -f l*.txt s*.txt *.json.gz *.err.gz
rm -rf $W
