#!/usr/bin/env bash
# Session 46, issue 15: where the out-of-core build leaves cores idle. The 200 M LAS converted
# in memory and out of core (1 GiB), twice each, with every core's busy share sampled from
# /proc/stat every 20 ms (sample.py), against the stages the build reports.
# Binary: .dev/pointlet-new5.xz (b77a2f9's conversion code is 27077d9's).
# Run: run(command="bash docs/bench/issue15/session46/1-h100-cpu-timeline/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
D=docs/bench/issue15/session46/1-h100-cpu-timeline
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-new5.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/w; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
/tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
for r in 1 2; do
  echo "== mem-$r"; python3 $D/sample.py /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB; rm -f $W/s.pointlet; sync
  echo "== ooc-$r"; python3 $D/sample.py /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W; rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
