#!/usr/bin/env bash
# Makes sure the web viewer's end-to-end test can run: Debian's chromium (headless WebGPU on
# SwiftShader, no GPU needed), playwright-core (pinned) in target/node-tools/ to drive it, and
# a target/web/ built from the current sources. The test fails, never skips, without them.
set -euo pipefail
cd "$(dirname "$0")/.."
PLAYWRIGHT_VERSION=1.65.1
# One run at a time: scripts/test.sh starts this in the background while the tests run, and the
# browser test calls it again; the second call waits here, then finds everything in place.
mkdir -p target
exec 9>target/.ensure-browser.lock
flock 9

if ! command -v chromium >/dev/null 2>&1; then
    echo "installing chromium for the web viewer test" >&2
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq chromium >/dev/null
fi
if ! command -v npm >/dev/null 2>&1; then
    echo "installing node and npm to drive chromium" >&2
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq nodejs npm >/dev/null
fi

tools=target/node-tools
installed=$(node -p "require('./$tools/node_modules/playwright-core/package.json').version" 2>/dev/null || true)
if [ "$installed" != "$PLAYWRIGHT_VERSION" ]; then
    mkdir -p "$tools"
    npm install --prefix "$tools" --no-save --no-audit --no-fund --silent \
        "playwright-core@$PLAYWRIGHT_VERSION"
fi

# Rebuild the viewer when any of its inputs is newer than the built wasm.
built=target/web/pointlet_web_bg.wasm
stale=1
if [ -f "$built" ]; then
    newer=$(find crates/web crates/gpu crates/store crates/core Cargo.lock scripts/build-web.sh \
        -newer "$built" -type f -print -quit)
    [ -z "$newer" ] && stale=0
fi
if [ "$stale" = 1 ]; then
    # Built as a user builds it, without the lints scripts/test.sh compiles the tests with.
    env -u RUSTC_WORKSPACE_WRAPPER -u RUSTFLAGS bash scripts/build-web.sh
fi
