#!/usr/bin/env bash
# Prepared in session 39 for the next lent GPU machine (issue 15), not yet run: the session's
# device time was spent. s5 = 11aa57f (runs gathered into a mapping of their file, keys eight at
# a time with BMI2) against s6 = 82cea12 (keys without the saturating float conversion and with
# a fixed state table, 7.7 against 9.6 ns on dev; out of core a group's run pages given back once
# all its reads are done, one `fallocate` per run piece, not after every 4 MiB read of the same
# run file). 200 M LAS: in memory and out of core at 1 GiB, alternated, two rounds, and
# PotreeConverter once; 200 M LAZ: `bench-read`, s5 and s6 alternated, two rounds. Every store
# compared byte for byte with the first of its input.
# Binaries built here (x86-64), stripped and carried as xz (the tracked tree is ~28 MB of the
# 64 MiB that travels): for each commit C, `git checkout C && cargo build --release -p pointlet
# && objcopy --strip-debug target/release/pointlet /tmp/p && xz -9 -c /tmp/p >
# .dev/pointlet-sN.xz`; the Debian `time` .deb (`apt-get download time`) and PotreeConverter
# (`cp -r ../shared/tools/potree-converter .dev/potree`), in .dev/, which a fresh checkout must
# ignore first: `mkdir -p .git/info && echo /.dev/ >> .git/info/exclude`.
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-s5.xz",
#   ".dev/pointlet-s6.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/potree"]) -- about 4 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 5 6; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo; uname -r
L=$W/g.las
/tmp/ps5 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
C las-read /tmp/ps6 bench-read $L
for r in 1 2; do
  C mem-s5-$r /tmp/ps5 $M --ram-budget 24GiB
  S mem-s6-$r /tmp/ps6 $M --ram-budget 24GiB
  C ooc-s5-$r /tmp/ps5 $M --ram-budget 1GiB --tmp $W
  S ooc-s6-$r /tmp/ps6 $M --ram-budget 1GiB --tmp $W
done
S potree bash .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/ps5 generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in 1 2; do
  C laz-read-$r /tmp/ps6 bench-read $W/g.laz
  C laz-s5-$r /tmp/ps5 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  S laz-s6-$r /tmp/ps6 convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
