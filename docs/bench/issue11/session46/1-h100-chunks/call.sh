#!/usr/bin/env bash
# Session 46, call 1: session 45's prepared call 3 (head = 03b0de3, the whole buffer made
# before the first frame, against new2 = 27077d9, a store's buffer in chunks of the binding
# limit made by the render thread one a frame), then issue 15's out-of-core build with its
# runs on the disk's page cache against tmpfs (plain, and with huge pages where mounting works).
# Binaries: .dev/pointlet-{head,new2}.xz (`cargo build --release -p pointlet`,
# `objcopy --strip-debug`, `xz -6`).
# Run: run(command="bash docs/bench/issue11/session46/1-h100-chunks/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c1; exec > >(tee "$OUT/c1/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="head new2"
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
W=/tmp/wt; T=/tmp/res; mkdir -p $W $T; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; free -g | head -2; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
findmnt -T /tmp; df -h /dev/shm; cat /sys/kernel/mm/transparent_hugepage/shmem_enabled; sysctl vm.dirty_ratio vm.dirty_background_ratio 2>/dev/null
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^[0-9]+ frames:|^while loading:|^loading:|^opening:|after the first frame|fill [(]GPU[)]' $T/$name.txt | tr '\n' ' ' | cut -c1-900)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
/tmp/p-head generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 1 --vram-budget 16GiB
done; done
rm -f $W/s200.pointlet
echo "at $SECONDS s"
timeout 180 /tmp/p-head generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet > /dev/null
for r in 1 2; do for v in $V; do
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
done; done
rm -f $W/s1g.pointlet
echo "at $SECONDS s"
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' $T/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $T/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
/tmp/p-new2 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
mkdir -p /dev/shm/r /mnt/huge; TMPS="$W /dev/shm/r"
mount -t tmpfs -o huge=always,size=40G tmpfs /mnt/huge && TMPS="$TMPS /mnt/huge" || echo "no huge tmpfs"
M="convert $L -o $W/s.pointlet"
for r in 1 2; do
  C mem-$r /tmp/p-new2 $M --ram-budget 24GiB
  for t in $TMPS; do C ooc-$(basename $t)-$r /tmp/p-new2 $M --ram-budget 1GiB --tmp $t; done
done
grep -i huge /proc/meminfo | head -4
echo "at $SECONDS s"
cd $T && tar czf $OUT/c1/runs.tgz *.txt
rm -rf $W
