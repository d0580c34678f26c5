#!/usr/bin/env bash
# Installs the system packages sphereshade needs to build and test on a fresh
# Debian 12 machine: lavapipe (CPU Vulkan), the Khronos validation layers,
# glslang/spirv tools, cmake + a C++ compiler + python3 (shaderc is built from
# source), Xvfb for the windowed smoke test and ffmpeg (trajectory movies,
# `render --movie`, and its test), and python3-venv/-dev for the Python
# module (`pip install .` in a venv; .ci/run runs its tests), and tachyon,
# the ray tracer tests/look.rs compares the look with. Idempotent: packages already
# present are skipped by apt-get; nothing is installed when all are there.
set -euo pipefail

PKGS=(mesa-vulkan-drivers vulkan-validationlayers vulkan-tools glslang-tools
      spirv-tools libvulkan-dev xvfb xauth cmake g++ python3 pkg-config
      libx11-dev libxkbcommon-dev libxkbcommon-x11-0 libwayland-dev ffmpeg
      python3-venv python3-dev python3-pip tachyon)

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup.sh: all system packages present"
else
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "setup.sh: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# vulkaninfo and the loader want a runtime dir; callers source nothing, so we
# only report what they should set.
if ! command -v vulkaninfo >/dev/null; then
  echo "setup.sh: vulkaninfo missing after install" >&2
  exit 1
fi
