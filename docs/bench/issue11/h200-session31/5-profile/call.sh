#!/usr/bin/env bash
# session 31 call 5: where a store's load spends its CPU now (committed code; the binary is
# call 4's, whose XP_NOBLOCK switch stays unset): the 1 G lean store under perf record -F 1999,
# flat profile by symbol and by thread/DSO, then one timed run. (A first attempt, with perf's
# libraries but the machine's own loader, crashed: its log is log-attempt1.txt.)
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-b4.gz > /tmp/pointlet && chmod +x /tmp/pointlet
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
$PERF --version
W=/tmp/w; mkdir -p $W; SECONDS=0
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --progressive --realtime --target-fps 60 --orbit-seconds 1 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
P() { local name=$1 file=$2; shift 2; $PERF record -F 1999 -o $W/$name.data /tmp/pointlet bench $file --progressive --realtime --target-fps 60 --orbit-seconds 1 "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt)"; $PERF report -i $W/$name.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -60 > $OUT/$name-sym.txt; $PERF report -i $W/$name.data --no-children --sort comm,dso 2>/dev/null | grep -v '^#' | grep '%' | head -30 > $OUT/$name-comm.txt; rm -f $W/$name.data; }
timeout 150 /tmp/pointlet generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
echo "at $SECONDS s"
P perf-s1g $W/s1g.pointlet --vram-budget 24GiB
B s1g-2 $W/s1g.pointlet --vram-budget 24GiB
echo "at $SECONDS s"
head -40 $OUT/perf-s1g-sym.txt; cat $OUT/perf-s1g-comm.txt | head -12
cd $OUT && gzip -f *.json; tar czf runs.tgz s*.txt *.json.gz && rm -f s*.txt *.json.gz
rm -rf $W
