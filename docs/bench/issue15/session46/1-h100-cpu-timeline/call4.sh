#!/usr/bin/env bash
# Session 46, issue 15, call 4: does out of core's reading stage lack threads or work? The
# 200 M LAS out of core (1 GiB) with the rayon pool at 16 (the cores), 20, 24 and 32 threads
# (RAYON_NUM_THREADS), alternated, two rounds, and in memory at 16 for the ratio.
# Binary: .dev/pointlet-new6.xz (41f9904's code).
# Run: run(command="bash docs/bench/issue15/session46/1-h100-cpu-timeline/call4.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/t4; exec > >(tee "$OUT/t4/log.txt") 2>&1
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-new6.xz > /tmp/p && chmod +x /tmp/p
W=/tmp/w; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
/tmp/p generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
C() { local name=$1 threads=$2; shift 2; echo "$name: $(RAYON_NUM_THREADS=$threads /usr/bin/time -f '| %e s wall, %U user, %S sys' /tmp/p convert $W/g.las -o $W/s.pointlet "$@" 2>&1 | grep -E '^wrote|wall' | sed 's/.*in \([0-9.]* s\)/\1/' | tr '\n' ' ' | cut -c1-330)"; rm -f $W/s.pointlet; sync; }
for r in 1 2; do
  C mem16-$r 16 --ram-budget 24GiB
  for t in 16 20 24 32; do C ooc$t-$r $t --ram-budget 1GiB --tmp $W; done
done
echo "at $SECONDS s"
rm -rf $W
