#!/usr/bin/env bash
# Session 42, third call: where out of core's extra ~11 core-s go (call 1: 24.7-25.5 user +
# 9.0-10.2 sys s out of core against 17.4-18.3 + 5.1-6.5 in memory). Flat on-CPU profiles (999
# Hz, by symbol and by DSO) of s42a in memory and out of core (1 GiB), the out-of-core one also
# cut at 45 % of its time (about the reading stage's end). One archive comes back.
# Run: run(command="bash docs/bench/issue15/session42/3-h100-profile/call.sh", carry=[".dev/pointlet-s42a.xz",
#   ".dev/time_1.9-0.2_amd64.deb", ".dev/perfpk.tgz"])
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-s42a.xz > /tmp/p && chmod +x /tmp/p
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
/tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
P() { local name=$1; shift
  $PERF record -F 999 -o $W/$name.data -- "$@" 2>&1 | grep -E '^wrote' | cut -c1-400 | tee $R/$name-wrote.txt
  rm -f $W/s.pointlet; sync
  for cut in "" 0%-45% 45%-100%; do
    local tag=${cut:-all}; local t=${cut:+--time $cut}
    $PERF report -i $W/$name.data --no-children --sort sym $t 2>/dev/null | grep -v '^#' | grep '%' | head -70 > $R/$name-$tag-sym.txt
    $PERF report -i $W/$name.data --no-children --sort dso $t 2>/dev/null | grep -v '^#' | grep '%' | head -12 > $R/$name-$tag-dso.txt
  done
  rm -f $W/$name.data; }
P mem /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
P ooc /tmp/p convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
echo "at $SECONDS s"
for f in mem-all ooc-all ooc-0%-45% ooc-45%-100%; do echo "== $f"; cat $R/$f-dso.txt; head -25 $R/$f-sym.txt | cut -c1-160; done
cd $R && tar czf $OUT/prof.tgz *
rm -rf $W
