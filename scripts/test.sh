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
# Clippy lints the workspace while the tests are built, as `cargo clippy` does it (clippy-driver
# compiles the workspace's crates; warnings, clippy's included, are errors; dependencies' lints
# stay capped). A separate `cargo clippy` would check every dependency a second time: about a
# quarter of the suite's time on a 2-core machine.
export RUSTC_WORKSPACE_WRAPPER="${RUSTC_WORKSPACE_WRAPPER:-clippy-driver}"
export RUSTFLAGS="${RUSTFLAGS:-} -D warnings"
cargo test --workspace --all-targets --locked --no-run
cargo test --workspace --locked
