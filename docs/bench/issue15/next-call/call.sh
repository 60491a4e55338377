#!/usr/bin/env bash
# Prepared in session 35 for the next lent GPU machine (issue 15), not yet run: 0b337ee
# (records straight into rows, 12-byte pairs, and 9c12495's stored positions before them) against
# dd278fc (the binary of session 34's call 1), alternated: 200 M LAS in memory, three rounds;
# out of core; LAZ decode and convert, two rounds. Stores compared byte for byte.
# The binaries, built here (x86-64) and carried gzipped (two fit the carry limit):
#   git worktree add /tmp/old dd278fc && (cd /tmp/old && cargo build --release -p pointlet)
#   objcopy --strip-debug /tmp/old/target/release/pointlet /tmp/p && gzip -1 -c /tmp/p > .dev/pointlet-u1.gz
#   (the same from 0b337ee or later into .dev/pointlet-v1.gz), with the Debian `time` .deb in .dev/
# Run: run(command="bash docs/bench/issue15/next-call/call.sh", carry=[".dev/pointlet-u1.gz",
#   ".dev/pointlet-v1.gz", ".dev/time_1.9-0.2_amd64.deb"]) (the whole .dev is over the limit).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-u1.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-v1.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-190) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
M="convert $L -o $W/s.pointlet"
for r in 1 2 3; do
  C new-$r /tmp/pointlet $M --ram-budget 24GiB
  C old-$r /tmp/pold $M --ram-budget 24GiB
done
C ooc-new /tmp/pointlet $M --ram-budget 1GiB --tmp $W
C ooc-old /tmp/pold $M --ram-budget 1GiB --tmp $W
C ooc-new2 /tmp/pointlet $M --ram-budget 1GiB --tmp $W
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
