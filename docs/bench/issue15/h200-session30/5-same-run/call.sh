#!/usr/bin/env bash
# session 30 call 5 (issue 15): the build of call 4 (radix buckets of ~4096 pairs, the merge
# releasing read run pages), 200 M generated LAS, the disk left to finish writing the input
# first: in memory three times, PotreeConverter on the same file, in memory again, out of
# core (--ram-budget 1GiB) twice.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-r4.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 3; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"; rm -rf $W/s.pointlet $W/potree; sync; }
for r in 1 2 3; do C mem-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 24GiB; done
C potree .dev/potree/run.sh $L -o $W/potree
C mem-4 /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 24GiB
for r in 1 2; do C ooc-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W; done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
