#!/usr/bin/env bash
# Session 49: where the in-memory writing stage of a LAZ convert goes, finer than session 47's
# profile (whose emit closure, 22 % of that stage, had everything inlined): a build whose emit
# pieces are not inlined (`rows`, `stage`, `copy_records`, `split`, `split_any`,
# `position_bounds` in crates/store/src/emit.rs marked `#[inline(never)]`), flat on-CPU profile
# (999 Hz) of the 200 M LAZ convert, cut at 0-75 % and 80-100 %; then `bench-read` and convert
# of the same LAZ with that binary, two rounds (the open ratio).
# Binary: .dev15/pointlet-prof.xz (`objcopy --strip-debug`, symbols kept); perf and its libraries:
# .dev15/perfpk.txz (tar of /tmp/perfpk, recipe in docs/bench/issue15/h100-session39/1-mapped-runs/).
# Run: run(command="bash docs/bench/issue15/session49/1-h100-emit-profile/call.sh", carry=[".dev15"])
set -uo pipefail
mkdir -p $OUT/prof; exec > >(tee "$OUT/prof/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
[ -x /usr/bin/time ] || dpkg -x .dev15/time_*.deb /
X .dev15/pointlet-prof.xz > /tmp/pp && chmod +x /tmp/pp
X .dev15/perfpk.txz | tar xf - -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w15; R=/tmp/res15; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
/tmp/pp generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
$PERF record -F 999 -o $W/laz.data -- /tmp/pp convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | grep -vE '^\s*$' | tail -4 | cut -c1-300
rm -f $W/s.pointlet; sync
for cut in "" 0%-75% 80%-100%; do
  tag=${cut:-all}; t=${cut:+--time $cut}
  $PERF report -i $W/laz.data --no-children --sort sym $t 2>/dev/null | grep -v '^#' | grep '%' | head -70 > $R/laz-$tag-sym.txt
  $PERF report -i $W/laz.data --no-children --sort dso $t 2>/dev/null | grep -v '^#' | grep '%' | head -10 > $R/laz-$tag-dso.txt
  echo "== laz $tag"; cat $R/laz-$tag-dso.txt; head -40 $R/laz-$tag-sym.txt | cut -c1-150
done
rm -f $W/laz.data
echo "at $SECONDS s"
for r in 1 2; do
  /tmp/pp bench-read $W/g.laz 2>&1 | tail -2
  /usr/bin/time -f "%e s wall, %U user, %S sys, %M KB" /tmp/pp convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -4
  rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
cd $R && tar czf $OUT/prof/prof.tgz *
rm -rf $W
