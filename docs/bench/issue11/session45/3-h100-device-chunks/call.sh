#!/usr/bin/env bash
# Session 45, call 3: head = 03b0de3 (the whole buffer made before the first frame) against
# new2 (a store's buffer in chunks of the binding limit, made by the render thread one a
# frame while the first ones are drawn: call 2's 512 MiB chunks slowed the Fill pass).
# 200 M store (16 GiB budget) and 1 G lean store (24 GiB), `bench --progressive --realtime
# --target-fps 60`, alternated, two rounds.
# Binaries: .dev/pointlet-{head,new2}.xz (`cargo build --release -p pointlet`,
# `objcopy --strip-debug`, `xz -9`).
# Run: run(command="bash docs/bench/issue11/session45/3-h100-device-chunks/call.sh",
#   carry=[".dev/pointlet-head.xz", ".dev/pointlet-new2.xz", ".gl", ".dev/time_1.9-0.2_amd64.deb"])
set -uo pipefail
mkdir -p $OUT/dc; exec > >(tee "$OUT/dc/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="head new2"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^while loading:|^loading:|^opening:|after the first frame|fill [(]GPU[)]' $T/$name.txt | tr '\n' ' ' | cut -c1-900)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-head generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 180 /tmp/p-head generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
done; done
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
cd $T && tar czf $OUT/dc/runs.tgz *.txt
rm -rf $W
