#!/usr/bin/env bash
# The S3-compatible server the s3:// tests start on loopback: moto's server from PyPI, in a
# virtual environment under target/tools/moto (Debian's pip refuses system-wide installs).
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/tools/moto
version=5.2.1
if "$venv/bin/python3" -c "import moto, flask; assert moto.__version__ == '$version'" 2>/dev/null; then
    exit 0
fi
if ! python3 -c "import venv, ensurepip" 2>/dev/null; then
    echo "installing python3 and its venv module for the S3 test server" >&2
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq python3 python3-venv python3-pip >/dev/null
fi
rm -rf "$venv"
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check "moto[server]==$version"
"$venv/bin/python3" -c "import moto, flask, boto3; print('moto', moto.__version__, 'for the s3:// tests')"
