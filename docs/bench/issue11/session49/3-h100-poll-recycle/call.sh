#!/usr/bin/env bash
# Session 49, prepared call 3: batches the GPU is done with come back only at the render
# thread's next poll (once a frame), so a store's load keeps making new ones (68-76 for the
# 1 G lean store in call 1, 0.06-0.47 s of the load threads' time). `poll-before-making.diff`
# polls the device (without waiting) from the load thread before it makes a new batch
# (`UploadMemory::collect_finished`). base = the commit the diff applies to, new = with it;
# the 1 G lean store and the 200 M store, `bench --progressive --realtime --target-fps 60`,
# alternated, three rounds: fully loaded, after the first frame, batches newly made, the bus.
# Binaries: `cargo build --release -p pointlet` without and with the diff (`git apply`),
# `strip --strip-all`, `xz -9e`, as .dev/pointlet-base.xz and .dev/pointlet-new.xz; .gl as in
# the device README.
# Run: run(command="bash docs/bench/issue11/session49/3-h100-poll-recycle/call.sh", carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c3; exec > >(tee "$OUT/c3/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="base new"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|after the first frame|^upload|^from host' $T/$name.txt | tr '\n' ' ' | cut -c1-1400)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
timeout 180 /tmp/p-base generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
timeout 100 /tmp/p-base generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet $W/s200.pointlet > /dev/null
for r in 1 2 3; do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 2
done; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/c3/runs.tgz *.txt *.json
rm -rf $W
