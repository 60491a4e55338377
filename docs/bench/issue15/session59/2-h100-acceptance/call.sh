#!/usr/bin/env bash
# Session 59, call 2: the acceptance benchmark of issue 15 with the session's code (the LAZ
# chunks decompressed, made rows and keyed a block at a time), PotreeConverter in the same
# run, 200 M generated points, the LAZ ratio over five alternated rounds. Carry `.dev59b`:
# pointlet.xz (`cargo build --release -p pointlet`, `objcopy --strip-debug`, `xz -6`),
# PotreeConverter's folder from ../shared/tools/potree-converter, the Debian `time` .deb.
# Run: run(command="bash docs/bench/issue15/session59/2-h100-acceptance/call.sh", carry=[".dev59b"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT/cb; exec > >(tee "$OUT/log.txt") 2>&1
xz -dc .dev59b/pointlet.xz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev59b/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w59
mkdir -p $W; SECONDS=0
uname -r; lscpu | grep -E 'Model name|Thread|Core|Socket'
POINTLET=/tmp/pointlet POINTS=${N:-200M} ROUNDS=2 LAZ_ROUNDS=${LAZ_ROUNDS:-5} POTREE_ROUNDS=1 \
  POTREE=.dev59b/potree-converter/run.sh timeout 560 bash scripts/convert-bench.sh $OUT/cb $W
# Eight files at most come back: the summary is in log.txt, the LAZ runs' stage times here.
grep -h '^wrote' $OUT/cb/laz-mem-*.txt | sed "s|$W/||"
echo "at $SECONDS s"
rm -rf $W
