#!/usr/bin/env bash
# Session 47, call 4: where the in-memory build's time goes, for LAZ's last open ratio (its
# convert adds a 1.2-1.5 s sort-and-write stage to the decode). Flat on-CPU profiles (999 Hz,
# by symbol and by DSO) of 803c858's in-memory convert of the 200 M LAS and of its LAZ, each
# also cut at its reading stage's end (LAS 0-35 % and 50-100 %, LAZ 0-75 % and 80-100 %).
# Binary: .dev/pointlet-head.xz (stripped of debug info, symbols kept); perf with its libraries
# as .dev/perfpk.tgz (recipe: docs/bench/issue15/h100-session39/1-mapped-runs/call.sh).
# Run: run(command="bash docs/bench/issue15/session47/4-h100-profile/call.sh", carry=[".dev"])
set -uo pipefail
mkdir -p $OUT/prof; exec > >(tee "$OUT/prof/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-head.xz > /tmp/p && chmod +x /tmp/p
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
P() { local name=$1 early=$2 late=$3; shift 3
  $PERF record -F 999 -o $W/$name.data -- "$@" 2>&1 | grep -E '^wrote' | cut -c1-300 | tee $R/$name-wrote.txt
  rm -f $W/s.pointlet; sync
  for cut in "" $early $late; do
    local tag=${cut:-all}; local t=${cut:+--time $cut}
    $PERF report -i $W/$name.data --no-children --sort sym $t 2>/dev/null | grep -v '^#' | grep '%' | head -60 > $R/$name-$tag-sym.txt
    $PERF report -i $W/$name.data --no-children --sort dso $t 2>/dev/null | grep -v '^#' | grep '%' | head -10 > $R/$name-$tag-dso.txt
  done
  rm -f $W/$name.data
  for cut in all $early $late; do echo "== $name $cut"; cat $R/$name-$cut-dso.txt; head -28 $R/$name-$cut-sym.txt | cut -c1-150; done; }
/tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
P las 0%-35% 50%-100% /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
rm -f $W/g.las; /tmp/p generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
P laz 0%-75% 80%-100% /tmp/p convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd $R && tar czf $OUT/prof/prof.tgz *
rm -rf $W
