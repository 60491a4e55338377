#!/usr/bin/env bash
# Session 41, second call: what runs while the in-memory writing stage drops to 1-2 busy cores
# for ~0.1 s (seen in every LAS and LAZ run of call.sh). On-CPU samples with stacks (999 Hz,
# the frame-pointer build s7fp) of in-memory LAS and LAZ conversions, kept whole as `perf
# script` text, and the off-CPU waits of the LAS one with their timeline (offcpu.py). Everything
# comes back in one archive (a call returns at most 8 files).
# Run: run(command="bash docs/bench/issue15/session41/2-h100-profile/call.sh", carry=[
#   ".dev/pointlet-s7fp.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/perfpk.tgz"])
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
HERE=$(cd "$(dirname "$0")" && pwd)
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
X .dev/pointlet-s7fp.xz > /tmp/ps7fp && chmod +x /tmp/ps7fp
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
/tmp/ps7fp generate --points 200M -o $W/g.las 2>&1 | tail -1
/tmp/ps7fp generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.las $W/g.laz > /dev/null
echo "at $SECONDS s"
ON() { local name=$1; shift
  $PERF record -F 999 -g -o $W/$name.data -- "$@" 2>&1 | grep -E '^wrote' | tee $R/$name-wrote.txt
  rm -f $W/s.pointlet; sync
  $PERF script -i $W/$name.data -F tid,time,ip,sym --max-stack 14 2>/dev/null | gzip -c > $R/$name-script.txt.gz
  $PERF report -i $W/$name.data --no-children --sort sym -g none 2>/dev/null | grep -v '^#' | grep '%' | head -60 > $R/$name-flat.txt
  rm -f $W/$name.data; }
OFF() { local name=$1; shift
  $PERF record -a -g -e sched:sched_switch -o $W/$name.data -- "$@" 2>&1 | grep -E '^wrote' | tee $R/$name-wrote.txt
  rm -f $W/s.pointlet; sync
  local rd=$(grep -oE 'reading [0-9.]+ s' $R/$name-wrote.txt | grep -oE '[0-9.]+')
  $PERF script -i $W/$name.data -F comm,tid,time,event,trace,ip,sym --max-stack 24 2>/dev/null \
    | awk 'NF == 0 { if (keep) print ""; keep = 0; next } /sched:sched_switch:/ { keep = /comm=ps7fp/ } keep' > $W/$name.txt
  python3 $HERE/../../offcpu.py ps7fp 12 ${rd:-0} < $W/$name.txt > $R/$name-waits.txt
  gzip -c $W/$name.txt > $R/$name.txt.gz
  rm -f $W/$name.data $W/$name.txt; }
# Busy cores every 20 ms beside each run.
S() { local name=$1; shift; (while :; do echo "$(date +%s.%N) $(head -1 /proc/stat)"; sleep 0.02; done) > $R/cpu-$name.txt & local sp=$!
  "$@"; kill $sp; }
S on-mem ON on-mem /tmp/ps7fp convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
S off-mem OFF off-mem /tmp/ps7fp convert $W/g.las -o $W/s.pointlet --ram-budget 24GiB
S on-laz ON on-laz /tmp/ps7fp convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
echo "at $SECONDS s"
head -30 $R/off-mem-waits.txt | cut -c1-300; tail -45 $R/off-mem-waits.txt
cd $R && tar czf $OUT/prof.tgz * && ls -la $OUT
rm -rf $W
