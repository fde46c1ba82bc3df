#!/usr/bin/env bash
# Installs what hitex needs at run time when it is missing:
#   - Mesa's lavapipe (software Vulkan) and the Vulkan loader, for the GPU backend;
#   - Xvfb and the X client libraries winit loads, for `hitex view` and its test.
# Without them hitex still runs on its CPU backend; GPU tests skip (or fail
# under HITEX_REQUIRE_GPU=1) and the viewer test skips (or fails under
# HITEX_REQUIRE_VIEWER=1).
set -euo pipefail

have_lavapipe() {
  ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1 &&
    { ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1'; }
}
have_x() {
  command -v Xvfb >/dev/null 2>&1 &&
    { ldconfig -p 2>/dev/null | grep -q 'libxkbcommon-x11\.so\.0'; } &&
    { ldconfig -p 2>/dev/null | grep -q 'libXcursor\.so\.1'; }
}

packages=()
have_lavapipe || packages+=(mesa-vulkan-drivers libvulkan1)
have_x || packages+=(xvfb xauth libxkbcommon-x11-0 libx11-xcb1 libxcursor1 libxi6 libxrandr2)
if [ ${#packages[@]} -eq 0 ]; then
  exit 0
fi
echo "hitex: installing ${packages[*]}" >&2
if command -v apt-get >/dev/null 2>&1; then
  SUDO=""
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
      echo "hitex: not root and no sudo: install ${packages[*]} yourself; the CPU backend works without them" >&2
      exit 0
    fi
  fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${packages[@]}" >/dev/null
else
  echo "hitex: no apt-get: install your distribution's Mesa Vulkan drivers and Xvfb; the CPU backend works without them" >&2
fi
