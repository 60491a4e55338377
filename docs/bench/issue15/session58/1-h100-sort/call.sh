#!/usr/bin/env bash
# Session 58, call 1: an A/B of the bucket sorts' sub-buckets, then the acceptance benchmark of
# issue 15 with the new build, in one call of ~4 min (machines were scarce). Builds (`objcopy
# --strip-debug`, `xz`): base = 3d28750 (.dev58/pointlet-base.xz), c = base + c.diff beside
# this file (.dev58/pointlet-c.xz: sub-buckets sorted from the second array back into place,
# three more radix bits for buckets over 32 K pairs; 4912ef2's code but for comments and a
# test). 200 M generated points.
# 1. LAZ: three rounds of `bench-read`, then an in-memory convert by each build (order
#    alternating); every store compared with base's.
# 2. `scripts/convert-bench.sh` with c on the same inputs: LAS decode, two in-memory and two
#    out-of-core converts, four alternated LAZ decode and convert rounds, PotreeConverter once
#    (.dev55: its folder from ../shared/tools/potree-converter, the Debian `time` .deb).
# Run: run(command="bash docs/bench/issue15/session58/1-h100-sort/call.sh", carry=[".dev58", ".dev55"])
# Short form (~2.5 min): AB_ROUNDS=4 ACCEPT=0, two LAS rounds of each build instead of part 2.
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT/cb; exec > >(tee "$OUT/log.txt") 2>&1
B=/tmp/pointlet-base; xz -dc .dev58/pointlet-base.xz > $B && chmod +x $B
C=/tmp/pointlet-c; xz -dc .dev58/pointlet-c.xz > $C && chmod +x $C
[ -x /usr/bin/time ] || dpkg -x .dev55/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w58
mkdir -p $W; SECONDS=0
N=${N:-200M}
uname -r; lscpu | grep -E 'Model name|Thread|Core|Socket'
conv() { # label binary input
  timeout 60 $2 convert $3 -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1 | sed "s|$W/||; s|^|$1: |"; cmp -s $W/s.pointlet $W/ref.pointlet || echo "$1: store differs from base's"; rm -f $W/s.pointlet; sync; }
# The names convert-bench.sh looks for, so that it reuses these inputs.
for e in laz las; do timeout 150 $B generate --points $N -o $W/gen-$N.$e 2>&1 | tail -1; done
sync; cat $W/gen-$N.laz > /dev/null
timeout 60 $B convert $W/gen-$N.laz -o $W/ref.pointlet --ram-budget 24GiB 2>&1 | tail -1 | sed "s|$W/||"
for r in $(seq ${AB_ROUNDS:-3}); do
  timeout 60 $B bench-read $W/gen-$N.laz 2>&1 | tail -1 | sed "s|^|r$r |"
  if [ $((r % 2)) = 1 ]; then conv "r$r base" $B $W/gen-$N.laz; conv "r$r c" $C $W/gen-$N.laz
  else conv "r$r c" $C $W/gen-$N.laz; conv "r$r base" $B $W/gen-$N.laz; fi
done
rm -f $W/ref.pointlet
echo "A/B done at $SECONDS s"
if [ "${ACCEPT:-1}" = 0 ]; then # the short form: the LAS A/B instead of the acceptance
  timeout 60 $B convert $W/gen-$N.las -o $W/ref.pointlet --ram-budget 24GiB 2>&1 | tail -1 | sed "s|$W/||"
  for r in 1 2; do conv "LAS r$r base" $B $W/gen-$N.las; conv "LAS r$r c" $C $W/gen-$N.las; done
  echo "at $SECONDS s"; rm -rf $W; exit 0
fi
POINTLET=$C POINTS=$N ROUNDS=2 LAZ_ROUNDS=4 POTREE_ROUNDS=1 POTREE=.dev55/potree-converter/run.sh \
  timeout $((590 - SECONDS)) bash scripts/convert-bench.sh $OUT/cb $W
# Eight files at most come back: the summary is in log.txt, the LAZ runs' stage times here.
grep -h '^wrote' $OUT/cb/laz-mem-*.txt | sed "s|$W/||"
echo "at $SECONDS s"
rm -rf $W
