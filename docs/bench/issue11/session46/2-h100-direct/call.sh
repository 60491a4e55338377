#!/usr/bin/env bash
# Session 46, call 2: a store's chunks with their memory made by Vulkan directly, off wgpu's
# allocator lock. head = 03b0de3 (the whole buffer through wgpu before the first frame);
# new3 = 27077d9 + device_memory.rs, run four ways (POINTLET_CHUNK_ALLOC): wgpu (27077d9's
# behaviour: chunks through wgpu, one a frame), frame (through Vulkan, one a frame), thread
# (through Vulkan on a thread of their own), all (every chunk before the first frame, a thread
# each; that switch was an experiment's, not committed). `bench S.pointlet --progressive
# --realtime --target-fps 60`, alternated, two rounds.
# Run: run(command="bash docs/bench/issue11/session46/2-h100-direct/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c2; exec > >(tee "$OUT/c2/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in head new3; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
B() { local name=$1 mode=$2 bin=$3 file=$4; shift 4; POINTLET_CHUNK_ALLOC=$mode timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^while loading:|^loading:|^opening:|after the first frame|fill [(]GPU[)]|^upload memory' $T/$name.txt | tr '\n' ' ' | cut -c1-1100)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
R() { local tag=$1 file=$2; shift 2
  for r in 1 2; do
    B $tag-head-$r - /tmp/p-head $file "$@"
    for m in wgpu frame thread all; do B $tag-$m-$r $m /tmp/p-new3 $file "$@"; done
  done; }
/tmp/p-head generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
R s200 $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 180 /tmp/p-head generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
R s1g $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
cd $T && tar czf $OUT/c2/runs.tgz *.txt *.json
rm -rf $W
