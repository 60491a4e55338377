#!/usr/bin/env bash
# Builds Pointlet and runs the main job on the built-in demo scene: generate → convert → info →
# render; then builds the web viewer (target/web/) that `pointlet serve` serves.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/ensure-vulkan.sh
cargo build --release --locked -p pointlet
bin=target/release/pointlet
out=target/demo
mkdir -p "$out"
$bin generate --points 2M --seed 1 -o "$out/demo.laz"
$bin convert "$out/demo.laz" -o "$out/demo.pointlet"
$bin info "$out/demo.pointlet"
$bin render "$out/demo.pointlet" -o "$out/demo.png" --edl
echo "picture: $out/demo.png"
bash scripts/build-web.sh
echo "web viewer: $bin serve $out/demo.pointlet, then open http://127.0.0.1:8080/?store=demo"
