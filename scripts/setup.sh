#!/usr/bin/env bash
# Installs what building and testing dhoit needs on a Debian machine: Mesa's Vulkan drivers
# (lavapipe, the CPU Vulkan device the GPU tests run on), a TrueType font for the words in
# plots and montages (fonts-dejavu-core), a C++ compiler for FLIP (nv-flip builds NVIDIA's C++
# FLIP), python3 and curl (the documents' table check, the web page's server) and the rustfmt /
# clippy components.
# Safe to run again: it only installs what is missing.
set -euo pipefail

need_apt=()
dpkg -s mesa-vulkan-drivers >/dev/null 2>&1 || need_apt+=(mesa-vulkan-drivers)
dpkg -s fonts-dejavu-core >/dev/null 2>&1 || need_apt+=(fonts-dejavu-core)
command -v c++ >/dev/null 2>&1 || need_apt+=(g++)
# The documents' table check and the web page's server.
command -v python3 >/dev/null 2>&1 || need_apt+=(python3)
command -v curl >/dev/null 2>&1 || need_apt+=(curl)
if [ ${#need_apt[@]} -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "setup: please install with your package manager: ${need_apt[*]} (Mesa's Vulkan drivers, a TrueType font, a C++ compiler, python3, curl)" >&2
    exit 1
  fi
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    if sudo -n true 2>/dev/null; then sudo="sudo -n"; else
      echo "setup: run as root, or install these first: ${need_apt[*]}" >&2
      exit 1
    fi
  fi
  echo "setup: installing ${need_apt[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

for comp in rustfmt clippy; do
  if ! cargo "${comp/rustfmt/fmt}" --version >/dev/null 2>&1; then
    echo "setup: adding the $comp component" >&2
    rustup component add "$comp"
  fi
done
