#!/usr/bin/env bash
# Device call 4 (session 26): the store filled through a shared map by four writer threads
# (map) against positioned writes from two (pwrite: the committed code's way), alternated, three
# rounds; out of core mapped; PotreeConverter in the same call.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
gunzip -c .dev/pointlet-map.gz > /tmp/pointlet && chmod +x /tmp/pointlet
P=/tmp/pointlet
W=/tmp/w; mkdir -p $W
uname -r; nproc
T() { local name=$1; shift; /usr/bin/time -v -o $OUT/$name.time "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|decoded' $OUT/$name.txt | tail -1) | $(grep -E 'Elapsed' $OUT/$name.time | awk '{print $NF}') | CPU $(grep Percent $OUT/$name.time | awk '{print $NF}') | RSS $(grep Maximum $OUT/$name.time | awk '{print $NF}') kB | $(grep trace $OUT/$name.txt)"; }
$P generate --points 200M -o $W/g.las
sync; sleep 2; cat $W/g.las > /dev/null
T las-read $P bench-read $W/g.las
for r in 1 2 3; do for v in pwrite map; do
  case $v in pwrite) e="POINTLET_STORE_WRITES=pwrite";; map) e="X=1";; esac
  rm -f $W/s.pointlet; sync; cat $W/g.las > /dev/null
  T las-mem-$v-$r env $e $P convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
  [ $v = pwrite ] && [ $r = 1 ] && mv $W/s.pointlet $W/ref.pointlet
  [ -f $W/s.pointlet ] && { cmp -s $W/s.pointlet $W/ref.pointlet && echo "  identical to pwrite-1" || echo "  DIFFERS from pwrite-1"; }
done; done
rm -f $W/s.pointlet $W/ref.pointlet; sync
cat $W/g.las > /dev/null
T potree .dev/potree/run.sh $W/g.las -o $W/potree
rm -rf $W/potree
rm -f $W/s.pointlet; sync; cat $W/g.las > /dev/null
T las-ooc-map $P convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
cd $OUT && tar czf runs.tgz *.txt *.time && rm -f las-* laz-* potree.*
rm -rf $W
