#!/usr/bin/env bash
# Device call 2 (session 26): the committed code (head: comparison sort of each block's buckets
# just before it) against bucket sorting in waves on a thread of its own (new: LSD radix; cmp:
# the comparison sort; w32: waves of 32 blocks), alternated, three rounds; out of core and LAZ
# with head and new; PotreeConverter in the same call.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
for b in head new; do gunzip -c .dev/pointlet-$b.gz > /tmp/pointlet-$b && chmod +x /tmp/pointlet-$b; done
W=/tmp/w; mkdir -p $W
uname -r; nproc
T() { local name=$1; shift; /usr/bin/time -v -o $OUT/$name.time "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|decoded' $OUT/$name.txt | tail -1) | $(grep -E 'Elapsed' $OUT/$name.time | awk '{print $NF}') | CPU $(grep Percent $OUT/$name.time | awk '{print $NF}') | RSS $(grep Maximum $OUT/$name.time | awk '{print $NF}') kB"; grep trace $OUT/$name.txt; }
/tmp/pointlet-new generate --points 200M -o $W/g.las
sync; sleep 2
cat $W/g.las > /dev/null
T las-read /tmp/pointlet-new bench-read $W/g.las
for r in 1 2 3; do
  for v in head new cmp w32; do
    case $v in head) b=head; e="X=1";; new) b=new; e="X=1";; cmp) b=new; e="POINTLET_SORT=1";; w32) b=new; e="POINTLET_WAVE_BLOCKS=32";; esac
    rm -f $W/s.pointlet; sync; cat $W/g.las > /dev/null
    T las-mem-$v-$r env $e /tmp/pointlet-$b convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
    [ $v = head ] && [ $r = 1 ] && mv $W/s.pointlet $W/ref.pointlet
    [ -f $W/s.pointlet ] && { cmp -s $W/s.pointlet $W/ref.pointlet && echo "  identical to head-1" || echo "  DIFFERS from head-1"; }
  done
done
rm -f $W/s.pointlet $W/ref.pointlet; sync
for b in head new; do
  rm -f $W/s.pointlet; sync; cat $W/g.las > /dev/null
  T las-ooc-$b /tmp/pointlet-$b convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
done
rm -f $W/s.pointlet; sync
cat $W/g.las > /dev/null
T potree .dev/potree/run.sh $W/g.las -o $W/potree
rm -rf $W/potree
/tmp/pointlet-new generate --points 200M -o $W/g.laz
cat $W/g.laz > /dev/null
T laz-read /tmp/pointlet-new bench-read $W/g.laz
for b in head new; do
  rm -f $W/s.pointlet; sync
  T laz-mem-$b /tmp/pointlet-$b convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
cd $OUT && tar czf runs.tgz *.txt *.time && rm -f las-* laz-* potree.*
rm -rf $W
