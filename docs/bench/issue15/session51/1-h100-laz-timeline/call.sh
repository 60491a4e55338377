#!/usr/bin/env bash
# Session 51: a 200 M LAZ convert is the decode plus ~1.8 s (sorting 0.2, writing 1.3 s, the
# reading stage 0.2 s longer than the decode) with ~14 of 16 cores busy after the decode
# (docs/BENCHMARKS.md, issue 15, session 51); 0.8x the decode rate needs ~0.13 s less. Where
# do the cores idle? The share of all cores busy every 50 ms (sample.py, /proc/stat every
# 10 ms) through two LAZ converts and one in-memory LAS convert, beside their stage times.
# Binary: .dev/pointlet-base.xz (7814aa5, `cargo build --release -p pointlet`, `strip
# --strip-all`, `xz -9e`).
# Run: run(command="bash docs/bench/issue15/session51/1-h100-laz-timeline/call.sh", carry=[".dev"])
set -uo pipefail
D=docs/bench/issue15/session51/1-h100-laz-timeline
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-base.xz > /tmp/p && chmod +x /tmp/p
# The larger of /tmp and the checkout's parent (a 200 M store is 5 GB).
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w15
mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
timeout 100 /tmp/p generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
timeout 60 /tmp/p bench-read $W/g.laz 2>&1 | tail -1
for r in 1 2; do
  timeout 60 python3 $D/sample.py /tmp/p convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
rm -f $W/g.laz; timeout 100 /tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
timeout 60 python3 $D/sample.py /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
rm -rf $W
