#!/usr/bin/env bash
# Session 60: out of core at 200 M points left 4–5 of the 16 cores idle through the reading
# stage (`1-h100-ooc-dirty`: 11–12 busy, in memory 16) with no writeback. Where do the idle
# threads wait? Every thread's state and kernel wait channel (/proc/PID/task/*/{stat,wchan})
# sampled every 5 ms through two out-of-core converts; per thread (in creation order) the
# samples running and the commonest wait channels, first for the reading stage (the first
# READ_S seconds, from the run before), then for the rest. Carry `.dev59b`. ~2 min.
# Run: run(command="bash docs/bench/issue15/session60/2-h100-ooc-threads/call.sh", carry=[".dev59b"])
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
Z=/tmp/pointlet; xz -dc .dev59b/pointlet.xz > $Z && chmod +x $Z
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w60
mkdir -p $W; SECONDS=0; trap 'rm -rf $W' EXIT
uname -r
timeout 100 $Z generate --points ${N:-200M} -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
for r in 1 2; do
  sync
  $Z convert $W/g.las -o $W/s.pointlet --ram-budget 1GiB > $W/conv.txt 2>&1 &
  P=$!; t0=$EPOCHREALTIME; exec {nap}<> <(:)
  # Shell builtins only: a sample of 20 threads takes well under a millisecond.
  while [ -d /proc/$P/task ]; do
    now=$(( (${EPOCHREALTIME/./} - ${t0/./}) / 1000 ))
    for t in /proc/$P/task/*; do
      read -r line 2>/dev/null < $t/stat || continue
      wc=; read -r wc 2>/dev/null < $t/wchan; wc=${wc:-?}
      rest=${line##*) }
      echo "$now ${t##*/} ${rest%% *} $wc"
    done
    read -r -t 0.005 -u $nap
  done > $W/s-$r.txt
  wait $P; tail -1 $W/conv.txt | sed "s|$W/||"; rm -f $W/s.pointlet
  rs=$(grep -o 'reading [0-9.]* s' $W/conv.txt | awk '{print $2 * 1000}')
  for stage in reading rest; do
    echo "== round $r, $stage (reading stage ${rs} ms); per thread: samples, running, top waits"
    awk -v rs=$rs -v st=$stage '(st == "reading") == ($1 < rs) {
        n[$2]++; if ($3 == "R") r[$2]++; else w[$2 " " $3 ":" $4]++ }
      END { for (t in n) { printf "%s %d %d", t, n[t], r[t];
              for (k in w) { split(k, a, " "); if (a[1] == t && w[k] * 10 >= n[t]) printf " %s=%d", a[2], w[k] }
              print "" } }' $W/s-$r.txt | sort -n | sed 's/^/  /'
  done
done
echo "at $SECONDS s"
