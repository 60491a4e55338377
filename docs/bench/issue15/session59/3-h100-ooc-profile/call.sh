#!/usr/bin/env bash
# Session 59, call 5: where out of core's time goes on a slow host. A sampled profile (perf
# 6.1 from `.perf/perf.tar.xz`, cpu-clock at 999 Hz a thread) of an in-memory and an
# out-of-core (`--ram-budget 1GiB`) convert of 200 M generated LAS points; per run the stage
# line, user/sys time, and the top symbols. Binary: `.dev59b/pointlet.xz` (abca106's code;
# `objcopy --strip-debug` keeps the symbol table perf names functions by).
# Run: run(command="bash docs/bench/issue15/session59/3-h100-ooc-profile/call.sh", carry=[".perf", ".dev59b"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
P=/tmp/pk; mkdir -p $P && tar -C $P -xJf .perf/perf.tar.xz
Z=/tmp/pointlet; xz -dc .dev59b/pointlet.xz > $Z && chmod +x $Z
[ -x /usr/bin/time ] || dpkg -x .dev59b/time_*.deb /
perf() { LD_LIBRARY_PATH=$P/lib $P/perf "$@"; }
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w59
mkdir -p $W; SECONDS=0
uname -r
timeout 100 $Z generate --points ${N:-200M} -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
for run in "mem 24GiB" "ooc 1GiB"; do
  set -- $run
  /usr/bin/time -f "$1: %e s wall, %U user %S sys" env LD_LIBRARY_PATH=$P/lib $P/perf record -q -e cpu-clock -F 999 -o $W/$1.data -- \
    timeout 60 $Z convert $W/g.las -o $W/s.pointlet --ram-budget $2 2>&1 | tail -2 | sed "s|$W/||"
  rm -f $W/s.pointlet; sync
  echo "== $1: top symbols (share of all samples)"
  perf report -i $W/$1.data --sort sym --stdio 2>/dev/null | grep -v '^#' | grep -v '^$' | head -40 | cut -c1-110 | tee $OUT/$1-top.txt
done
echo "at $SECONDS s"
rm -rf $W
