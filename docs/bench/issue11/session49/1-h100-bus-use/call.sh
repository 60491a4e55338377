#!/usr/bin/env bash
# Session 49, call 1: where a store's load loses against the BAR's write speed (87 % of it after
# the first frame in session 48): `bench` now reports how long the bus had a copy going on and
# how many at once (`upload bus, ...` lines), and how many threads should copy at once:
# BUS_WRITERS = 4 (.dev/pointlet-w4.xz, the working tree), 6 and 8 (the same with the constant
# in crates/gpu/src/shuffle.rs changed). The 1 G lean store and a 200 M store, `bench
# --progressive --realtime --target-fps 60`, alternated, two rounds.
# Binaries: `cargo build --release -p pointlet`, `strip --strip-all`, `xz -9e`; .gl as in the
# device README.
# Run: run(command="bash docs/bench/issue11/session49/1-h100-bus-use/call.sh", carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c1; exec > >(tee "$OUT/c1/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="w4 w6 w8"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
nvidia-smi --query-gpu=name,driver_version,pcie.link.gen.current,pcie.link.width.current --format=csv,noheader 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^while loading:|^loading:|after the first frame|^upload|^from host' $T/$name.txt | tr '\n' ' ' | cut -c1-1400)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
timeout 180 /tmp/p-w4 generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
timeout 100 /tmp/p-w4 generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB; done; done
echo "at $SECONDS s"
for v in $V; do B s200-$v /tmp/p-$v $W/s200.pointlet --orbit-seconds 2; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/c1/runs.tgz *.txt *.json
rm -rf $W
