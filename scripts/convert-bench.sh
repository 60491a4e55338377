#!/usr/bin/env bash
# The conversion benchmark of issue 15 (docs/BENCHMARKS.md): one generated LAS (and a LAZ of the
# same points) decoded only (`bench-read`, the baseline), converted in memory and out of core,
# and organised by PotreeConverter in the same run, each under /usr/bin/time -v.
#
# Usage: scripts/convert-bench.sh OUT_DIR [WORK_DIR]
#   OUT_DIR   machine.txt, NAME.txt per run (the command's output, then time -v), summary.txt
#   WORK_DIR  inputs (generated once, kept for later runs), stores and runs (removed);
#             default /tmp/pointlet-convert-bench; needs ~5× the LAS size free (200M: ~35 GB)
# Environment:
#   POINTS    points to generate (default 200M)
#   POINTLET  the binary (default target/release/pointlet)
#   ROUNDS    rounds of each timed conversion (default 2; the ratios use the best)
#   POTREE_ROUNDS  rounds of PotreeConverter (default ROUNDS)
#   LAZ_ROUNDS     rounds of the LAZ decode and in-memory convert, alternated (default ROUNDS;
#             the ratio is of the sums: on the GPU machine one round's decode alone moved by up
#             to 40 % within minutes, docs/BENCHMARKS.md)
#   POTREE    PotreeConverter's run.sh (the build in the shared tools folder beside the
#             repository: potree-converter/run.sh); unset, the Potree runs are skipped
# On the GPU machine (no Rust, no network, no /usr/bin/time): copy the release binary and
# PotreeConverter's folder into .dev/ (ignored by git, named in `carry`), with the Debian
# `time` package's .deb (`apt-get download time`), and start the command with
# `[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /;` (docs/BENCHMARKS.md, issue 15).
set -euo pipefail
[ $# -ge 1 ] || {
  echo "usage: $0 OUT_DIR [WORK_DIR]" >&2
  exit 2
}
out=$1
work=${2:-/tmp/pointlet-convert-bench}
bin=${POINTLET:-target/release/pointlet}
points=${POINTS:-200M}
rounds=${ROUNDS:-2}
potree_rounds=${POTREE_ROUNDS:-$rounds}
laz_rounds=${LAZ_ROUNDS:-$rounds}
potree=${POTREE:-}
[ -x "$bin" ] || {
  echo "no pointlet binary at $bin (cargo build --release --bin pointlet, or set POINTLET)" >&2
  exit 1
}
mkdir -p "$out" "$work"
mem_store=$work/mem.pointlet
ooc_store=$work/ooc.pointlet
potree_out=$work/potree
trap 'rm -rf "$mem_store" "$ooc_store" "$work/laz.pointlet" "$potree_out"' EXIT

cores=$(nproc)
{
  echo "cores: $cores"
  grep -m1 'model name' /proc/cpuinfo | sed 's/.*: /cpu: /'
  awk '/^MemTotal:/ { printf "memory: %.1f GiB\n", $2 / 1048576 }' /proc/meminfo
  echo "points: $points"
  "$bin" --version 2>/dev/null || true
} | tee "$out/machine.txt"

# Inputs are generated once (under a temporary name, so an interrupted run is not reused).
las=$work/gen-$points.las
laz=$work/gen-$points.laz
for input in "$las" "$laz"; do
  if [ ! -f "$input" ]; then
    partial=$work/partial-$(basename "$input")
    "$bin" generate --points "$points" -o "$partial"
    mv "$partial" "$input"
  fi
done
n=$("$bin" info "$las" | awk '$1 == "points" { print $2 }')
las_bytes=$(stat -c %s "$las")
# In memory: room for every point (~70 B each in the builder, about 2× the LAS record) and more.
mem_budget=$((3 * las_bytes + (1 << 30)))
echo "$n points; LAS $las_bytes bytes, LAZ $(stat -c %s "$laz") bytes; in-memory budget $mem_budget bytes"

warm() { # FILE: read it so that every run reads from the page cache alike
  cat "$1" >/dev/null
}
runs=()
timed() { # NAME COMMAND...: the command's output, then time -v's report, into $out/NAME.txt
  local name=$1
  shift
  runs+=("$name")
  # Every run starts with the disk idle: the last run's store (or the inputs just generated)
  # still being written back slowed the next run's writes 1.3-1.6x (docs/BENCHMARKS.md).
  sync
  if ! /usr/bin/time -v -a -o "$out/$name.txt" "$@" >"$out/$name.txt" 2>&1; then
    tail -n 30 "$out/$name.txt" >&2
    echo "$name failed (see $out/$name.txt)" >&2
    exit 1
  fi
  echo "$name: $(wall "$out/$name.txt") s"
}
stats() { # FILE: wall seconds, user seconds, system seconds, peak RSS in kB of a time -v report
  # The wall clock reads m:ss.ss or h:mm:ss; the last report in the file counts.
  awk -F': ' '
    /Elapsed \(wall clock\) time/ { n = split($NF, t, ":"); w = 0; for (i = 1; i <= n; i++) w = w * 60 + t[i] }
    /User time \(seconds\)/ { u = $NF }
    /System time \(seconds\)/ { s = $NF }
    /Maximum resident set size/ { r = $NF }
    END { printf "%.2f %.2f %.2f %d\n", w, u, s, r }' "$1"
}
wall() { stats "$1" | cut -d' ' -f1; }
best() { # PREFIX: the shortest wall time of this run's PREFIX-* runs
  for name in "${runs[@]}"; do
    if [[ $name == "$1"-* ]]; then wall "$out/$name.txt"; fi
  done | sort -g | head -n1
}
laz_rates() { # the LAZ convert rate over the decode rate: by the sums of all rounds, and the
  # lowest and highest round
  for r in $(seq "$laz_rounds"); do
    echo "$(wall "$out/laz-read-$r.txt") $(wall "$out/laz-mem-$r.txt")"
  done | awk '{ d += $1; c += $2; q = $1 / ($2 > 0 ? $2 : 0.01)
                lo = NR == 1 || q < lo ? q : lo; hi = NR == 1 || q > hi ? q : hi }
              END { printf "LAZ convert rate / LAZ decode rate: %.2f× by the sums of %d rounds (%.2f–%.2f by round)\n",
                      d / (c > 0 ? c : 0.01), NR, lo, hi }'
}

warm "$las"
timed las-read "$bin" bench-read "$las"
for r in $(seq "$rounds"); do
  rm -f "$mem_store"
  warm "$las"
  timed "las-mem-$r" "$bin" convert "$las" -o "$mem_store" --ram-budget "$mem_budget"
done
for r in $(seq "$rounds"); do
  rm -f "$ooc_store"
  warm "$las"
  timed "las-ooc-$r" "$bin" convert "$las" -o "$ooc_store" --ram-budget 1GiB --tmp "$work"
done
if cmp -s "$mem_store" "$ooc_store"; then
  identical="in-memory and out-of-core stores: identical"
else
  identical="in-memory and out-of-core stores: DIFFERENT"
fi
echo "$identical"
rm -f "$mem_store" "$ooc_store"
for r in $(seq "$laz_rounds"); do
  warm "$laz"
  timed "laz-read-$r" "$bin" bench-read "$laz"
  timed "laz-mem-$r" "$bin" convert "$laz" -o "$work/laz.pointlet" --ram-budget "$mem_budget"
  rm -f "$work/laz.pointlet"
done
if [ -n "$potree" ]; then
  for r in $(seq "$potree_rounds"); do
    rm -rf "$potree_out"
    warm "$las"
    timed "potree-$r" "$potree" "$las" -o "$potree_out"
  done
  rm -rf "$potree_out"
else
  echo "POTREE is not set: PotreeConverter skipped (set it to PotreeConverter's run.sh)"
fi

{
  cat "$out/machine.txt"
  echo "points in the LAS: $n"
  echo
  printf '%-10s %9s %10s %7s %12s\n' run "wall s" "M pts/s" "CPU %" "peak RSS MiB"
  for name in "${runs[@]}"; do
    read -r w u s rss < <(stats "$out/$name.txt")
    awk -v name="$name" -v w="$w" -v u="$u" -v s="$s" -v rss="$rss" -v n="$n" -v c="$cores" \
      'BEGIN { w = w > 0 ? w : 0.01
               printf "%-10s %9.2f %10.2f %7.0f %12.0f\n", name, w, n / w / 1e6,
                 100 * (u + s) / (w * c), rss / 1024 }'
  done
  echo
  echo "$identical"
  ratio() { # LABEL NUMERATOR DENOMINATOR
    awk -v l="$1" -v a="$2" -v b="$3" 'BEGIN { printf "%s: %.2f×\n", l, a / (b > 0 ? b : 0.01) }'
  }
  mem=$(best las-mem)
  ratio "out of core / in memory (best rounds)" "$(best las-ooc)" "$mem"
  # The LAZ acceptance compares rates: convert rate / decode rate = decode time / convert time.
  laz_rates
  if [ -n "$potree" ]; then
    ratio "PotreeConverter / pointlet in memory (best rounds)" "$(best potree)" "$mem"
  fi
} | tee "$out/summary.txt"
