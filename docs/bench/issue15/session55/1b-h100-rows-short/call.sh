#!/usr/bin/env bash
# Session 55, call 1b: call 1 (`../1-h100-rows/call.sh`, which never got a machine) cut to fit
# the session's last device minutes: the base build (x) against the rows build (z), 200 M LAZ
# (two rounds of bench-read, x, z after one discarded convert) and 200 M LAS (two rounds in
# memory, then z out of core); builds as call 1's header says.
# Run: run(command="bash docs/bench/issue15/session55/1b-h100-rows-short/call.sh", carry=[".dev", ".dev15"])
set -uo pipefail
mkdir -p $OUT/t; exec > >(tee "$OUT/t/log.txt") 2>&1
xz -dc .dev15/pointlet-x.xz > /tmp/x && xz -dc .dev15/pointlet-z.xz > /tmp/z && chmod +x /tmp/x /tmp/z
dpkg -x .dev/time_1.9-0.2_amd64.deb /tmp/tm 2>/dev/null; T=/tmp/tm/usr/bin/time
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w15
mkdir -p $W; SECONDS=0
nproc; uname -r; lscpu | grep -E 'Thread|Core|Socket'
conv() { # label binary input budget
  $T -f "cpu %U user %S sys" timeout 100 /tmp/$2 convert $3 -o $W/s.pointlet --ram-budget $4 2>&1 | grep -E '^wrote|^cpu' | tr '\n' ' ' | sed "s|$W/||g; s|^|$1: |"; echo; rm -f $W/s.pointlet; sync; }
timeout 150 /tmp/z generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
conv warm-up z $W/g.laz 24GiB
for r in 1 2; do
  timeout 60 /tmp/z bench-read $W/g.laz 2>&1 | tail -1
  conv "LAZ base r$r" x $W/g.laz 24GiB
  conv "LAZ rows r$r" z $W/g.laz 24GiB
done
echo "at $SECONDS s"
rm -f $W/g.laz; timeout 100 /tmp/z generate --points 200M -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
for r in 1 2; do
  conv "LAS base r$r" x $W/g.las 24GiB
  conv "LAS rows r$r" z $W/g.las 24GiB
done
conv "LAS out of core, rows" z $W/g.las 1GiB
echo "at $SECONDS s"
rm -rf $W
