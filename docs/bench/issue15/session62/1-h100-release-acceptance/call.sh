#!/usr/bin/env bash
# Session 62, call 1: session 60's prepared comparison (`../../session60/3-h100-release/call.sh`,
# run as it is) and the acceptance of issue 15 on the same host. One build, HEAD plus
# `../../session60/x-switches.diff`; without the switches it is HEAD. First the out-of-core
# variants, alternated, every thread's state and kernel wait channel sampled (base: the read
# pages' holes punched by the loading threads; XBG=1: by a thread of their own; XW=1: runs
# written through `write`), into $OUT/variants/log.txt. Then `scripts/convert-bench.sh` without
# switches: LAS in memory and out of core three rounds, the LAZ ratio over five alternated
# rounds, PotreeConverter once. Carry `.dev62`: pointlet-x.xz (`cargo build --release -p
# pointlet`, `objcopy --strip-debug`, `xz -6`), PotreeConverter's folder, the `time` .deb.
# Run: run(command="bash docs/bench/issue15/session62/1-h100-release-acceptance/call.sh", carry=[".dev62"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
[ -e .dev60 ] || ln -s .dev62 .dev60 # session 60's call reads its build from .dev60
OUT=$OUT/variants timeout 300 bash docs/bench/issue15/session60/3-h100-release/call.sh
Z=/tmp/pointlet # decompressed by session 60's call
[ -x /usr/bin/time ] || dpkg -x .dev62/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w62
mkdir -p $W; SECONDS=0; trap 'rm -rf $W' EXIT
POINTLET=$Z POINTS=${N:-200M} ROUNDS=3 LAZ_ROUNDS=${LAZ_ROUNDS:-5} POTREE_ROUNDS=1 \
  POTREE=.dev62/potree-converter/run.sh timeout 290 bash scripts/convert-bench.sh $W/cb $W
grep -h '^wrote' $W/cb/las-*.txt $W/cb/laz-mem-*.txt | sed "s|$W/||"
tar -C $W -czf $OUT/cb.tar.gz cb
echo "acceptance at $SECONDS s"
