#!/usr/bin/env bash
# Session 49, call 2: what the load's threads do while a store streams to the GPU (call 1 found
# the bus writers starved: 2.1-3.3 copies at once of the 4 allowed, no copy 13-27 % of the time).
# `render s1g.pointlet --progressive` (the 1 G lean store, or as many points as the argument
# says: load, then frames until converged),
# three runs: plain; under `perf record -F 999` (flat on-CPU profile by symbol and by DSO); under
# states.py (every thread's state every 5 ms, the samples come back whole as states.tsv.gz).
# Binary: .dev11/pointlet-sym.xz (f90de0d, `objcopy --strip-debug`, `xz -9e`); perf and its
# libraries: .dev11/perfpk.txz (as in docs/bench/issue15/session49/1-h100-emit-profile/); .gl as
# in the device README.
# Run: run(command="bash docs/bench/issue11/session49/2-h100-thread-states/call.sh [POINTS]",
#   carry=[".dev11", ".gl"])
set -uo pipefail
D=docs/bench/issue11/session49/2-h100-thread-states
mkdir -p $OUT/c2; exec > >(tee "$OUT/c2/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev11/pointlet-sym.xz > /tmp/p && chmod +x /tmp/p
X .dev11/perfpk.txz | tar xf - -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/wt; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
timeout 150 /tmp/p generate --points ${1:-1G} --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
R="render $W/s1g.pointlet --progressive -o $W/x.png --width 1280 --height 720"
echo "== plain"; timeout 60 /tmp/p $R 2>&1 | tail -1
echo "== perf"; timeout 60 $PERF record -F 999 -o $W/r.data -- /tmp/p $R 2>&1 | tail -2
$PERF report -i $W/r.data --no-children --sort dso 2>/dev/null | grep -v '^#' | grep '%' | head -12
$PERF report -i $W/r.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -60 | cut -c1-150
$PERF report -i $W/r.data --no-children --sort comm 2>/dev/null | grep -v '^#' | grep '%' | head -12
rm -f $W/r.data
echo "== states"; timeout 60 python3 $D/states.py $W/states.tsv /tmp/p $R | tail -1
gzip -c $W/states.tsv > $OUT/c2/states.tsv.gz
echo "at $SECONDS s"
rm -rf $W
