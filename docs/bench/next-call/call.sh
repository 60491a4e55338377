#!/usr/bin/env bash
# Prepared in session 42 (no GPU machine was lent then), for the next call: the acceptance
# figures still open, with one binary, more rounds than session 41, on one instance.
#   Issue 15: 200 M LAS in memory and out of core (1 GiB) alternated, four rounds;
#             PotreeConverter once; 200 M LAZ bench-read and convert alternated, four rounds.
#   Issue 11 / session 42's depth pass (colour loaded for every point passing its depth test,
#             no branch on the uniform any_hidden): bench-raster of atomic-min-32, hqs and
#             hqs1r on 100 M generated points, s9 (32155d6) against cur, alternated, twice.
# Binaries (built on dev: `cargo build --release -p pointlet`, then `objcopy --strip-debug` and
# `xz -9` into .dev/): .dev/pointlet-cur.xz (this tree), .dev/pointlet-s9.xz (32155d6, from
# `git worktree add /tmp/s9 32155d6`). .dev/potree: a copy of ../shared/tools/potree-converter;
# .dev/time_*.deb: `apt-get download time`. .gl/*.deb: the Vulkan loader (device README).
# Run: run(command="bash docs/bench/next-call/call.sh", carry=[".dev/pointlet-cur.xz",
#   ".dev/pointlet-s9.xz", ".dev/time_1.9-0.2_amd64.deb", ".dev/potree", ".gl"]) -- ~8 minutes
#   (within one call's 10); then move this folder under docs/bench/issue15/sessionNN/.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in cur s9; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
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
for r in 1 2 3 4; do
  C mem-$r $P $M --ram-budget 24GiB
  C ooc-$r $P $M --ram-budget 1GiB --tmp $W
done
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
# The depth pass: medians of 10 frames per configuration, both encodings, every vertex order.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for r in 1 2; do for v in s9 cur; do
  timeout 120 /tmp/p-$v bench-raster --points 100M --frames 10 --variants atomic-min-32,hqs,hqs1r --json $R/raster-$v-$r.json > $R/raster-$v-$r.txt 2>&1
  echo "raster-$v-$r:"; grep -E ' full16 .*(atomic-min-32|hqs)|unreliable|rror' $R/raster-$v-$r.txt
done; done
echo "at $SECONDS s"
cd $R && tar czf $OUT/runs.tgz *
rm -rf $W
