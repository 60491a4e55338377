#!/usr/bin/env bash
# Session 52: batches pulled from host memory by a transfer queue of their own (the copy
# engine) beside the BAR's batches (`StagedBatch::pulled`, crates/gpu/src/transfer.rs): on
# hosts whose GPU pulls host memory at ~50 GB/s the BAR path moves ~30 GB/s (sessions 48-51).
# 1. Correctness on this GPU: the shuffle tests (a third of their staged batches pulled) and
#    the engine's progressive tests, with the transfer queue and without
#    (POINTLET_TRANSFER_QUEUE=0); `render --progressive` of a store and `render` of a LAS file
#    with base, pull without and pull with the queue: the PNGs compared.
# 2. The 1 G lean store and the 200 M store, `bench --progressive --realtime --target-fps 60`,
#    base (7814aa5) and pull alternated, ROUNDS rounds.
# Binaries: `cargo build --release -p pointlet`, `strip --strip-all`, `xz -9e`, as
# .dev/pointlet-{base,pull}.xz; test binaries (`cargo test --release --no-run -p pointlet-gpu
# --test shuffle -p pointlet-engine --test progressive`, stripped) as .dev/t-{shuffle,progressive}.xz;
# .gl as in the device README.
# The code measured is transfer-queue.diff beside this script (dropped after this call; runs.tgz
# keeps the texts and JSON, not the PNGs, which cmp found identical).
# Run: run(command="bash docs/bench/issue11/session52/1-h100-transfer-queue/call.sh 3", carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c; exec > >(tee "$OUT/c/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="base pull"; ROUNDS=${1:-3}
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
for t in shuffle progressive; do X .dev/t-$t.xz > /tmp/t-$t && chmod +x /tmp/t-$t; done
# The tests find testdata/ where they were built.
mkdir -p /work; [ -e /work/main ] || ln -s $PWD /work/main
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/wt
T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; nvidia-smi --query-gpu=name,pcie.link.gen.current,pcie.link.width.current --format=csv,noheader
for q in 1 0; do
  echo "== tests, POINTLET_TRANSFER_QUEUE=$q"
  POINTLET_TRANSFER_QUEUE=$q timeout 120 /tmp/t-shuffle 2>&1 | grep -E "^test |test result|panicked" | head -20
  POINTLET_TRANSFER_QUEUE=$q timeout 240 /tmp/t-progressive 2>&1 | grep -E "FAILED|failed|panicked|test result" | head -20
done
echo "at $SECONDS s"
timeout 180 /tmp/p-base generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
timeout 100 /tmp/p-base generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
timeout 60 /tmp/p-base generate --points 20M -o $W/g20.las 2>&1 | tail -1
sync; sleep 1; cat $W/*.pointlet $W/g20.las > /dev/null
I() { local name=$1; shift; timeout 100 "$@" > $T/$name.txt 2>&1; echo "$name: rc $? $(tail -1 $T/$name.txt | cut -c1-200)"; }
for f in s200.pointlet g20.las; do
  extra=""; [ $f = s200.pointlet ] && extra="--progressive"
  I img-$f-base /tmp/p-base render $W/$f $extra -o $T/$f-base.png
  POINTLET_TRANSFER_QUEUE=0 I img-$f-pull0 /tmp/p-pull render $W/$f $extra -o $T/$f-pull0.png
  I img-$f-pull /tmp/p-pull render $W/$f $extra -o $T/$f-pull.png
  for v in pull0 pull; do cmp $T/$f-base.png $T/$f-$v.png && echo "$f: $v image identical to base"; done
done
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|after the first frame|^upload|^transfer' $T/$name.txt | tr '\n' ' ' | cut -c1-1300)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
for r in $(seq $ROUNDS); do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 2
done; done
echo "at $SECONDS s"
cd $T && tar czf $OUT/c/runs.tgz *.txt *.json *.png
rm -rf $W
