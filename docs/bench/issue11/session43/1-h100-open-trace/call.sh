#!/usr/bin/env bash
# Prepared in session 43 (no device could be started then); run in session 44 as the first call of
# that session, on one H100 host (16 cores), together with ../../../issue15/session43/1-h100-keys/call.sh 2
# (order: this with 200, keys, this with 1g); outputs beside this script.
# Where a store read as a point file spends its time before the first frame (1 G lean store:
# frame 0 began 0.34 s after opening in session 42, the 200 M store 0.07–0.08 s, the 50 M LAZ
# 0.02 s: it grows with the GPU buffer) and what bounds loading after it. `bench` itself now
# reports the passes' and the GPU buffers' making (`opening:`), the upload memory made and
# the load thread's waits on a full queue (`upload memory:`, 9c5e680). A diagnostic build on
# top (`trace.diff` beside this script, on ea4cb66; not committed) adds, with
# POINTLET_TRACE_OPEN=1, timestamps of each frame and its uploads (batches, points, ms), and
# knobs: POINTLET_ALLOC_PROBE=GiB,… times creating, clearing and freeing GPU buffers of those
# sizes before the bench; POINTLET_QUEUE=N lets N batches wait instead of 64;
# POINTLET_PRESTAGE=N maps N batches of upload memory (2^20 points each, in parallel) before
# the GPU buffer is made; POINTLET_MAX_BATCHES / POINTLET_UPLOAD_SHARE override the 64 batches
# and the quarter of a frame a frame may scatter. What each would show: allocation time per
# GiB (probe), whether the loader stalls while the buffer is made (queue, prestage), whether
# the render thread's scatter recording bounds loading (max batches, share).
# Binary: .dev/pointlet-diag.xz (`git apply trace.diff`, `cargo build --release -p pointlet`,
# debug info stripped, xz).
# Run: run(command="bash docs/bench/issue11/session43/1-h100-open-trace/call.sh [200|1g]",
#   carry=[".dev/pointlet-diag.xz", ".gl"]); `200` (~1 min) first, `1g` (~2 min) after.
set -uo pipefail
P=${1:-200}; mkdir -p $OUT/trace; exec > >(tee "$OUT/trace/log-$P.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-diag.xz > /tmp/pd && chmod +x /tmp/pd
W=/tmp/wt; T=/tmp/trace; mkdir -p $W $T; SECONDS=0
B() { local name=$1 file=$2; shift 2; POINTLET_TRACE_OPEN=1 timeout 100 /tmp/pd bench $file --realtime --target-fps 60 "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|^opening:|^upload memory:' $T/$name.txt | tr '\n' ' ') $(grep -iE 'error|PROBE' $T/$name.txt | head -5)"; }
if [ $P = 200 ]; then
/tmp/pd generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
POINTLET_ALLOC_PROBE=1,4,16,20,4 B probe $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
for r in 1 2; do B s200-$r $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB; done
POINTLET_QUEUE=512 B s200-q512 $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
POINTLET_QUEUE=512 POINTLET_PRESTAGE=256 B s200-pre256 $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
POINTLET_MAX_BATCHES=512 POINTLET_UPLOAD_SHARE=1 B s200-mb512 $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
POINTLET_QUEUE=512 POINTLET_MAX_BATCHES=512 POINTLET_UPLOAD_SHARE=1 B s200-q512-mb512 $W/s200.pointlet --progressive --orbit-seconds 1 --vram-budget 16GiB
rm -f $W/s200.pointlet
else
timeout 150 /tmp/pd generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
for r in 1 2; do B s1g-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
  POINTLET_QUEUE=512 B s1g-q512-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
  POINTLET_QUEUE=512 POINTLET_PRESTAGE=256 B s1g-pre256-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
  POINTLET_QUEUE=512 POINTLET_MAX_BATCHES=512 POINTLET_UPLOAD_SHARE=1 B s1g-q512-mb512-$r $W/s1g.pointlet --progressive --orbit-seconds 2 --vram-budget 24GiB
done
fi
echo "at $SECONDS s"
cd $T && tar czf $OUT/trace/runs-$P.tgz *.txt
rm -rf $W
