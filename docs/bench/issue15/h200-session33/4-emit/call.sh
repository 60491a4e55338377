#!/usr/bin/env bash
# session 33 call 4 (issue 15): the mapped in-memory writing stage's emit, variants by switch
# (experiment.diff against bc066cd, pointlet-t9): XP_BIGBLOCK (with the mapping, a stretch's
# pointlets computed in one parallel pass instead of 16 MiB blocks), XP_LOCAL (each pointlet's
# records copied once into a local buffer in shuffled order, streams split from it), both;
# per-stretch XP_TRACE, 200 M generated LAS, alternated, two rounds; stores compared.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t9.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
V() { local name=$1; shift; env "$@" XP_TRACE=1 /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" /tmp/pointlet $M > /tmp/cb/$name.txt 2>&1
  echo "$name: $(grep -E '^wrote' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-120) | $(tail -1 /tmp/cb/$name.txt)"
  grep XP /tmp/cb/$name.txt | awk '{e+=$5; s+=$8; j+=$11; r+=$14; n++} END{printf "   stretches %d: emit %.0f ms, sort %.0f ms, join %.0f ms, release %.0f ms\n", n, e, s, j, r}'
  if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; sync; }
for r in 1 2; do
  V none-$r XP_NONE=1; V big-$r XP_BIGBLOCK=1; V local-$r XP_LOCAL=1; V both-$r XP_BIGBLOCK=1 XP_LOCAL=1
done
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
