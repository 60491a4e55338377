#!/usr/bin/env bash
# Device call (session 27): a store read with --progressive, committed loader (head: positions
# dequantized and encoded on the CPU) against stored positions dequantized on the GPU (new),
# alternated; the upload path's own speed (new prints it); then a 1 G-point store.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for b in head new; do gunzip -c .dev/pointlet-$b.gz > /tmp/pointlet-$b && chmod +x /tmp/pointlet-$b; done
W=/tmp/w; mkdir -p $W
uname -r; nproc; grep -m1 'model name' /proc/cpuinfo; free -g | head -2; df -h /tmp | tail -1
nvidia-smi --query-gpu=name,pcie.link.gen.current,pcie.link.width.current,pcie.link.gen.max --format=csv
B() { local name=$1 bin=$2 file=$3; shift 3; /tmp/pointlet-$bin bench $file --progressive --realtime --orbit-seconds 4 --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -E '^upload path' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
SECONDS=0
/tmp/pointlet-new generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
echo "generated in $SECONDS s"
sync; sleep 2; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do
  for b in head new; do B s200-$b-$r $b $W/s200.pointlet --vram-budget 16GiB; done
done
B s200-new-elevation new $W/s200.pointlet --vram-budget 16GiB --color elevation
B s200-new-intensity new $W/s200.pointlet --vram-budget 16GiB --color intensity
rm -f $W/s200.pointlet
echo "at $SECONDS s"
SECONDS=0
timeout 200 /tmp/pointlet-new generate --points 1G -o $W/s1g.pointlet 2>&1 | tail -1
echo "generated 1G in $SECONDS s"; ls -la $W
if [ -f $W/s1g.pointlet ]; then
  sync; cat $W/s1g.pointlet > /dev/null
  for r in 1 2; do
    for b in new head; do B s1g-$b-$r $b $W/s1g.pointlet --vram-budget 24GiB; done
  done
fi
cd $OUT && gzip -f *.json && tar czf runs.tgz *.txt *.json.gz && rm -f s*.txt s*.json.gz
rm -rf $W
