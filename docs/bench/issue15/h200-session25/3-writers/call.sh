#!/usr/bin/env bash
# Device call 3 (session 25): store writers (1/2/4 threads), LAS and LAZ conversion, LAZ
# loading with the faster arithmetic decoder, PotreeConverter in the same call.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for w in 1 2 4; do gunzip -c .dev/pointlet-w$w.gz > /tmp/pointlet-w$w && chmod +x /tmp/pointlet-w$w; done
P=/tmp/pointlet-w2
W=/tmp/w; mkdir -p $W
uname -r; nproc
T() { local name=$1; shift; /usr/bin/time -v -o $OUT/$name.time "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|decoded' $OUT/$name.txt | tail -1) | $(grep -E 'Elapsed' $OUT/$name.time | awk '{print $NF}') | CPU $(grep Percent $OUT/$name.time | awk '{print $NF}') | RSS $(grep Maximum $OUT/$name.time | awk '{print $NF}') kB"; }
for t in 1 2 4; do echo "write_bench $t: $(.dev/write_bench $W/wb.bin 8 $t pwrite-falloc 2>&1 | tr '\n' ' ')"; done
$P generate --points 200M -o $W/g.las
$P generate --points 200M -o $W/g.laz
sync; sleep 2
cat $W/g.las > /dev/null
T las-read $P bench-read $W/g.las
for r in 1 2; do for w in 1 2 4; do
  rm -f $W/s.pointlet; cat $W/g.las > /dev/null
  T las-mem-w$w-$r /tmp/pointlet-w$w convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
done; done
rm -f $W/s.pointlet; sync
cat $W/g.las > /dev/null
T potree .dev/potree/run.sh $W/g.las -o $W/potree
rm -rf $W/potree
cat $W/g.laz > /dev/null
T laz-read $P bench-read $W/g.laz
for w in 2; do rm -f $W/s.pointlet; T laz-mem-w$w /tmp/pointlet-w$w convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB; done
rm -f $W/s.pointlet; sync
$P bench $W/g.laz --realtime --orbit-seconds 12 --target-fps 60 --vram-budget 16GiB > $OUT/laz-load.txt 2>&1
grep -E 'loading:|while loading' $OUT/laz-load.txt
$P generate --points 200M -o $W/s200.pointlet
cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do
  $P bench $W/s200.pointlet --progressive --realtime --orbit-seconds 4 --target-fps 60 --vram-budget 16GiB > $OUT/store-load-$r.txt 2>&1
  grep -E 'loading:|while loading' $OUT/store-load-$r.txt
done
rm -f $W/s200.pointlet
rm -f $W/s.pointlet; sync
cat $W/g.las > /dev/null
T las-ooc-w2 $P convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
rm -rf $W
