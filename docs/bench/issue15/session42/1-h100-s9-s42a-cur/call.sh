#!/usr/bin/env bash
# Prepared in session 42 (no GPU machine was lent then), for the next call: issue 15's open
# ratios on one instance, three builds alternated, four rounds:
#   s9   = 32155d6 (session 41's code),
#   s42a = 7d7a678 (a spilled run gathered in 2 MiB tasks in file order by the spilling thread
#          itself and idle pool threads, up to 16 ahead; the budget keeps three I/O chunks a
#          spiller),
#   cur  = 51b5955 (s42a, and each spiller buckets its run on a one-thread pool of its own).
# 200 M LAS in memory and out of core (1 GiB); PotreeConverter once; 200 M LAZ bench-read and
# convert with cur (in memory, no spilling: the builds differ only out of core). Every store
# compared with the first one written.
# ../2-h100-raster/call.sh times session 42's depth pass change (bench-raster).
# Binaries (built on dev: `cargo build --release -p pointlet` in a `git worktree add DIR COMMIT`
# for each, then `objcopy --strip-debug` and `xz -9` into .dev/pointlet-NAME.xz).
# .dev/potree: a copy of ../shared/tools/potree-converter; .dev/time_*.deb: `apt-get download
# time`.
# Run: run(command="bash docs/bench/issue15/session42/1-h100-s9-s42a-cur/call.sh", carry=[".dev/pointlet-cur.xz",
#   ".dev/pointlet-s42a.xz", ".dev/pointlet-s9.xz", ".dev/time_1.9-0.2_amd64.deb",
#   ".dev/potree"]) -- ~6 minutes (one call allows 10); (archived as run: moved under
#   docs/bench/issue15/session42/)
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in cur s42a s9; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
W=/tmp/w; R=/tmp/res; mkdir -p $W $R; SECONDS=0
nproc; grep -m1 'model name' /proc/cpuinfo
P=/tmp/p-cur
# Conversion: a line per run (the command's summary, then time's), stores compared with the first.
C() { local name=$1; shift; /usr/bin/time -f "%e s wall, %U user, %S sys, %M kB" "$@" > $R/$name.txt 2>&1; echo "$name: $(grep -E '^wrote|^decoded' $R/$name.txt | sed 's/.*in \([0-9.]* s\)/\1/' | cut -c1-300) | $(tail -1 $R/$name.txt)"
  if [ -f $W/s.pointlet ]; then if [ -f $W/ref.pointlet ]; then cmp $W/s.pointlet $W/ref.pointlet || echo "   DIFFERENT"; rm -f $W/s.pointlet; else mv $W/s.pointlet $W/ref.pointlet; fi; fi; sync; }
L=$W/g.las
$P generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 1; cat $L > /dev/null
M="convert $L -o $W/s.pointlet"
C las-read $P bench-read $L
for r in 1 2 3 4; do for v in s9 s42a cur; do
  C mem-$v-$r /tmp/p-$v $M --ram-budget 24GiB
  C ooc-$v-$r /tmp/p-$v $M --ram-budget 1GiB --tmp $W
done; done
echo "at $SECONDS s"
C potree bash .dev/potree/run.sh $L -o $W/potree; rm -rf $W/potree
echo "at $SECONDS s"
rm -f $L $W/ref.pointlet; $P generate --points 200M -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
for r in 1 2 3 4; do
  C laz-read-$r $P bench-read $W/g.laz
  C laz-$r $P convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
done
rm -rf $W/g.laz $W/ref.pointlet
echo "at $SECONDS s"
cd $R && tar czf $OUT/runs.tgz *
rm -rf $W
