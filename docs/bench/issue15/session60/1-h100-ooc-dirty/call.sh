#!/usr/bin/env bash
# Session 59's prepared call (next-h100-ooc-dirty), printing the host's writeback settings,
# cgroup limits and the work directory's file system first: is out of core slow at 200 M points
# on the slower hosts because the kernel starts writing the runs back? At 150 M on a
# …-v1272 host out of core took 1.35× in memory (`3-h100-ooc-profile`), at 200 M 1.69×
# (`2-h100-acceptance`): runs (~9 GB) and store (~7 GB) dirty at once pass the background
# writeback threshold (`vm.dirty_background_ratio` 10 % of ~125 GiB) only at 200 M, and a run's
# hole punches (`runs::release_records`) then wait for pages under writeback (dev at 80 M,
# `dev-ooc-dirty/`: raising the thresholds took out of core from ~13.8 to ~8.2 s; switching
# the punches off did not help, so the writeback itself is what costs). Out-of-core
# converts at the default thresholds and with them raised (background 50 %, 80 %), alternated,
# /proc/vmstat's dirty and writeback pages and /proc/stat's busy cores sampled every 50 ms;
# in-memory converts beside.
# Carry `.dev59b` (pointlet.xz: abca106's code; the Debian `time` .deb). ~3 min.
# Run: run(command="bash docs/bench/issue15/session60/1-h100-ooc-dirty/call.sh", carry=[".dev59b"])
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
Z=/tmp/pointlet; xz -dc .dev59b/pointlet.xz > $Z && chmod +x $Z
[ -x /usr/bin/time ] || dpkg -x .dev59b/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w59
mkdir -p $W; SECONDS=0
uname -r; grep -E "MemTotal|MemAvailable" /proc/meminfo; nproc
echo "vm: bg $(cat /proc/sys/vm/dirty_background_ratio)% / $(cat /proc/sys/vm/dirty_background_bytes) B, fg $(cat /proc/sys/vm/dirty_ratio)% / $(cat /proc/sys/vm/dirty_bytes) B"
cat /proc/self/cgroup; for f in memory.max memory.high; do echo "$f: $(cat /sys/fs/cgroup/$f 2>&1)"; done
df -T $W /tmp | sed 1d; findmnt -T $W -o SOURCE,FSTYPE,OPTIONS | tail -1
bg0=$(cat /proc/sys/vm/dirty_background_ratio); fg0=$(cat /proc/sys/vm/dirty_ratio)
trap 'echo $bg0 > /proc/sys/vm/dirty_background_ratio; echo $fg0 > /proc/sys/vm/dirty_ratio; rm -rf $W' EXIT
timeout 100 $Z generate --points ${N:-200M} -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
conv() { # label budget bg fg
  echo $3 > /proc/sys/vm/dirty_background_ratio; echo $4 > /proc/sys/vm/dirty_ratio; sync
  local vm=$W/vm-${1// /_}.txt
  ( while sleep 0.05; do awk '/^nr_dirty |^nr_writeback /{printf "%s ", $2} END {printf " "}' /proc/vmstat; awk '/^cpu /{print $2+$3+$4+$7+$8, $5+$6; exit}' /proc/stat; done ) > $vm &
  local s=$!
  /usr/bin/time -f "$1: %e s wall, %U user %S sys" timeout 60 $Z convert $W/g.las -o $W/s.pointlet --ram-budget $2 2>&1 | tail -2 | sed "s|$W/||"
  kill $s; rm -f $W/s.pointlet
  awk '{ d = $1 > d ? $1 : d; w = $2 > w ? $2 : w; if ($2 > 0) n++ } END { printf "  peak dirty %.1f GiB, peak writeback %.2f GiB, %d samples of 50 ms with writeback\n", d / 262144, w / 262144, n }' $vm
  # Cores busy (of all) per 0.25 s from /proc/stat's jiffies, while the convert ran.
  awk -v n=$(nproc) '{ if (NR % 5 == 1) { if (b0 != "") printf "%.1f ", n * ($3 - b0) / (($3 - b0) + ($4 - i0) + 1e-9); b0 = $3; i0 = $4 } } END { print "" }' $vm | sed 's/^/  cores busy per 0.25 s: /'
}
for r in 1 2; do
  conv "r$r mem" 24GiB $bg0 $fg0
  conv "r$r ooc default" 1GiB $bg0 $fg0
  conv "r$r ooc raised" 1GiB 50 80
done
echo "at $SECONDS s"
