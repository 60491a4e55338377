#!/usr/bin/env bash
# Session 59, call 1: an A/B/C of the LAZ convert on 200 M generated points. Builds
# (`objcopy --strip-debug`, `xz`): base = 0f0534a (.dev59/pointlet-base.xz); s = base +
# s.diff beside this file (a LAZ chunk decompressed a block of 1,024 records at a time, each
# block made rows and keyed while in the cache); n = s + n.diff (into the mapped store the
# streams are split in a thread's buffer and copied with non-temporal stores).
# Per round: `bench-read`, then an in-memory convert by each build (order rotating); every
# store compared with base's. Then two rounds of in-memory LAS converts by each build.
# Run: run(command="bash docs/bench/issue15/session59/1-h100-stream/call.sh", carry=[".dev59"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
for b in base s n; do xz -dc .dev59/pointlet-$b.xz > /tmp/pointlet-$b && chmod +x /tmp/pointlet-$b; done
[ -x /usr/bin/time ] || dpkg -x .dev59/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w59
mkdir -p $W; SECONDS=0
N=${N:-200M}
uname -r; lscpu | grep -E 'Model name|Thread|Core|Socket'
conv() { # label build input
  /usr/bin/time -f "$1: %U user %S sys %M KB" timeout 60 /tmp/pointlet-$2 convert $3 -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -2 | sed "s|$W/||; s|^wrote|$1: wrote|"
  cmp -s $W/s.pointlet $W/ref.pointlet || echo "$1: store differs from base's"; rm -f $W/s.pointlet; sync; }
for e in laz $([ "${LAS:-1}" = 1 ] && echo las); do timeout 150 /tmp/pointlet-base generate --points $N -o $W/gen.$e 2>&1 | tail -1; done
sync; cat $W/gen.laz > /dev/null
timeout 60 /tmp/pointlet-base convert $W/gen.laz -o $W/ref.pointlet --ram-budget 24GiB 2>&1 | tail -1 | sed "s|$W/||"
# BUILDS="base s" LAS=0: those builds alternated, no LAS rounds (the second call).
if [ "${BUILDS:-}" = "base s" ]; then orders=("base s" "s base"); else orders=("base s n" "s n base" "n base s"); fi
for r in $(seq ${AB_ROUNDS:-4}); do
  [ $SECONDS -gt ${STOP_AT:-999} ] && break
  timeout 60 /tmp/pointlet-base bench-read $W/gen.laz 2>&1 | tail -1 | sed "s|^|r$r |"
  for b in ${orders[$(( (r - 1) % ${#orders[@]} ))]}; do conv "r$r $b" $b $W/gen.laz; done
done
echo "LAZ done at $SECONDS s"
[ "${LAS:-1}" = 1 ] && timeout 60 /tmp/pointlet-base convert $W/gen.las -o $W/ref.pointlet --ram-budget 24GiB 2>&1 | tail -1 | sed "s|$W/||"
[ "${LAS:-1}" = 1 ] && for r in 1 2; do for b in ${orders[$(( (r - 1) % 3 ))]}; do conv "LAS r$r $b" $b $W/gen.las; done; done
echo "at $SECONDS s"; rm -rf $W
