#!/usr/bin/env bash
# Session 54, call 2: (a) the bucket sorts with each bucket of up to 32 K pairs sorted whole as
# packed (key offset, place) u64s by the standard library (new, `packed.diff`) against as built
# (base), on
# 200 M LAZ (three rounds of bench-read, base, packed; one discarded convert first) and 200 M
# LAS in memory (two rounds); (b) where out of core waits (call 1's sampling, which hung: bash
# 5.2's `wait` without arguments also waits for the log's `tee`): /proc/vmstat dirty and
# writeback pages every 0.5 s and the threads' kernel wait channels every 0.1 s, with the runs'
# hole punches (as built) and without (POINTLET_X=nopunch).
# Binaries (`cargo build --release -p pointlet`, `strip --strip-all`, `xz -9e`): base =
# .dev15/pointlet-x.xz, daf3e84 + `git apply switches.diff` (session 53's switches, and a
# SORT_X switch left at 0 here); new = .dev15/pointlet-y.xz, daf3e84 + session 53's
# switches.diff + packed.diff.
# Run: run(command="bash docs/bench/issue15/session54/2-h100-packed-leaves/call.sh", carry=[".dev", ".dev15"])
set -uo pipefail
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev15/pointlet-x.xz > /tmp/x && X .dev15/pointlet-y.xz > /tmp/y && chmod +x /tmp/x /tmp/y
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
  conv "LAZ new r$r" y $W/g.laz 24GiB
done
echo "at $SECONDS s"
rm -f $W/g.laz; timeout 100 /tmp/x generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
for r in 1 2; do
  conv "LAS base r$r" x $W/g.las 24GiB
  conv "LAS new r$r" y $W/g.las 24GiB
done
timeout 100 /tmp/y convert $W/g.las -o $W/m.pointlet --ram-budget 24GiB >/dev/null 2>&1
timeout 100 /tmp/x convert $W/g.las -o $W/b.pointlet --ram-budget 24GiB >/dev/null 2>&1
cmp $W/m.pointlet $W/b.pointlet && echo "new store = base store"; rm -f $W/m.pointlet $W/b.pointlet
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
echo "at $SECONDS s"
rm -rf $W
