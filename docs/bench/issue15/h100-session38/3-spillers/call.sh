#!/usr/bin/env bash
# session 38 call 3 (issue 15): out of core, call 2 found the reading stage at ~9.5 of 16 cores,
# bound by the two spilling threads' writes of run files (4.2 s in all for 36 runs). s3 =
# 2a9780f + experiment.diff (XP_SPILLERS sets the spilling threads; the budget is shared by the
# filling run and those spilling, so more spillers mean smaller runs). 200 M LAS, 1 GiB,
# alternated; one in-memory run for the ratio.
# Not run (the device time was spent; the full version is docs/bench/issue15/next-call/call.sh).
# Run: run(command="bash docs/bench/issue15/h100-session38/3-spillers/call.sh",
#   carry=[".dev/pointlet-s3.xz", ".dev/time_1.9-0.2_amd64.deb"])
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-s3.xz > /tmp/ps3 && chmod +x /tmp/ps3
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/ps3 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > /tmp/cb/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' /tmp/cb/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 /tmp/cb/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
M="convert $L -o $W/s.pointlet"
C mem /tmp/ps3 $M --ram-budget 24GiB
for rs in 1:2 1:4 1:3 2:2 2:4; do r=${rs%:*} s=${rs#*:}; C ooc-sp$s-$r env XP_SPILLERS=$s /tmp/ps3 $M --ram-budget 1GiB --tmp $W; done

echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
