#!/usr/bin/env bash
# session 33 call 5 (issue 15): the mapped writing stage with a stretch per block and leaves of
# the bucket sort packed into u64 (code.diff against bc066cd, pointlet-t10) against the same
# with the tuple sort in the leaves (XP_OLDLEAF, a switch of this build only) and against
# bc066cd (pointlet-t6), alternated, three rounds, 200 M generated LAS; PotreeConverter in the
# same call; out of core (1 GiB) twice; LAZ decode and convert. Stores compared.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t6.gz > /tmp/pold && chmod +x /tmp/pold
gunzip -c .dev/pointlet-t10.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las; Z=$W/g.laz
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-150) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2 3; do
  C new-$r /tmp/pointlet $M
  C oldleaf-$r env XP_OLDLEAF=1 /tmp/pointlet $M
  C base-$r /tmp/pold $M
done
C potree .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree; sync
for r in 1 2; do C ooc-$r /tmp/pointlet convert $L -o $W/s.pointlet --ram-budget 1GiB --tmp $W; done
C new-4 /tmp/pointlet $M
echo "at $SECONDS s"
/tmp/pointlet generate --points 200M -o $Z 2>&1 | tail -1
rm -f $L $W/ref.pointlet; sync; cat $Z > /dev/null
C laz-read /tmp/pointlet bench-read $Z; tail -2 /tmp/cb/laz-read.txt | head -1
for r in 1 2; do C laz-new-$r /tmp/pointlet convert $Z -o $W/s.pointlet --ram-budget 24GiB; rm -f $W/s.pointlet $W/ref.pointlet; done
C laz-read-2 /tmp/pointlet bench-read $Z; tail -2 /tmp/cb/laz-read-2.txt | head -1
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
