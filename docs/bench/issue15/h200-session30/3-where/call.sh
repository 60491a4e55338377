#!/usr/bin/env bash
# session 30 call 3 (issue 15): where the out-of-core reading stage waits. The build of call 2
# (the merge releasing read run pages), 200 M generated LAS, --ram-budget 1GiB: runs on the
# disk (--tmp on ext4) with /proc/meminfo's Dirty and Writeback and the threads' wait channels
# sampled every 0.2 s, against runs on a tmpfs (--tmp /dev/shm); in memory before and after.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-r2.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb /dev/shm/r; SECONDS=0
grep -H . /proc/sys/vm/dirty_* ; mount | grep -E " / | /tmp " ; df -h /tmp /dev/shm
/tmp/pointlet generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 2; cat $W/g.las > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -f $W/s.pointlet; sync; }
S() { # NAME: an out-of-core build on the disk, sampled
  /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp $W > /tmp/cb/$1.txt 2>&1 & local pid=$!
  local t0=$SECONDS; : > /tmp/cb/$1-mem.txt; : > /tmp/cb/$1-wchan.txt
  while kill -0 $pid 2>/dev/null; do
    echo "$(date +%s.%N | cut -c7-14) $(awk '/^(Dirty|Writeback):/ {printf "%s %d MB ", $1, $2/1024}' /proc/meminfo)" >> /tmp/cb/$1-mem.txt
    for t in /proc/$pid/task/*; do echo "$(cat $t/comm 2>/dev/null) $(cat $t/wchan 2>/dev/null)"; done >> /tmp/cb/$1-wchan.txt
    sleep 0.2
  done; wait $pid
  echo "$1: $(grep -E '^wrote' /tmp/cb/$1.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150)"
  sort /tmp/cb/$1-wchan.txt | uniq -c | sort -rn | head -12
  awk 'NR % 5 == 1' /tmp/cb/$1-mem.txt
  rm -f $W/s.pointlet; sync
}
C mem-1 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2; do
  S ooc-disk-$r
  C ooc-shm-$r /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB --tmp /dev/shm/r
done
C mem-2 /tmp/pointlet convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W /dev/shm/r
