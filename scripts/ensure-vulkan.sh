#!/usr/bin/env bash
# Makes sure a Vulkan driver exists; on a machine without a GPU that is Mesa's CPU driver (lavapipe).
set -euo pipefail
have_icd() {
  local icds loader
  icds=$(ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json /usr/local/share/vulkan/icd.d/*.json 2>/dev/null || true)
  # No `grep -q`: it closes the pipe early and pipefail would then report ldconfig's SIGPIPE.
  loader=$( (ldconfig -p 2>/dev/null || /sbin/ldconfig -p 2>/dev/null || true) | grep -c 'libvulkan.so.1' || true)
  [ -n "$icds" ] && [ "${loader:-0}" -gt 0 ]
}
if have_icd; then exit 0; fi
echo "no Vulkan driver found: installing Mesa's CPU Vulkan driver (mesa-vulkan-drivers)" >&2
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
have_icd || { echo "error: still no Vulkan driver after installing mesa-vulkan-drivers" >&2; exit 1; }
