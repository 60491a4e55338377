#!/usr/bin/env bash
# Prepared in session 43 (no device could be started then); run in session 44 with ROUNDS=2, on
# one H100 host, between the two parts of ../../../issue11/session43/1-h100-open-trace/call.sh; outputs
# beside this script. The diff was committed after (739864c).
# Run files carrying their records' keys, so that the groups read the keys back instead of
# computing them again (`keys-in-runs-rebased.diff` beside this script: session 42's
# session42/4-h100-keys/keys-in-runs.diff on c779464), against the same commit without it:
# 200 M LAS in memory and out of core (1 GiB), alternated, three rounds (or the first
# argument's); stores compared with the first.
# Binaries: .dev/pointlet-base.xz (c779464, or a later commit with the same conversion code),
# .dev/pointlet-keys.xz (the same with the diff applied); each `cargo build --release -p
# pointlet`, `objcopy --strip-debug`, `xz -9`.
# Run: run(command="bash docs/bench/issue15/session43/1-h100-keys/call.sh [ROUNDS]",
#   carry=[".dev/pointlet-base.xz", ".dev/pointlet-keys.xz", ".dev/time_1.9-0.2_amd64.deb"])
set -uo pipefail
mkdir -p $OUT/keys; exec > >(tee "$OUT/keys/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in base keys; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
/tmp/p-keys generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
M="convert $L -o $W/s.pointlet"
for r in $(seq ${1:-3}); do for v in base keys; do
  C mem-$v-$r /tmp/p-$v $M --ram-budget 24GiB
  C ooc-$v-$r /tmp/p-$v $M --ram-budget 1GiB --tmp $W
done; done
echo "at $SECONDS s"
cd $R && tar czf $OUT/keys/runs.tgz *
rm -rf $W
