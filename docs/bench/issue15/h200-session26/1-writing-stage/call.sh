#!/usr/bin/env bash
# Device call 1 (session 26): where the writing stage's time goes (diagnostic build with
# trace lines): LSD radix bucket sorts pipelined with the blocks (piped), the same sorted just
# before each block (serial), the comparison sort so (cmp: the committed code), sorting all
# buckets first (all), 64 MiB blocks; a perf profile; out of core; LAZ; PotreeConverter in the same call.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
gunzip -c .dev/pointlet-diag.gz > /tmp/pointlet && chmod +x /tmp/pointlet
tar xzf .dev/perfpk.tgz -C /tmp
P=/tmp/pointlet
W=/tmp/w; mkdir -p $W
uname -r; nproc; grep -m1 'model name' /proc/cpuinfo
T() { local name=$1; shift; /usr/bin/time -v -o $OUT/$name.time "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|decoded' $OUT/$name.txt | tail -1) | $(grep -E 'Elapsed' $OUT/$name.time | awk '{print $NF}') | CPU $(grep Percent $OUT/$name.time | awk '{print $NF}') | RSS $(grep Maximum $OUT/$name.time | awk '{print $NF}') kB"; grep trace $OUT/$name.txt; }
$P generate --points 200M -o $W/g.las
sync; sleep 2
cat $W/g.las > /dev/null
T las-read $P bench-read $W/g.las
for r in 1 2; do
  for v in piped serial cmp all blk64; do
    case $v in piped) e="X=1";; serial) e="POINTLET_SERIAL_EMIT=1";; cmp) e="POINTLET_SERIAL_EMIT=1 POINTLET_SORT=1";; all) e="POINTLET_SORT_ALL=1";; blk64) e="POINTLET_BLOCK_MIB=64";; esac
    rm -f $W/s.pointlet; cat $W/g.las > /dev/null
    T las-mem-$v-$r env $e $P convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
    [ $v = piped ] && [ $r = 1 ] && mv $W/s.pointlet $W/ref.pointlet
    [ -f $W/s.pointlet ] && { cmp -s $W/s.pointlet $W/ref.pointlet && echo "  identical to piped-1" || echo "  DIFFERS from piped-1"; }
  done
done
rm -f $W/s.pointlet; cat $W/g.las > /dev/null
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf record -F 1999 -o $W/p.data $P convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB 2>&1 | grep -E "wrote|trace"
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf report -i $W/p.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -60 > $OUT/perf-sym.txt
LD_LIBRARY_PATH=/tmp/perfpk/lib /tmp/perfpk/perf report -i $W/p.data --no-children --sort comm,sym 2>/dev/null | grep -v '^#' | grep '%' | head -60 > $OUT/perf-comm-sym.txt
rm -f $W/s.pointlet $W/ref.pointlet $W/p.data; sync
for v in piped cmp; do
  case $v in piped) e="X=1";; cmp) e="POINTLET_SERIAL_EMIT=1 POINTLET_SORT=1";; esac
  rm -f $W/s.pointlet; cat $W/g.las > /dev/null
  T las-ooc-$v env $e $P convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done
rm -f $W/s.pointlet; sync
cat $W/g.las > /dev/null
T potree .dev/potree/run.sh $W/g.las -o $W/potree
rm -rf $W/potree
$P generate --points 200M -o $W/g.laz
cat $W/g.laz > /dev/null
T laz-read $P bench-read $W/g.laz
rm -f $W/s.pointlet
T laz-mem $P convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
cd $OUT && tar czf runs.tgz *.txt *.time && rm -f las-* laz-* potree.* 
rm -rf $W
