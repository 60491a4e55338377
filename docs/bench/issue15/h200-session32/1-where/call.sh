#!/usr/bin/env bash
# session 32 call 1 (issue 15): page-cache write throughput by number of writers (dd, ext4 and
# tmpfs, and O_DIRECT to the disk), then the 200 M LAS converted in memory and out of core
# (--ram-budget 1GiB) with XP_TRACE (per-run fill, spill wait, sort, gather, write times) and
# one out-of-core build under perf record (flat, by symbol and by thread). (The first attempt
# hung in its first `wait`, which also waited for the tee of the log: 10 minutes lost.)
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
cat /proc/sys/kernel/perf_event_paranoid /proc/sys/kernel/kptr_restrict 2>&1
W=/tmp/w; mkdir -p $W /tmp/cb /dev/shm/d; SECONDS=0
DD() { # DIR WRITERS COUNT(16 MiB blocks) [oflag]
  local d=$1 n=$2 c=$3 fl=${4:-}; local t0=$(date +%s.%N)
  local p=(); for i in $(seq $n); do dd if=/dev/zero of=$d/dd$i bs=16M count=$c $fl 2>/dev/null & p+=($!); done; wait ${p[@]}
  local t1=$(date +%s.%N)
  echo "dd $d writers=$n each=$((c*16)) MiB $fl: $(awk -v a=$t0 -v b=$t1 -v s=$((n*c*16)) "BEGIN{printf \"%.2f\", s/1024/(b-a)}") GiB/s"
  if [ -z "$fl" ]; then t0=$(date +%s.%N); p=(); for i in $(seq $n); do dd if=$d/dd$i of=/dev/null bs=16M 2>/dev/null & p+=($!); done; wait ${p[@]}; t1=$(date +%s.%N)
    echo "   read back: $(awk -v a=$t0 -v b=$t1 -v s=$((n*c*16)) "BEGIN{printf \"%.2f\", s/1024/(b-a)}") GiB/s"; fi
  rm -f $d/dd*; sync
}
for n in 1 2 4 8 16; do DD $W $n 128; done
for n in 1 4 16; do DD /dev/shm/d $n 128; done
for n in 1 4; do timeout 60 bash -c "$(declare -f DD); DD $W $n 32 oflag=direct"; done
echo "at $SECONDS s"
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
XP_TRACE=1 C ooc-trace-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
grep XP /tmp/cb/ooc-trace-1.txt | head -30
$PERF record -F 999 -o $W/p.data /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W > /tmp/cb/perf-ooc.txt 2>&1
rm -f $W/s.pointlet; sync
$PERF report -i $W/p.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -70 > /tmp/cb/perf-ooc-sym.txt
$PERF report -i $W/p.data --no-children --sort comm,dso 2>/dev/null | grep -v '^#' | grep '%' | head -30 > /tmp/cb/perf-ooc-comm.txt
head -45 /tmp/cb/perf-ooc-sym.txt; head -15 /tmp/cb/perf-ooc-comm.txt
XP_TRACE=1 C ooc-trace-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W /dev/shm/d
