#!/usr/bin/env bash
# One large conversion with the default memory budget (issue 15: a 1 G-point LAZ): the input is
# generated once, then converted under /usr/bin/time -v; the store is checked with `info` and
# removed. docs/BENCHMARKS.md has the figures.
#
# Usage: scripts/convert-big.sh OUT_DIR INPUT_DIR STORE_DIR RUN_DIR
#   OUT_DIR    gen.txt, convert.txt (output, then time -v), info.txt, df.txt
#   INPUT_DIR  where the generated input goes (kept for later runs)
#   STORE_DIR  where the store is written (removed after `info`)
#   RUN_DIR    the converter's `--tmp`, for its spilled runs (~46 bytes a point)
# Environment: POINTS (default 1G), EXT (laz or las, default laz), POINTLET (the binary).
# A 1 G-point LAZ needs ~10.5 GB for the input, ~38 GB for the store and ~46 GB for runs; on a
# 64 GB disk put the input and the store on a tmpfs and the runs on the disk.
set -euo pipefail
[ $# -eq 4 ] || {
  echo "usage: $0 OUT_DIR INPUT_DIR STORE_DIR RUN_DIR" >&2
  exit 2
}
out=$1
inputs=$2
stores=$3
run_dir=$4
bin=${POINTLET:-target/release/pointlet}
points=${POINTS:-1G}
ext=${EXT:-laz}
mkdir -p "$out" "$inputs" "$stores" "$run_dir"
input=$inputs/gen-$points.$ext
store=$stores/big.pointlet
trap 'rm -f "$store"' EXIT
if [ ! -f "$input" ]; then
  partial=$inputs/partial-gen-$points.$ext
  /usr/bin/time -v "$bin" generate --points "$points" -o "$partial" >"$out/gen.txt" 2>&1
  mv "$partial" "$input"
fi
df -h "$inputs" "$stores" "$run_dir" >"$out/df.txt"
cat "$input" >/dev/null
status=0
/usr/bin/time -v "$bin" convert "$input" -o "$store" --tmp "$run_dir" >"$out/convert.txt" 2>&1 || status=$?
df -h "$inputs" "$stores" "$run_dir" >>"$out/df.txt"
if [ "$status" -ne 0 ]; then
  tail -n 30 "$out/convert.txt" >&2
  echo "convert failed ($status)" >&2
  exit 1
fi
"$bin" info "$store" >"$out/info.txt"
awk -F': ' '
  /^wrote / { print }
  /Elapsed \(wall clock\)/ { print "wall " $NF }
  /Maximum resident set size/ { printf "peak RSS %.2f GiB\n", $NF / 1048576 }
  /Percent of CPU/ { print "CPU " $NF }' "$out/convert.txt" | tee "$out/summary.txt"
