#!/usr/bin/env bash
# Prepared in session 57, not run: the acceptance benchmark of issue 15 with the LAZ ratio over
# six alternated rounds (`LAZ_ROUNDS`, f5cf833's scripts/convert-bench.sh), PotreeConverter in
# the same run, 200 M generated points. Carry `.dev57` (pointlet-b.xz: the conversion code of
# 27fdabe, as HEAD's; or rebuild: `cargo build --release -p pointlet`, `objcopy --strip-debug`,
# `xz -9`) and `.dev55` (PotreeConverter's folder from ../shared/tools/potree-converter, the
# Debian `time` package's .deb). ~4 min.
# Run: run(command="bash docs/bench/issue15/session57/next-h100-acceptance/call.sh", carry=[".dev57", ".dev55"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT/cb; exec > >(tee "$OUT/log.txt") 2>&1
xz -dc .dev57/pointlet-b.xz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev55/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w57
mkdir -p $W; SECONDS=0
uname -r; lscpu | grep -E 'Thread|Core|Socket'
POINTLET=/tmp/pointlet POINTS=${N:-200M} ROUNDS=2 LAZ_ROUNDS=6 POTREE_ROUNDS=1 POTREE=.dev55/potree-converter/run.sh \
  timeout 540 bash scripts/convert-bench.sh $OUT/cb $W
# Eight files at most come back: the summary is in log.txt, the LAZ runs' stage times here.
grep -h '^wrote' $OUT/cb/laz-mem-*.txt | sed "s|$W/||"
echo "at $SECONDS s"
rm -rf $W
