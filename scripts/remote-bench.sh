#!/usr/bin/env bash
# Streaming a store over HTTP on loopback with injected latency: `bench --realtime` along the
# orbit from the local file, from `pointlet serve`, and through scripts/latency-proxy.py at
# each latency; prints the share of requested points drawn and the frame rate of each.
# Usage: POINTS=5M LATENCIES="20 50" bash scripts/remote-bench.sh OUT_DIR [POINTLET]
set -euo pipefail
out=${1:?usage: remote-bench.sh OUT_DIR [POINTLET]}
bin=${2:-target/release/pointlet}
points=${POINTS:-5M}
latencies=${LATENCIES:-20 50}
bench_flags=(--realtime --orbit-seconds "${ORBIT_SECONDS:-20}" --width 640 --height 360
  --bucket "${BUCKET:-1M}" --vram-budget 256MiB --ram-budget 512MiB --point-size 1)
mkdir -p "$out"
store="$out/remote-bench.pointlet"
[ -f "$store" ] || "$bin" generate --points "$points" -o "$store" >/dev/null
port=$((20000 + RANDOM % 20000))
"$bin" serve "$store" --bind "127.0.0.1:$port" >"$out/serve.log" 2>&1 &
pids=($!)
trap 'kill "${pids[@]}" 2>/dev/null || true' EXIT
sleep 2
summary() { grep -E "streaming:|avg" "$1" | tr '\n' ' '; echo; }
echo "== local file" | tee "$out/summary.txt"
"$bin" bench "$store" "${bench_flags[@]}" --json "$out/local.json" >"$out/local.txt" 2>&1
summary "$out/local.txt" | tee -a "$out/summary.txt"
echo "== serve, no added latency" | tee -a "$out/summary.txt"
url="http://127.0.0.1:$port/stores/remote-bench.pointlet"
"$bin" bench "$url" "${bench_flags[@]}" --json "$out/http-0.json" >"$out/http-0.txt" 2>&1
summary "$out/http-0.txt" | tee -a "$out/summary.txt"
for ms in $latencies; do
  proxy=$((port + ms + 1))
  python3 "$(dirname "$0")/latency-proxy.py" "$proxy" "$port" "$ms" >/dev/null &
  pids+=($!)
  sleep 1
  echo "== serve, +$ms ms per request" | tee -a "$out/summary.txt"
  url="http://127.0.0.1:$proxy/stores/remote-bench.pointlet"
  "$bin" bench "$url" "${bench_flags[@]}" --json "$out/http-$ms.json" >"$out/http-$ms.txt" 2>&1
  summary "$out/http-$ms.txt" | tee -a "$out/summary.txt"
done
