#!/usr/bin/env bash
# Session 55, call 1: session 54's prepared call 2 with a third build. (a) 200 M LAZ, one
# discarded convert, then three rounds of bench-read and a convert by each build; 200 M LAS in
# memory, two rounds of each; the three builds' stores compared; (b) out of core (1 GiB):
# /proc/vmstat dirty and writeback pages every 0.5 s and the threads' kernel wait channels
# every 0.1 s, with the runs' hole punches (as built) and without (POINTLET_X=nopunch), then
# the newest build once.
# Builds (`cargo build --release -p pointlet`, `strip --strip-all`, `xz -9e`), all with
# session 53's `switches.diff` (experiment switches, off unless POINTLET_X names them):
#   x = daf3e84 + session 54's switches.diff (base: radix leaves);
#   y = daf3e84 + session 54's packed.diff (the bucket sorts as landed in c6f5ce8);
#   z = 7f94f7b + rows.diff (y, and LAS records turned into rows one record at a time).
# Run: run(command="bash docs/bench/issue15/session55/1-h100-rows/call.sh", carry=[".dev", ".dev15"])
set -uo pipefail
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev15/pointlet-x.xz > /tmp/x && X .dev15/pointlet-y.xz > /tmp/y && X .dev15/pointlet-z.xz > /tmp/z && chmod +x /tmp/x /tmp/y /tmp/z
dpkg -x .dev/time_1.9-0.2_amd64.deb /tmp/tm 2>/dev/null; T=/tmp/tm/usr/bin/time
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w15
mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; uname -r; df -h $W | tail -1; lscpu | grep -E 'Thread|Core|Socket'
conv() { # label binary input budget
  $T -f "cpu %U user %S sys" timeout 100 /tmp/$2 convert $3 -o $W/s.pointlet --ram-budget $4 2>&1 | grep -E '^wrote|^cpu' | tr '\n' ' ' | sed "s|$W/||g; s|^|$1: |"; echo; rm -f $W/s.pointlet; sync; }
timeout 150 /tmp/x generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
conv warm-up x $W/g.laz 24GiB
for r in 1 2 3; do
  timeout 60 /tmp/x bench-read $W/g.laz 2>&1 | tail -1
  conv "LAZ base r$r" x $W/g.laz 24GiB
  conv "LAZ packed r$r" y $W/g.laz 24GiB
  conv "LAZ rows r$r" z $W/g.laz 24GiB
done
echo "at $SECONDS s"
rm -f $W/g.laz; timeout 100 /tmp/x generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
for r in 1 2; do
  conv "LAS base r$r" x $W/g.las 24GiB
  conv "LAS packed r$r" y $W/g.las 24GiB
  conv "LAS rows r$r" z $W/g.las 24GiB
done
timeout 100 /tmp/y convert $W/g.las -o $W/m.pointlet --ram-budget 24GiB >/dev/null 2>&1
timeout 100 /tmp/x convert $W/g.las -o $W/b.pointlet --ram-budget 24GiB >/dev/null 2>&1
cmp $W/m.pointlet $W/b.pointlet && echo "packed store = base store"; rm -f $W/m.pointlet
timeout 100 /tmp/z convert $W/g.las -o $W/m.pointlet --ram-budget 24GiB >/dev/null 2>&1
cmp $W/m.pointlet $W/b.pointlet && echo "rows store = base store"; rm -f $W/m.pointlet $W/b.pointlet
echo "at $SECONDS s"
for v in none nopunch; do
  ( for i in $(seq 1 30); do echo "t=$i/2 $(grep -E '^nr_(dirty|writeback|dirty_threshold|dirty_background_threshold) ' /proc/vmstat | tr '\n' ' ')"; sleep 0.5; done ) > /tmp/vm-$v.txt &
  S=$!
  ( sleep 0.3; P=$(pgrep -f '^/tmp/x convert' | head -1); for i in $(seq 1 120); do grep -h . /proc/$P/task/*/wchan 2>/dev/null; echo; sleep 0.1; done ) > /tmp/wchan-$v.txt &
  C=$!
  POINTLET_X=$v conv "LAS out of core, $v" x $W/g.las 1GiB
  kill $S $C 2>/dev/null; wait $S $C 2>/dev/null
  cat /tmp/vm-$v.txt; echo "wait channels ($v), samples of all threads:"; grep -v '^$' /tmp/wchan-$v.txt | sort | uniq -c | sort -rn | head -12
done
conv "LAS out of core, rows build" z $W/g.las 1GiB
conv "LAS in memory, rows build" z $W/g.las 24GiB
echo "at $SECONDS s"
rm -rf $W
