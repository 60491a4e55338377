#!/usr/bin/env bash
# Session 57, call 3: A/B of the writing stage's fix for idle cores. Builds, both with symbols
# (`objcopy --strip-debug`): base = 6a43304's code (in .perf/perf.tar.xz with perf 6.1); a =
# base + buckets over 256 K pairs split by the parallel pass (was over 1 M) + records copied in
# 16-byte pieces (.dev57/pointlet-a.xz). 200 M generated LAZ points: six rounds of `bench-read`
# then an in-memory convert by each build (order alternating), a profile of build a's convert
# (per 20 ms after decoding, as call 2); 200 M LAS points, two in-memory converts by each.
# Run: run(command="bash docs/bench/issue15/session57/3-h100-large/call.sh", carry=[".perf", ".dev57"])
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
P=/tmp/pk; mkdir -p $P && tar -C $P -xJf .perf/perf.tar.xz; B=$P/pointlet
A=/tmp/pointlet-a; xz -dc .dev57/pointlet-a.xz > $A && chmod +x $A
perf() { LD_LIBRARY_PATH=$P/lib $P/perf "$@"; }
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w57
mkdir -p $W; SECONDS=0
conv() { # label binary input
  timeout 60 $2 convert $3 -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1 | sed "s|$W/||; s|^|$1: |"; cmp -s $W/s.pointlet $W/ref.pointlet || echo "$1: store differs from base's"; rm -f $W/s.pointlet; sync; }
timeout 150 $B generate --points ${N:-200M} -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
timeout 60 $B convert $W/g.laz -o $W/ref.pointlet --ram-budget 24GiB 2>&1 | tail -1
for r in 1 2 3 4 5 6; do
  timeout 60 $A bench-read $W/g.laz 2>&1 | tail -1 | sed "s|^|r$r |"
  if [ $((r % 2)) = 1 ]; then conv "r$r base" $B $W/g.laz; conv "r$r a" $A $W/g.laz
  else conv "r$r a" $A $W/g.laz; conv "r$r base" $B $W/g.laz; fi
done
perf record -q -e cpu-clock -F 999 -o $W/c.data -- timeout 60 $A convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1
rm -f $W/s.pointlet $W/ref.pointlet; sync
perf script -i $W/c.data -F time,ip,sym,dso 2>/dev/null | awk '
  { t = $1; sub(":", "", t); t += 0; T[NR] = t; S[NR] = $0; if ($0 ~ /lazcodec/) last = t }
  END { for (i = 1; i <= NR; i++) { if (T[i] < last - 0.1) continue
      b = int((T[i] - last + 0.1) * 50); s = S[i]; k = "other"
      if (s ~ /clear_page/) k = "zero"; else if (s ~ /memset/) k = "memset"
      else if (s ~ /sort|partition|bucket/) k = "sort"; else if (s ~ /kernel.kallsyms/) k = "kernel"
      n[b]++; c[b, k]++; if (b > lb) lb = b }
    printf "ms_from_last_decode cores zero memset sort kernel other\n"
    for (b = 0; b <= lb; b++) printf "%5d %6.2f %5.2f %5.2f %5.2f %5.2f %5.2f\n", b * 20 - 100, n[b] / 19.98, c[b, "zero"] / 19.98, c[b, "memset"] / 19.98, c[b, "sort"] / 19.98, c[b, "kernel"] / 19.98, c[b, "other"] / 19.98 }' > $OUT/a-tail-bins.txt
awk 'NR > 1 && $1 >= 0 { n++; busy += $2 } END { printf "a, after decoding: %d ms, busy %.2f core-s, idle %.2f core-s\n", n * 20, busy * 0.02, (16 * n - busy) * 0.02 }' $OUT/a-tail-bins.txt
rm -f $W/g.laz
timeout 150 $B generate --points ${N:-200M} -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
timeout 60 $B convert $W/g.las -o $W/ref.pointlet --ram-budget 24GiB 2>&1 | tail -1
for r in 1 2; do conv "LAS r$r base" $B $W/g.las; conv "LAS r$r a" $A $W/g.las; done
echo "at $SECONDS s"
rm -rf $W
