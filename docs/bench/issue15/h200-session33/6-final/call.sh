#!/usr/bin/env bash
# session 33 call 6 (issue 15): the committed code (code.diff against bc066cd, pointlet-t11)
# against bc066cd (pointlet-t6), alternated, three rounds in memory, 200 M generated LAS, page
# cache warm, `sync` after each run; PotreeConverter in the same call; out of core (1 GiB)
# once; stores compared. (The commit adds one line to this code.diff: leaves of fewer than 2 pairs
# return at once; this release build sent them, empty ones included, to the tuple sort.)
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t6.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-t11.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2 3; do C new-$r /tmp/pointlet $M; C base-$r /tmp/pold $M; done
C potree .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree; sync
C ooc-1 /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W
C new-4 /tmp/pointlet $M
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
