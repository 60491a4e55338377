#!/usr/bin/env bash
# Session 53: pointlets cut by selection at their boundaries instead of sorted bucket by bucket,
# and each pointlet's stored order taken from its points' own keys (ascending shuffle key,
# docs/FORMAT.md "Point order") instead of a Fisher–Yates permutation of their sorted order.
# Base = .dev/pointlet-base.xz (7814aa5's code, the same as daf3e84's); new =
# .dev15/pointlet-new.xz (this change; `cargo build --release -p pointlet`, `strip --strip-all`,
# `xz -9e`). 200 M LAZ: one convert of each discarded first (a fresh machine's first ~10 GB of
# allocations pay first touch), then three rounds of bench-read, base, new. 200 M LAS: two
# rounds of base and new, in memory and out of core (1 GiB); new's in-memory and out-of-core
# stores compared with cmp.
# Run: run(command="bash docs/bench/issue15/session53/1-h100-cuts/call.sh", carry=[".dev", ".dev15"])
set -uo pipefail
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-base.xz > /tmp/base && X .dev15/pointlet-new.xz > /tmp/new && chmod +x /tmp/base /tmp/new
dpkg -x .dev/time_1.9-0.2_amd64.deb /tmp/tm 2>/dev/null; T=/tmp/tm/usr/bin/time
# The larger of /tmp and the checkout's parent (a 200 M store is 5 GB).
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w15
mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; uname -r
conv() { # binary input output budget
  $T -f "cpu %U user %S sys, %M KB" timeout 100 /tmp/$1 convert $2 -o $3 --ram-budget $4 2>&1 | grep -E '^wrote|^cpu' | tr '\n' ' ' | sed "s|$W/||g"; echo; }
timeout 100 /tmp/new generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for b in base new; do echo -n "warm-up $b: "; conv $b $W/g.laz $W/s.pointlet 24GiB; rm -f $W/s.pointlet; done
for r in 1 2 3; do
  echo "== LAZ round $r"
  timeout 60 /tmp/base bench-read $W/g.laz 2>&1 | tail -1
  for b in base new; do echo -n "$b: "; conv $b $W/g.laz $W/s.pointlet 24GiB; rm -f $W/s.pointlet; sync; done
done
echo "at $SECONDS s"
rm -f $W/g.laz; timeout 100 /tmp/new generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
for r in 1 2; do
  echo "== LAS round $r"
  for b in base new; do
    echo -n "$b in memory: "; conv $b $W/g.las $W/m.pointlet 24GiB
    echo -n "$b out of core: "; conv $b $W/g.las $W/o.pointlet 1GiB
    if [ $b = new ]; then cmp $W/m.pointlet $W/o.pointlet && echo "new: in memory = out of core"; fi
    rm -f $W/m.pointlet $W/o.pointlet; sync
  done
done
echo "at $SECONDS s"
rm -rf $W
