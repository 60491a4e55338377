#!/usr/bin/env bash
# session 38 call 2 (issue 15): call 1 showed the in-memory build on one core for its first
# 1.6 s (the run's pairs written as `vec![Pair::default(); n]`, 2.4 GB, before the parallel
# reading). z2 = 505f744 + those pairs (and a group's buffers out of core) taken zeroed from
# the allocator. x1 = 505f744. 200 M LAS in memory alternated, PotreeConverter in the same run,
# out of core at 1 GiB, LAZ decode against convert; busy cores sampled.
# Run: run(command="bash docs/bench/issue15/h100-session38/2-zeroed/call.sh", carry=[
#   ".dev/pointlet-x1.xz", ".dev/pointlet-z2.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/potree"])
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for b in x1 z2; do X .dev/pointlet-$b.xz > /tmp/p$b && chmod +x /tmp/p$b; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/pz2 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-230) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
C las-read /tmp/pz2 bench-read $L
S mem-z2 /tmp/pz2 $M --ram-budget 24GiB
C mem-x1 /tmp/px1 $M --ram-budget 24GiB
C mem-z2-2 /tmp/pz2 $M --ram-budget 24GiB
C mem-x1-2 /tmp/px1 $M --ram-budget 24GiB
S potree bash .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree
C mem-z2-3 /tmp/pz2 $M --ram-budget 24GiB
S ooc-z2 /tmp/pz2 $M --ram-budget 1GiB --tmp $W
C ooc-x1 /tmp/px1 $M --ram-budget 1GiB --tmp $W
C ooc-z2-2 /tmp/pz2 $M --ram-budget 1GiB --tmp $W
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/pz2 generate --points 200M -o $Z 2>&1 | tail -1
sync; cat $Z > /dev/null
Mz="convert $Z -o $W/s.pointlet --ram-budget 24GiB"
C laz-read-1 /tmp/pz2 bench-read $Z
S laz-z2-1 /tmp/pz2 $Mz
C laz-x1 /tmp/px1 $Mz
C laz-read-2 /tmp/pz2 bench-read $Z
C laz-z2-2 /tmp/pz2 $Mz
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
