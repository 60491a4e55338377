#!/usr/bin/env bash
# Prepared in sessions 35-37 for the next lent GPU machine (issue 15), not yet run. Session 37
# replaced the out-of-core path (fc6a009: runs spilled grouped by key bucket, no sort; read back
# a group of buckets at a time, sorted in memory and written through the mapping while the next
# group is read) — on dev 2.69 -> 2.06 s (medians of five alternated rounds, 20 M points, 1 GiB),
# out of core / in memory 2.24 -> 1.72x. This call measures it on 16 cores against the
# merge of sorted runs it replaced, and two variants of it:
#   v1: ec279e6 (sorted runs, parallel heap merge, two writer threads; sessions 35-36's code)
#   x1: fc6a009 or later (bucketed runs, groups, the store written through a mapping)
#   y1: x1 + ooc-writers.diff (out of core through the two writer threads instead: faster on dev)
#   w1: x1 + reuse-run.diff (a spilled run's memory refilled without zero-filling it first)
# 200 M LAS in memory (x1, v1: two rounds each; the ratio's divisor), out of core at 1 GiB
# (v1, x1, y1, w1 alternated, two rounds, busy cores sampled in the first), LAZ decode and
# convert (x1) with v1 once. Stores compared byte for byte with the first one written.
# The binaries, built here (x86-64) and carried gzipped (~15 MB each, four fit the 64 MiB carry):
#   git worktree add /tmp/old ec279e6 && (cd /tmp/old && cargo build --release -p pointlet)
#   objcopy --strip-debug /tmp/old/target/release/pointlet /tmp/p && gzip -1 -c /tmp/p > .dev/pointlet-v1.gz
#   (the same from HEAD into .dev/pointlet-x1.gz; from HEAD with ooc-writers.diff applied into
#   .dev/pointlet-y1.gz, and with reuse-run.diff applied into .dev/pointlet-w1.gz), with the
#   Debian `time` .deb (`apt-get download time`) in .dev/, which a fresh checkout must ignore
#   first: `mkdir -p .git/info && echo /.dev/ >> .git/info/exclude`
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-v1.gz",
#   ".dev/pointlet-x1.gz", ".dev/pointlet-y1.gz", ".dev/pointlet-w1.gz", ".dev/time_1.9-0.2_amd64.deb"]).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for b in v1 x1 y1 w1; do gunzip -c .dev/pointlet-$b.gz > /tmp/p$b && chmod +x /tmp/p$b; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/px1 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-230) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
# S: C with /proc/stat's first line sampled every 0.1 s into $OUT/cpu-NAME.txt: cores busy over
# time show which stage leaves cores idle (`awk -v cores=16 -f busy.awk $OUT/cpu-ooc-x1.txt`).
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
S mem-x1 /tmp/px1 $M --ram-budget 24GiB
C mem-v1 /tmp/pv1 $M --ram-budget 24GiB
C mem-x1-2 /tmp/px1 $M --ram-budget 24GiB
C mem-v1-2 /tmp/pv1 $M --ram-budget 24GiB
for b in x1 v1 y1 w1; do S ooc-$b /tmp/p$b $M --ram-budget 1GiB --tmp $W; done
for b in v1 w1 y1 x1; do C ooc-$b-2 /tmp/p$b $M --ram-budget 1GiB --tmp $W; done
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/px1 generate --points 200M -o $Z 2>&1 | tail -1
sync; cat $Z > /dev/null
Mz="convert $Z -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2; do
  C laz-read-$r /tmp/px1 bench-read $Z
  C laz-x1-$r /tmp/px1 $Mz
done
C laz-v1 /tmp/pv1 $Mz
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
