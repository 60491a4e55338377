#!/usr/bin/env bash
# Session 55, call 2: the acceptance benchmark of issue 15 with the code as committed (the
# "rows" build of call 1: 7f94f7b + rows.diff = 9d2df54's code), PotreeConverter in the same
# run: scripts/convert-bench.sh on 200 M generated points (LAS and LAZ), two rounds, one of
# PotreeConverter; then two more rounds of LAZ bench-read and convert, alternated.
# Carry `.dev55`: pointlet-z.xz (call 1's z: 9d2df54 + session 53's switches.diff, whose
# switches are off unless POINTLET_X names one; `cargo build --release -p pointlet`,
# `strip --strip-all`, `xz -9e`), PotreeConverter's folder (../shared/tools/potree-converter), the Debian `time`
# package's .deb (`apt-get download time`).
# Run: run(command="bash docs/bench/issue15/session55/2-h100-acceptance/call.sh", carry=[".dev55"]);
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT/cb; exec > >(tee "$OUT/log.txt") 2>&1
xz -dc .dev55/pointlet-z.xz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev55/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w55
mkdir -p $W; SECONDS=0
uname -r; lscpu | grep -E 'Thread|Core|Socket'
POINTLET=/tmp/pointlet POINTS=${N:-200M} ROUNDS=2 POTREE_ROUNDS=1 POTREE=.dev55/potree-converter/run.sh \
  timeout 420 bash scripts/convert-bench.sh $OUT/cb $W
echo "at $SECONDS s"
Z=$W/gen-${N:-200M}.laz; cat $Z > /dev/null
for r in 2 3; do
  timeout 60 /tmp/pointlet bench-read $Z 2>&1 | tail -1
  /usr/bin/time -f "cpu %U user %S sys %e wall %M kB" timeout 60 /tmp/pointlet convert $Z -o $W/z.pointlet --ram-budget 24GiB 2>&1 | grep -E '^wrote|^cpu' | tr '\n' ' ' | sed "s|$W/||g; s|^|LAZ r$r: |"; echo
  rm -f $W/z.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
