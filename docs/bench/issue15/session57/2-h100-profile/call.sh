#!/usr/bin/env bash
# Session 57, call 2: the LAZ convert's stages after reading, finely. A sampled profile
# (perf, cpu-clock at 999 Hz a thread) of two in-memory converts of 200 M generated LAZ
# points, summed per 20 ms from the last decoding sample (busy cores = samples / 19.98, by
# kind of work), and the first profile's perf.data, read here (dev) with the same binary.
# Build and carry as call 1 (`.perf`: 6a43304's code with symbols, perf 6.1).
# Run: run(command="bash docs/bench/issue15/session57/2-h100-profile/call.sh", carry=[".perf"])
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
P=/tmp/pk; mkdir -p $P && tar -C $P -xJf .perf/perf.tar.xz; Z=$P/pointlet
perf() { LD_LIBRARY_PATH=$P/lib $P/perf "$@"; }
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w57
mkdir -p $W; SECONDS=0
timeout 150 $Z generate --points ${N:-200M} -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
timeout 60 $Z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1; rm -f $W/s.pointlet; sync
tail_bins() { # perf.data → per 20 ms after the last decoding sample: all samples, then by kind
  perf script -i $1 -F time,ip,sym,dso 2>/dev/null | awk '
    { t = $1; sub(":", "", t); t += 0; T[NR] = t; S[NR] = $0; if ($0 ~ /lazcodec/) last = t }
    END { for (i = 1; i <= NR; i++) { if (T[i] < last - 0.1) continue
        b = int((T[i] - last + 0.1) * 50); s = S[i]; k = "other"
        if (s ~ /lazcodec|record::Decoder|las::/) k = "decode"
        else if (s ~ /clear_page/) k = "zero"
        else if (s ~ /memset/) k = "memset"
        else if (s ~ /sort|partition|bucket/) k = "sort"
        else if (s ~ /copy_records|stage|split|emit|crc32|permutation|shuffle/) k = "emit"
        else if (s ~ /libc/) k = "libc"
        else if (s ~ /kernel.kallsyms/) k = "kernel"
        else if (s ~ /Fn<A> for &F>::call/) k = "closure"
        else if (s ~ /call_mut/) k = "callmut"
        n[b]++; c[b, k]++; if (b > lb) lb = b }
      split("decode zero memset sort emit libc kernel closure callmut other", K, " ")
      printf "ms_from_last_decode  cores"; for (i = 1; i <= 10; i++) printf " %7s", K[i]; printf "\n"
      for (b = 0; b <= lb; b++) { printf "%5d %6.2f", b * 20 - 100, n[b] / 19.98
        for (i = 1; i <= 10; i++) printf " %7.2f", c[b, K[i]] / 19.98; printf "\n" } }'
}
for r in 1 2; do
  perf record -q -e cpu-clock -F 999 -o $W/c$r.data -- timeout 60 $Z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1
  rm -f $W/s.pointlet; sync
  echo "== convert $r, per 20 ms"; tail_bins $W/c$r.data | tee $OUT/tail-bins-$r.txt
done
perf report -i $W/c1.data --sort sym --stdio --time 80%-100% 2>/dev/null | grep -v '^#' | grep -v '^$' | head -40
cp $W/c1.data $OUT/convert.perf.data
echo "at $SECONDS s"
rm -rf $W
