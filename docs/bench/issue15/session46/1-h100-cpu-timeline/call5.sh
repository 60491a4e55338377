#!/usr/bin/env bash
# Session 46, issue 15, call 5: a timeline of every run of the out-of-core build (the main
# thread making room, decoding, handing over; each spilling thread bucketing, gathering,
# written), from a build of 41f9904 with `trace.diff` (POINTLET_TRACE=1), two rounds.
# Run: run(command="bash docs/bench/issue15/session46/1-h100-cpu-timeline/call5.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/t5; exec > >(tee "$OUT/t5/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-trace.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/w; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
/tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
for r in 1 2; do
  POINTLET_TRACE=1 /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W > $OUT/t5/ooc-$r.txt 2>&1
  grep -E '^wrote' $OUT/t5/ooc-$r.txt | cut -c1-300; rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
