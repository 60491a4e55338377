#!/usr/bin/env bash
# Session 47, issue 15: base = 2ca97d0 (the session-46 head: a part zeroes its own slices)
# against new8 = 0b3ea38 (each decoding task puts its part's pairs in bucket order; the
# spilling thread moves whole cells instead of a pool-wide scatter that waited for the pool
# busy decoding: session 46's head waited 0.53-0.63 s for the spillers). The 200 M LAS in
# memory and out of core (1 GiB), alternated, three rounds; every store compared with the first.
# Run: run(command="bash docs/bench/issue15/session47/1-h100-part-cells/call.sh",
#   carry=[".dev", ".gl"])
set -uo pipefail
mkdir -p $OUT/c; exec > >(tee "$OUT/c/log.txt") 2>&1
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet.xz > /tmp/p-base && X .dev/pointlet-new8.xz > /tmp/p-new8 && chmod +x /tmp/p-*
W=/tmp/w; mkdir -p $W; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
/tmp/p-base generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; sleep 1; cat $W/g.las > /dev/null
C() { local name=$1 bin=$2; shift 2; echo "$name: $(/usr/bin/time -f '| %e s wall, %U user, %S sys, %M kB' $bin convert $W/g.las -o $W/s.pointlet "$@" 2>&1 | grep -E '^wrote|wall' | sed 's/.*in \([0-9.]* s\)/\1/' | tr '\n' ' ' | cut -c1-330)"
  if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; sync; }
for r in 1 2 3; do for v in base new8; do
  C mem-$v-$r /tmp/p-$v --ram-budget 24GiB
  C ooc-$v-$r /tmp/p-$v --ram-budget 1GiB --tmp $W
done; done
echo "at $SECONDS s"
rm -rf $W
