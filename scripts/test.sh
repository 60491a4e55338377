#!/usr/bin/env bash
# The whole test suite: formatting, lints, and every test (GPU tests run on lavapipe without a GPU;
# the viewer's window test runs under an Xvfb server it starts itself).
set -euo pipefail
cd "$(dirname "$0")/.."
# A one-off build gains nothing from incremental caches, which only cost disk.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
bash scripts/ensure-vulkan.sh
bash scripts/ensure-xvfb.sh
bash scripts/ensure-moto.sh
# Chromium and the pinned CesiumJS + playwright-core of the 3D Tiles load test (about 1.5 min the
# first time, nothing after).
bash scripts/ensure-cesium.sh
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo test --workspace --locked
