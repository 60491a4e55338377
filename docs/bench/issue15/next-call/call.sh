#!/usr/bin/env bash
# Prepared in sessions 35-36 for the next lent GPU machine (issue 15), not yet run: 0b337ee or
# later (records straight into rows, 12-byte pairs, Morton codes by table since ea4a707, the LAZ
# decoder's branches made selects in 2100030..6f1ad06, and 9c12495's stored positions before
# them) against dd278fc (the binary of session 34's call 1),
# alternated: 200 M LAS in memory, three rounds; out of core; LAZ decode and convert, two
# rounds. Stores compared byte for byte; busy cores sampled during some runs (see S below).
# Out of core also a third binary, v1 with reuse-run.diff applied (session 36: a spilled run's
# memory refilled without zero-filling it first, ~12 GB less memset in a 200 M-point build; no
# difference above dev's noise with its 4 runs), alternated with v1.
# The binaries, built here (x86-64) and carried gzipped (three fit the 64 MiB carry limit):
#   git worktree add /tmp/old dd278fc && (cd /tmp/old && cargo build --release -p pointlet)
#   objcopy --strip-debug /tmp/old/target/release/pointlet /tmp/p && gzip -1 -c /tmp/p > .dev/pointlet-u1.gz
#   (the same from 0b337ee or later into .dev/pointlet-v1.gz, and from it with reuse-run.diff
#   applied into .dev/pointlet-w1.gz; ~15 MB each), with the Debian `time` .deb in .dev/
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-u1.gz",
#   ".dev/pointlet-v1.gz", ".dev/pointlet-w1.gz", ".dev/time_1.9-0.2_amd64.deb"]).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-u1.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-v1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
gunzip -c .dev/pointlet-w1.gz > /tmp/preuse && chmod +x /tmp/preuse
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-190) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
# S: C with /proc/stat's first line sampled every 0.1 s into $OUT/cpu-NAME.txt: cores busy over
# time show which stage of the out-of-core build leaves cores idle (`awk -v cores=16 -f
# busy.awk $OUT/cpu-ooc-new.txt`).
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.1; done) > $OUT/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
S mem-new /tmp/pointlet $M --ram-budget 24GiB
for r in 1 2 3; do
  C new-$r /tmp/pointlet $M --ram-budget 24GiB
  C old-$r /tmp/pold $M --ram-budget 24GiB
done
S ooc-new /tmp/pointlet $M --ram-budget 1GiB --tmp $W
S ooc-reuse /tmp/preuse $M --ram-budget 1GiB --tmp $W
S ooc-old /tmp/pold $M --ram-budget 1GiB --tmp $W
C ooc-new2 /tmp/pointlet $M --ram-budget 1GiB --tmp $W
C ooc-reuse2 /tmp/preuse $M --ram-budget 1GiB --tmp $W
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; /tmp/pointlet generate --points 200M -o $Z 2>&1 | tail -1
sync; cat $Z > /dev/null
Mz="convert $Z -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2; do
  C laz-read-$r /tmp/pointlet bench-read $Z
  C laz-new-$r /tmp/pointlet $Mz
  C laz-old-$r /tmp/pold $Mz
done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
