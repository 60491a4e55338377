#!/usr/bin/env bash
# Browser frame times of the web viewer: a generated store served by `pointlet serve` on
# loopback, opened in headless chromium (WebGPU on SwiftShader, no GPU needed), orbited for
# ORBIT_SECONDS per canvas size and point budget; one JSON line per run in
# OUT_DIR/web-bench.jsonl.
# Usage: POINTS=10M ORBIT_SECONDS=15 SIZES="1280x720 640x360" BUDGETS="500000 2000000" \
#          bash scripts/web-bench.sh OUT_DIR [POINTLET]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: web-bench.sh OUT_DIR [POINTLET]}
bin=${2:-target/release/pointlet}
points=${POINTS:-10M}
mkdir -p "$out"
bash scripts/ensure-browser.sh
store="$out/bench-$points.pointlet"
[ -f "$store" ] || "$bin" generate --points "$points" -o "$store" >/dev/null
port=$((20000 + RANDOM % 20000))
"$bin" serve "$store" --bind "127.0.0.1:$port" --web-dir target/web >"$out/serve.log" 2>&1 &
server=$!
trap 'kill "$server" 2>/dev/null || true' EXIT
for _ in $(seq 50); do grep -q serving "$out/serve.log" && break; sleep 0.2; done
name=$(basename "$store" .pointlet)
: >"$out/web-bench.jsonl"
for size in ${SIZES:-1280x720 640x360}; do
  for budget in ${BUDGETS:-500000 2000000}; do
    PLAYWRIGHT_MODULES="$PWD/target/node-tools/node_modules" node scripts/web-bench.mjs \
      "http://127.0.0.1:$port/?store=$name&ui=off&budget=$budget" "${size%x*}" "${size#*x}" \
      "${ORBIT_SECONDS:-15}" | tee -a "$out/web-bench.jsonl"
  done
done
