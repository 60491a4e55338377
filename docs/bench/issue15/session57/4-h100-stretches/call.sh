#!/usr/bin/env bash
# Session 57, call 4: what the writing stage waits for. Build a (call 3) with a temporary
# debug print (POINTLET_DEBUG_BUCKETS: the buckets' sizes after partitioning, and for each
# stretch how long its emitting and the next stretch's sorting took), not committed: build a
# with debug.diff beside this file applied, .dev57b/pointlet-dbg.xz. Two in-memory converts of 200 M generated LAZ points with the print,
# the second under perf (cpu-clock, 999 Hz a thread); perf.data comes back for reading here.
# Run: run(command="bash docs/bench/issue15/session57/4-h100-stretches/call.sh", carry=[".perf", ".dev57b"])
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
P=/tmp/pk; mkdir -p $P && tar -C $P -xJf .perf/perf.tar.xz; B=$P/pointlet
D=/tmp/pointlet-dbg; xz -dc .dev57b/pointlet-dbg.xz > $D && chmod +x $D
perf() { LD_LIBRARY_PATH=$P/lib $P/perf "$@"; }
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w57
mkdir -p $W; SECONDS=0
timeout 150 $B generate --points ${N:-200M} -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
POINTLET_DEBUG_BUCKETS=1 timeout 60 $D convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB > $OUT/stretches-1.txt 2>&1; rm -f $W/s.pointlet; sync
POINTLET_DEBUG_BUCKETS=1 perf record -q -e cpu-clock -F 999 -o $W/c.data -- timeout 60 $D convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB > $OUT/stretches-2.txt 2>&1
cp $W/c.data $OUT/convert.perf.data
cat $OUT/stretches-1.txt $OUT/stretches-2.txt | grep -v '^$' | grep -v '\r' | head -80
echo "at $SECONDS s"
rm -rf $W
