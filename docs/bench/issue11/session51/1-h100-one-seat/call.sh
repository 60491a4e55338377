#!/usr/bin/env bash
# Session 51: on session 50's host (its call 1-h100-colour-loop) a store's load was bound by
# the bus, not the CPU: `bench-read --staged` read and coloured 53-61 GB/s of 16-byte points,
# the load moved 30.1-30.6 GB/s after the first frame against the 33.8-34.1 GB/s the bus takes
# either way, with copies going on 96 % of the time but 3.2 at once of the four seats. A part
# took two seats (positions, then colours), each taken by a thread woken from sleep tens of
# microseconds after it was freed (a part's copy is ~100 us): seat1w6 = one seat for both
# (`StagedRegion::write_pair`) and six seats (`BUS_WRITERS`), seat1spin = one seat for both,
# four seats, a waiting thread spinning for one up to 200 us before it sleeps; base =
# 7814aa5. The 1 G lean
# store and the 200 M store, `bench --progressive --realtime --target-fps 60` alternated, ROUNDS
# rounds, the 1 G beside `bench-read --staged`. Then issue 15's acceptance with base (the
# conversion code of 7814aa5): 200 M LAS in memory and out of core (1 GiB), PotreeConverter
# once, 200 M LAZ `bench-read` and convert, ROUNDS rounds; every store compared with the first.
# Binaries: `cargo build --release -p pointlet`, `strip --strip-all`, `xz -9e`, as
# .dev/pointlet-{base,seat1w6,seat1spin}.xz; .dev/potree: a copy of ../shared/tools/potree-converter;
# .dev/time_*.deb and .gl as in the device README.
# Run: run(command="bash docs/bench/issue11/session51/1-h100-one-seat/call.sh 3", carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c; exec > >(tee "$OUT/c/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
V="base seat1w6 seat1spin"; ROUNDS=${1:-3}
for v in $V; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
df -h /tmp . /dev/shm | cat
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/wt
T=/tmp/res; mkdir -p $W $T; SECONDS=0; echo "stores in $W"
nproc; grep -m1 'model name' /proc/cpuinfo; free -g | head -2
B() { local name=$1 bin=$2 file=$3; shift 3; timeout 100 $bin bench $file --progressive --realtime --target-fps 60 --json $T/$name.json "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^loading:|after the first frame|^upload' $T/$name.txt | tr '\n' ' ' | cut -c1-1100)"; grep -iE 'error|panick' $T/$name.txt | head -3; }
S() { local name=$1 bin=$2 file=$3; timeout 60 $bin bench-read $file --staged > $T/$name.txt 2>&1; echo "$name: $(tail -1 $T/$name.txt | cut -c1-200)"; }
timeout 180 /tmp/p-base generate --points 1G --lean -o $W/s1g.pointlet 2>&1 | tail -1
timeout 100 /tmp/p-base generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s1g.pointlet $W/s200.pointlet > /dev/null
for r in $(seq $ROUNDS); do for v in $V; do
  S s1g-staged-$v-$r /tmp/p-$v $W/s1g.pointlet
  B s1g-$v-$r /tmp/p-$v $W/s1g.pointlet --orbit-seconds 2 --vram-budget 24GiB
  B s200-$v-$r /tmp/p-$v $W/s200.pointlet --orbit-seconds 2
done; done
echo "at $SECONDS s"
rm -f $W/s1g.pointlet $W/s200.pointlet
# Issue 15 (base only).
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $T/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $T/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $T/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
timeout 100 /tmp/p-base generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
C las-read /tmp/p-base bench-read $L
C potree timeout 120 bash .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree
M="convert $L -o $W/s.pointlet"
for r in $(seq $ROUNDS); do
  C mem-$r /tmp/p-base $M --ram-budget 24GiB
  C ooc-$r /tmp/p-base $M --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; timeout 100 /tmp/p-base generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in $(seq $ROUNDS); do
  C laz-read-$r /tmp/p-base bench-read $W/g.laz
  C laz-$r /tmp/p-base convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
echo "at $SECONDS s"
cd $T && tar czf $OUT/c/runs.tgz *.txt *.json
rm -rf $W
