#!/usr/bin/env bash
# Builds the browser viewer into target/web/: index.html, main.js, the wasm-bindgen glue and the
# .wasm. wasm-bindgen-cli is installed into target/tools/ at exactly the version of the
# wasm-bindgen crate in Cargo.lock (the glue and the crate must match), and reused after that.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
out=${POINTLET_WEB_OUT:-$root/target/web}

if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
    rustup target add wasm32-unknown-unknown
fi

version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
if [ -z "$version" ]; then
    echo "error: no wasm-bindgen version in Cargo.lock" >&2
    exit 1
fi
bindgen=$root/target/tools/bin/wasm-bindgen
if ! [ -x "$bindgen" ] || [ "$("$bindgen" --version | awk '{print $2}')" != "$version" ]; then
    # --locked first (the CLI's own lock file); an index that lacks one of its pinned crates
    # (seen with webpki-roots) gets the newest compatible ones instead.
    cargo install --locked --version "$version" --root "$root/target/tools" wasm-bindgen-cli ||
        cargo install --version "$version" --root "$root/target/tools" wasm-bindgen-cli
fi

# The `web` profile: release without debug info (faster to build, a smaller .wasm). A target
# folder of its own: scripts/test.sh builds the viewer while `cargo test` runs, and cargo locks
# a target folder for one build at a time.
cargo build -p pointlet-web --profile web --target wasm32-unknown-unknown --locked \
    --target-dir "$root/target/wasm"
mkdir -p "$out"
"$bindgen" --target web --no-typescript --out-dir "$out" \
    "$root/target/wasm/wasm32-unknown-unknown/web/pointlet_web.wasm"
cp crates/web/www/index.html crates/web/www/main.js "$out/"
echo "built the web viewer into $out"
