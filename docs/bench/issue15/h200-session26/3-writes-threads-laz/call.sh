#!/usr/bin/env bash
# Device call 3 (session 26): one file's write rate by mode and threads (the writing stage's
# bound), the writing stage with fewer computing threads beside the two writers (16 / 14 / 12,
# alternated), and LAZ loading while drawing with the current code on this instance.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-head.gz > /tmp/pointlet && chmod +x /tmp/pointlet
gunzip -c .dev/pointlet-emit.gz > /tmp/pointlet-emit && chmod +x /tmp/pointlet-emit
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
P=/tmp/pointlet
W=/tmp/w; mkdir -p $W
uname -r; nproc
for m in pwrite-falloc mmap-populate-falloc; do for t in 1 2 4 16; do
  echo "write_bench $m $t: $(.dev/write_bench $W/wb.bin 8 $t $m 2>&1 | tr '\n' ' ')"; done; done
$P generate --points 200M -o $W/g.las
sync; sleep 2
for r in 1 2; do for t in 16 14 12; do
  rm -f $W/s.pointlet; sync; cat $W/g.las > /dev/null
  echo "emit-$t-$r: $(POINTLET_EMIT_THREADS=$t /usr/bin/time -f '%e s %P %M KB' /tmp/pointlet-emit convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB 2>&1 | grep -E 'wrote|KB' | tr '\n' ' ')"
done; done
rm -f $W/s.pointlet $W/g.las; sync
$P generate --points 200M -o $W/g.laz
sync; cat $W/g.laz > /dev/null
for r in 1 2; do
  $P bench-read $W/g.laz 2>&1 | tail -1
  $P bench $W/g.laz --realtime --orbit-seconds 12 --target-fps 60 --vram-budget 16GiB > $OUT/laz-load-$r.txt 2>&1
  grep -E 'loading:|while loading' $OUT/laz-load-$r.txt
done
rm -rf $W
