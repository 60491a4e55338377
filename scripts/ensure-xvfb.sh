#!/usr/bin/env bash
# Makes sure the viewer's window test can run: Xvfb (the test starts its own virtual X server
# and fails, never skips, without one) and the X client libraries winit loads at run time.
set -euo pipefail
LIBS="libX11.so.6 libX11-xcb.so.1 libXcursor.so.1 libXi.so.6 libXrandr.so.2 libxkbcommon-x11.so.0"
have_all() {
  local cache
  command -v Xvfb >/dev/null 2>&1 || return 1
  cache=$(ldconfig -p 2>/dev/null || /sbin/ldconfig -p 2>/dev/null || true)
  for lib in $LIBS; do
    case "$cache" in *"$lib "*) ;; *) return 1 ;; esac
  done
}
if have_all; then exit 0; fi
echo "installing the virtual X server and X client libraries for the viewer test" >&2
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq xvfb libx11-6 libx11-xcb1 libxcursor1 libxi6 libxrandr2 \
  libxkbcommon-x11-0 >/dev/null
have_all || { echo "error: Xvfb or an X client library is still missing after installing them" >&2; exit 1; }
