#!/usr/bin/env bash
# Session 57, call 1: where the LAZ convert's time goes on 16 cores, and is its spread the
# host's? (a) a sampled profile (perf, cpu-clock at 999 Hz a thread) of one in-memory convert
# and one `bench-read` of 200 M generated LAZ points, summed per 0.1 s (samples a bin, by kind
# of work: busy cores = samples / 99.9); (b) session 56's prepared steal call: eight rounds of
# `bench-read` then a convert, each run between two readings of /proc/stat (busy, steal ticks).
# Build: 6a43304's code (= 9d2df54's conversion), `cargo build --release -p pointlet`,
# `objcopy --strip-debug` (symbols kept), packed with perf 6.1 and its libraries in
# .perf/perf.tar.xz (`tar -C DIR -cf - . | xz -9`). Carry `.perf` and `.dev`.
# Run: run(command="bash docs/bench/issue15/session57/1-h100-steal-profile/call.sh", carry=[".perf", ".dev"])
# N=4M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
P=/tmp/pk; mkdir -p $P && tar -C $P -xJf .perf/perf.tar.xz; Z=$P/pointlet
perf() { LD_LIBRARY_PATH=$P/lib $P/perf "$@"; }
dpkg -x .dev/time_1.9-0.2_amd64.deb /tmp/tm 2>/dev/null; T=/tmp/tm/usr/bin/time
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w57
mkdir -p $W; SECONDS=0
nproc; uname -r; lscpu | grep -E 'Thread|Core|Socket|Model name'; df -T $W | tail -1
echo "thp: $(cat /sys/kernel/mm/transparent_hugepage/enabled) defrag: $(cat /sys/kernel/mm/transparent_hugepage/defrag)"
grep -E 'MemTotal|MemFree|^Cached' /proc/meminfo; perf --version
timeout 150 $Z generate --points ${N:-200M} -o $W/g.laz 2>&1 | tail -1
sync; cat $W/g.laz > /dev/null
timeout 60 $Z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1; rm -f $W/s.pointlet; sync
# kind of work by symbol (dso [kernel.kallsyms] for the kernel's)
bins() { # perf.data → per 0.1 s: all samples, then by kind
  perf script -i $1 -F time,ip,sym,dso 2>/dev/null | awk '
    { t = $1; sub(":", "", t); t += 0; if (t0 == "") t0 = t; b = int((t - t0) * 10)
      s = $0; k = "other"
      if (s ~ /lazcodec|record::Decoder|las::/) k = "decode"
      else if (s ~ /clear_page/) k = "zero"
      else if (s ~ /memset/) k = "memset"
      else if (s ~ /sort|partition|bucket/) k = "sort"
      else if (s ~ /copy_records|stage|split|emit|memmove|memcpy|crc32|permutation|shuffle/) k = "emit"
      else if (s ~ /hilbert|key_rows|key_and/) k = "key"
      else if (s ~ /kernel.kallsyms/) k = "kernel"
      n[b]++; c[b, k]++; tot[k]++; if (b > last) last = b }
    END { split("decode zero memset sort emit key kernel other", K, " ")
      printf "bin_s  cores"; for (i = 1; i <= 8; i++) printf " %7s", K[i]; printf "\n"
      for (b = 0; b <= last; b++) { printf "%5.1f %6.2f", b / 10, n[b] / 99.9
        for (i = 1; i <= 8; i++) printf " %7.2f", c[b, K[i]] / 99.9; printf "\n" }
      printf "total core-s:"; for (i = 1; i <= 8; i++) printf " %s %.2f", K[i], tot[K[i]] / 999; printf "\n" }'
}
perf record -q -e cpu-clock -F 999 -o $W/c.data -- timeout 60 $Z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB 2>&1 | tail -1
rm -f $W/s.pointlet; sync
perf record -q -e cpu-clock -F 999 -o $W/r.data -- timeout 60 $Z bench-read $W/g.laz 2>&1 | tail -1
echo "== convert, per 0.1 s"; bins $W/c.data | tee $OUT/convert-bins.txt | tail -n +1
echo "== bench-read, per 0.1 s"; bins $W/r.data > $OUT/read-bins.txt; tail -1 $OUT/read-bins.txt
perf report -i $W/c.data --sort dso,sym --stdio 2>/dev/null | grep -v '^#' | head -60 > $OUT/convert-syms.txt
perf report -i $W/r.data --sort dso,sym --stdio 2>/dev/null | grep -v '^#' | head -30 > $OUT/read-syms.txt
head -25 $OUT/convert-syms.txt
# (b) the steal rounds; cpu line: user nice system idle iowait irq softirq steal (ticks, 100 a s)
ticks() { awk '/^cpu / { print $2 + $3 + $4 + $7 + $8, $9 }' /proc/stat; }
timed() { # label command...
  local a b; a=$(ticks)
  local line; line=$($T -f "cpu %U user %S sys %e wall" "${@:2}" 2>&1 | grep -E '^wrote|^decoded|^cpu' | tr '\n' ' ' | sed "s|$W/||g")
  b=$(ticks)
  echo "$1: $line| busy $(( ${b% *} - ${a% *} )) steal $(( ${b#* } - ${a#* } )) ticks"
}
for r in 1 2 3 4 5 6 7 8; do
  timed "r$r bench-read" timeout 60 $Z bench-read $W/g.laz
  timed "r$r convert" timeout 60 $Z convert $W/g.laz -o $W/s.pointlet --ram-budget 24GiB
  rm -f $W/s.pointlet; sync
done
echo "at $SECONDS s"
rm -rf $W
