#!/usr/bin/env bash
# Session 53: what bounds the writing stage on the GPU machine? Call 1 took ~70 % of the bucket
# sorts' work away (dev) and the writing stage did not shorten. A build of daf3e84 with
# experiment switches (`switches.diff`; POINTLET_X=nosort: buckets left unsorted; seq: each
# pointlet's records taken in run order, no scattered gather; nomap: streams computed into
# reused buffers, nothing written to the mapping; nopunch: spilled runs' pages left in place
# when read): stores are wrong with the first three, the stage
# times are what count. 200 M LAS in memory, each switch and all three, two rounds alternated. Then
# two out-of-core builds (the runs' pages punched out as they are read, as built, and with
# POINTLET_X=nopunch not) with /proc/vmstat's dirty and writeback pages and the threads' kernel
# wait channels sampled (call 1's out of core took 7.4-7.9 s on its host, the CPU 36 % busy:
# does a hole punch wait on the runs' writeback?).
# Binary: .dev15/pointlet-x.xz (daf3e84 with `git apply switches.diff`, `cargo build --release -p
# pointlet`, `strip --strip-all`, `xz -9e`; estimated ~2 min on one host). Prepared in session 53, not run:
# no machine could be started after call 1.
# Run: run(command="bash docs/bench/issue15/session53/2-h100-writing-parts/call.sh", carry=[".dev", ".dev15"])
set -uo pipefail
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev15/pointlet-x.xz > /tmp/x && chmod +x /tmp/x
dpkg -x .dev/time_1.9-0.2_amd64.deb /tmp/tm 2>/dev/null; T=/tmp/tm/usr/bin/time
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w15
mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; uname -r; df -h $W | tail -1
free -g; grep -H . /proc/sys/vm/dirty_ratio /proc/sys/vm/dirty_background_ratio /proc/sys/vm/dirty_bytes /proc/sys/vm/dirty_background_bytes
conv() { # label budget
  $T -f "cpu %U user %S sys" timeout 100 /tmp/x convert $W/g.las -o $W/s.pointlet --ram-budget $2 2>&1 | grep -E '^wrote|^cpu' | tr '\n' ' ' | sed "s|$W/||g; s|^|$1: |"; echo; rm -f $W/s.pointlet; sync; }
timeout 100 /tmp/x generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
POINTLET_X= conv warm-up 24GiB
for r in 1 2; do
  for v in none nosort seq nomap nosort,seq,nomap; do
    POINTLET_X=$v conv "$v r$r" 24GiB
  done
done
echo "at $SECONDS s"
# Out of core twice (runs' pages punched out as read, as built; and not): dirty and writeback
# pages every 0.5 s, and what the build's threads wait in (their kernel wait channel) every
# 0.1 s, counted.
for v in none nopunch; do
  ( for i in $(seq 1 40); do echo "t=$i/2 $(grep -E '^nr_(dirty|writeback|dirty_threshold|dirty_background_threshold) ' /proc/vmstat | tr '\n' ' ')"; sleep 0.5; done ) > /tmp/vm-$v.txt &
  S=$!
  ( sleep 0.3; P=$(pgrep -f '^/tmp/x convert' | head -1); for i in $(seq 1 150); do grep -h . /proc/$P/task/*/wchan 2>/dev/null; sleep 0.1; done ) > /tmp/wchan-$v.txt &
  C=$!
  POINTLET_X=$v conv "out of core, $v" 1GiB
  kill $S $C 2>/dev/null; wait
  cat /tmp/vm-$v.txt; echo "wait channels ($v), samples of all threads:"; grep -v '^$' /tmp/wchan-$v.txt | sort | uniq -c | sort -rn | head -15
done
POINTLET_X= conv "in memory" 24GiB
echo "at $SECONDS s"
rm -rf $W
