#!/usr/bin/env bash
# Prepared in session 56, not run: is the LAZ ratio's spread the host's? Eight rounds of the
# rows build z on 200 M LAZ, each `bench-read` then an in-memory convert, every run between two
# readings of /proc/stat's cpu line: the steal (time the hypervisor gave the vCPUs to someone
# else) and the guest's own busy time each run saw, and user/sys of each process by `time`.
# If the runs with the lowest ratios are those with the most steal, the ratio is the host's.
# Carry `.dev` (time_1.9-0.2_amd64.deb) and `.dev15` (pointlet-z.xz, as session 55's call 1
# describes). Run: run(command="bash docs/bench/issue15/session56/next-h100-laz-steal/call.sh",
# carry=[".dev", ".dev15"]) (~2.5 min). N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
xz -dc .dev15/pointlet-z.xz > /tmp/z && chmod +x /tmp/z
dpkg -x .dev/time_1.9-0.2_amd64.deb /tmp/tm 2>/dev/null; T=/tmp/tm/usr/bin/time
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w56
mkdir -p $W; SECONDS=0
nproc; uname -r; lscpu | grep -E 'Thread|Core|Socket|Model name'
# cpu line: user nice system idle iowait irq softirq steal, in clock ticks (USER_HZ, 100 a second)
ticks() { awk '/^cpu / { print $2 + $3 + $4 + $7 + $8, $9 }' /proc/stat; }
timed() { # label command...
  local a b; a=$(ticks)
  local line; line=$($T -f "cpu %U user %S sys %e wall" "${@:2}" 2>&1 | grep -E '^wrote|^decoded|^cpu' | tr '\n' ' ' | sed "s|$W/||g")
  b=$(ticks)
  echo "$1: $line| busy $(( ${b% *} - ${a% *} )) steal $(( ${b#* } - ${a#* } )) ticks"
}
timeout 150 /tmp/z generate --points ${N:-200M} -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
timeout 60 /tmp/z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB > /dev/null 2>&1; rm -f $W/s.pointlet
for r in 1 2 3 4 5 6 7 8; do
  timed "r$r bench-read" timeout 60 /tmp/z bench-read $W/g.laz
  timed "r$r convert" timeout 60 /tmp/z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
