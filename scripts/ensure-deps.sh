#!/usr/bin/env bash
# Installs what hitex's GPU backend needs when it is missing: Mesa's lavapipe
# (software Vulkan) and the Vulkan loader. Without them hitex still runs on
# its CPU backend, and GPU tests skip (or fail under HITEX_REQUIRE_GPU=1).
set -euo pipefail

have_lavapipe() {
  ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1 &&
    { ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1'; }
}

if have_lavapipe; then
  exit 0
fi
echo "hitex: installing Mesa's lavapipe Vulkan driver (mesa-vulkan-drivers libvulkan1)" >&2
if command -v apt-get >/dev/null 2>&1; then
  SUDO=""
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
      echo "hitex: not root and no sudo: install mesa-vulkan-drivers libvulkan1 yourself; the CPU backend works without them" >&2
      exit 0
    fi
  fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
else
  echo "hitex: no apt-get: install your distribution's Mesa Vulkan drivers; the CPU backend works without them" >&2
fi
