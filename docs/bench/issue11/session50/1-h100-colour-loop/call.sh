#!/usr/bin/env bash
# Session 50, prepared call: a store's progressive load is CPU-bound (session 49's prepared
# thread-states call, run in session 50: the pool's threads running in 67-96 % of the samples
# while loading) and the RGB colour loop had 19.6 % of its CPU samples (a byte gather with a
# variable place and bounds checks). base = the code before, simd = that loop four points at
# a time by byte shuffles (SSSE3), p16 = simd with 16 384-point parts instead of 65 536 (a
# part's buffers in the L2 cache). The 1 G lean store (or as many points as the
# second argument says) and the 200 M store, `bench --progressive --realtime --target-fps 60`,
# alternated, three rounds (or as many as the first argument says); before each, `bench-read
# --staged` of the same store (the load's CPU side without the bus: the parts read,
# checksummed, coloured and copied into ordinary memory).
# Binaries: `cargo build --release -p pointlet` of 4a22802 (simd), of 9c24b07 with 7cdb6bd~1's
# crates/core/src/color.rs (base) and of 4a22802 with PART_POINTS = 16_384 in crates/engine/
# src/store_points.rs (p16), `strip --strip-all`, `xz -9e`, as .dev/pointlet-{base,simd,p16}.xz;
# .gl as in the device README.
# Run: run(command="bash docs/bench/issue11/session50/1-h100-colour-loop/call.sh [ROUNDS [LEAN_POINTS]]", carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c; exec > >(tee "$OUT/c/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="base simd p16"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
# The session's first call found /tmp too full for the 1 G store (19 GB): the roomiest place.
df -h /tmp . /dev/shm | cat
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/wt
T=/tmp/res; mkdir -p $W $T; SECONDS=0; echo "stores in $W"
nproc; grep -m1 'model name' /proc/cpuinfo
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|after the first frame|^upload bus' $T/$name.txt | tr '\n' ' ' | cut -c1-900)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
S() { local name=$1 bin=$2 file=$3; timeout 60 $bin bench-read $file --staged > $T/$name.txt 2>&1; echo "$name: $(tail -1 $T/$name.txt | cut -c1-200)"; }
timeout 180 /tmp/p-base generate --points ${2:-1G} --lean -o $W/s1g.pointlet 2>&1 | tail -1
timeout 100 /tmp/p-base generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet $W/s200.pointlet > /dev/null
for r in $(seq ${1:-3}); do for v in $V; do
  S s1g-staged-$v-$r /tmp/p-$v $W/s1g.pointlet
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
  S s200-staged-$v-$r /tmp/p-$v $W/s200.pointlet
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 2
done; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/c/runs.tgz *.txt *.json
rm -rf $W
