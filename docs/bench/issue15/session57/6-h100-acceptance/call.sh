#!/usr/bin/env bash
# Session 57, call 6: the acceptance benchmark of issue 15 with build b (call 5: 6a43304 +
# 5-h100-balanced/b.diff, the code as committed), PotreeConverter in the same run:
# scripts/convert-bench.sh on 200 M generated points (LAS and LAZ), two rounds, one of
# PotreeConverter; then four more rounds of LAZ bench-read and convert.
# Carry `.dev57` (pointlet-b.xz: `cargo build --release -p pointlet`, `objcopy --strip-debug`,
# `xz -9`) and `.dev55` (PotreeConverter's folder from ../shared/tools/potree-converter, the
# Debian `time` package's .deb).
# Run: run(command="bash docs/bench/issue15/session57/6-h100-acceptance/call.sh", carry=[".dev57", ".dev55"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT/cb; exec > >(tee "$OUT/log.txt") 2>&1
xz -dc .dev57/pointlet-b.xz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev55/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w57
mkdir -p $W; SECONDS=0
uname -r; lscpu | grep -E 'Thread|Core|Socket'
POINTLET=/tmp/pointlet POINTS=${N:-200M} ROUNDS=2 POTREE_ROUNDS=1 POTREE=.dev55/potree-converter/run.sh \
  timeout 420 bash scripts/convert-bench.sh $OUT/cb $W
echo "at $SECONDS s"
Z=$W/gen-${N:-200M}.laz; cat $Z > /dev/null
for r in 3 4 5 6; do
  timeout 60 /tmp/pointlet bench-read $Z 2>&1 | tail -1
  /usr/bin/time -f "cpu %U user %S sys %e wall %M kB" timeout 60 /tmp/pointlet convert $Z -o $W/z.pointlet --ram-budget 24GiB 2>&1 | grep -E '^wrote|^cpu' | tr '\n' ' ' | sed "s|$W/||g; s|^|LAZ r$r: |"; echo
  rm -f $W/z.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
