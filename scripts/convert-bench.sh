#!/usr/bin/env bash
# The conversion benchmark of docs/BENCHMARKS.md (issue 2): 50 M generated points as LAZ and
# LAS, decoded only (`bench-read`, the baseline), converted in memory and out of core.
# Usage: scripts/convert-bench.sh OUT_DIR [WORK_DIR]; needs target/release/pointlet.
set -euo pipefail
out=$1
work=${2:-/tmp/pointlet-convert-bench}
bin=${POINTLET:-target/release/pointlet}
points=${POINTS:-50M}
mkdir -p "$out" "$work"
{ nproc; grep -m1 'model name' /proc/cpuinfo; free -g | sed -n 2p; } >"$out/machine.txt"
timed() { # NAME COMMAND...: wall seconds and peak RSS of one command into $out/NAME.txt
  local name=$1
  shift
  /usr/bin/time -v "$@" >"$out/$name.txt" 2>&1
  grep -E 'Elapsed|Maximum resident' "$out/$name.txt"
}
for ext in laz las; do
  input=$work/gen.$ext
  [ -f "$input" ] || "$bin" generate --points "$points" -o "$input"
  size=$(stat -c %s "$input")
  echo "== $ext: $size bytes"
  # Warm the page cache so that every run reads from memory alike.
  cat "$input" >/dev/null
  timed "$ext-read" "$bin" bench-read "$input"
  timed "$ext-convert-mem" "$bin" convert "$input" -o "$work/mem.pointlet"
  # Out of core: a RAM budget of 1/8 of the points' in-memory size (about 40 B a point).
  timed "$ext-convert-ooc" "$bin" convert "$input" -o "$work/ooc.pointlet" --ram-budget 256MiB --tmp "$work"
  cmp "$work/mem.pointlet" "$work/ooc.pointlet" && echo "stores identical"
  rm -f "$work/mem.pointlet" "$work/ooc.pointlet"
done
