#!/usr/bin/env bash
# The whole test suite: formatting, lints, and every test (GPU tests run on lavapipe without a GPU;
# the viewer's window test runs under an Xvfb server it starts itself).
set -euo pipefail
cd "$(dirname "$0")/.."
# A one-off build gains nothing from incremental caches, which only cost disk.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
# What the tests need besides the build (mostly downloads: apt, pip, npm) installs while the
# tests build: Mesa's CPU Vulkan driver, Xvfb, the S3 server, and Chromium with the pinned
# CesiumJS + playwright-core of the 3D Tiles load test (minutes the first time, nothing after).
services_log=$(mktemp)
(
    bash scripts/ensure-vulkan.sh
    bash scripts/ensure-xvfb.sh
    bash scripts/ensure-moto.sh
    bash scripts/ensure-cesium.sh
) >"$services_log" 2>&1 &
services=$!
# A failed build still lets a half-done package install finish.
trap 'wait "$services" 2>/dev/null || true; rm -f "$services_log"' EXIT
cargo fmt --all -- --check
# Clippy lints the workspace while the tests are built, as `cargo clippy` does it (clippy-driver
# compiles the workspace's crates; warnings, clippy's included, are errors; dependencies' lints
# stay capped). A separate `cargo clippy` would check every dependency a second time: about a
# quarter of the suite's time on a 2-core machine.
export RUSTC_WORKSPACE_WRAPPER="${RUSTC_WORKSPACE_WRAPPER:-clippy-driver}"
export RUSTFLAGS="${RUSTFLAGS:-} -D warnings"
# The web viewer's build (wasm-bindgen-cli and the wasm, ~5 minutes the first time) starts now,
# at the lowest priority, on the cycles the test build leaves idle; under the lock of
# ensure-browser.sh, whose call by the browser test then finds it done. Same flags as that
# call, or cargo would build the wasm again.
mkdir -p target
nice -n 19 flock target/.ensure-browser.lock bash scripts/build-web.sh >/dev/null 2>&1 &
web=$!
trap 'wait "$services" "$web" 2>/dev/null || true; rm -f "$services_log"' EXIT
cargo test --workspace --all-targets --locked --no-run
if ! wait "$services"; then
    cat "$services_log" >&2
    echo "error: installing what the tests need failed (above)" >&2
    exit 1
fi
cat "$services_log"
# What else the browser test needs (chromium, playwright-core; the web build again should the
# early one have failed) installs at the lowest priority while the other tests run; the browser
# test runs last, and its own call of ensure-browser.sh waits for it and finds it done (and
# reports any failure itself).
nice -n 19 bash scripts/ensure-browser.sh >/dev/null 2>&1 &
browser=$!
browser_log=$(mktemp)
trap 'wait "$services" "$web" "$browser" 2>/dev/null || true; rm -f "$services_log" "$browser_log"' EXIT
browser_test=the_browser_draws_the_shared_view_as_render_does
cargo test --workspace --locked -- --skip "$browser_test"
cargo test --locked -p pointlet --test web -- --exact "$browser_test" 2>&1 | tee "$browser_log"
# A renamed test would match nothing here and pass unseen: it must have run.
if ! grep -q "^test $browser_test \.\.\. ok" "$browser_log"; then
    echo "error: the browser test $browser_test did not run" >&2
    exit 1
fi
