#!/usr/bin/env bash
# Session 41, fifth call: s10 (s9 with a mapped run file gathered a 2 MiB page per task over the
# whole run, each page released once written, instead of 16 MiB chunks one after another)
# against s9, alternated, three rounds: 200 M LAS in memory and out of core (1 GiB). Stores
# compared byte for byte with s9's first.
# Run: run(command="bash docs/bench/issue15/session41/5-h100-s9-s10/call.sh", carry=[
#   ".dev/pointlet-s9.xz", ".dev/pointlet-s10.xz", ".dev/time_1.9-0.2_amd64.deb"]) -- ~2 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in 9 10; do X .dev/pointlet-s$v.xz > /tmp/ps$v && chmod +x /tmp/ps$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
L=$W/g.las
/tmp/ps10 generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.05; done) > $R/cpu-$name.txt & local sp=$!
  C $name "$@"; kill $sp; }
M="convert $L -o $W/s.pointlet"
for r in 1 2 3; do
  S mem-s9-$r /tmp/ps9 $M --ram-budget 24GiB
  S ooc-s9-$r /tmp/ps9 $M --ram-budget 1GiB --tmp $W
  S mem-s10-$r /tmp/ps10 $M --ram-budget 24GiB
  S ooc-s10-$r /tmp/ps10 $M --ram-budget 1GiB --tmp $W
done
echo "at $SECONDS s"
cd $R && tar czf $OUT/runs.tgz *
rm -rf $W
