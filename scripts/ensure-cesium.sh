#!/usr/bin/env bash
# What the CesiumJS load test needs: Debian's chromium (headless, WebGL on SwiftShader) and the
# pinned npm packages cesium + playwright-core in target/node-tools/cesium. Idempotent: a second
# run with everything in place does nothing and touches no network.
set -euo pipefail
cd "$(dirname "$0")/.."
CESIUM_VERSION=1.145.0
PLAYWRIGHT_VERSION=1.65.1
dir=target/node-tools/cesium

if [ ! -x /usr/bin/chromium ]; then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
  else
    echo "ensure-cesium: /usr/bin/chromium is missing; install Debian's chromium package" >&2
    exit 1
  fi
fi

if ! command -v npm >/dev/null 2>&1; then
  echo "installing node and npm for the browser tests" >&2
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq nodejs npm >/dev/null
fi

installed() {
  node -e "
    const v = (p) => require('./$dir/node_modules/' + p + '/package.json').version;
    process.exit(v('cesium') === '$CESIUM_VERSION' && v('playwright-core') === '$PLAYWRIGHT_VERSION' ? 0 : 1)
  " 2>/dev/null
}

if ! installed; then
  mkdir -p "$dir"
  # A package.json of our own keeps npm from walking up into another project.
  [ -f "$dir/package.json" ] || echo '{"name":"pointlet-cesium-test","private":true}' > "$dir/package.json"
  # playwright-core downloads no browser: chromium comes from Debian.
  (cd "$dir" && npm install --no-audit --no-fund --loglevel=error --save-exact \
      "cesium@$CESIUM_VERSION" "playwright-core@$PLAYWRIGHT_VERSION")
fi
