#!/usr/bin/env bash
# Session 46, issue 15, call 2: what the out-of-core build's threads wait for in its reading
# stage (70-80 % of cores busy there against 100 % in memory, call 1). Every thread's state and
# kernel wait function sampled every 10 ms (waits.py), cut at the reading stage's end.
# Run: run(command="bash docs/bench/issue15/session46/1-h100-cpu-timeline/call2.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
D=docs/bench/issue15/session46/1-h100-cpu-timeline
mkdir -p $OUT/t2; exec > >(tee "$OUT/t2/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-new5.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/w; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; uname -r
/tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
for r in 1 2; do
  echo "== mem-$r"; python3 $D/waits.py 0.35 /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB; rm -f $W/s.pointlet; sync
  echo "== ooc-$r"; python3 $D/waits.py 0.52 /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W; rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
