#!/usr/bin/env bash
# The whole test suite: formatting, lints, and every test (GPU tests run on lavapipe without a GPU).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/ensure-vulkan.sh
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo test --workspace --locked
