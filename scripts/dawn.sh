#!/usr/bin/env bash
# Dawn (Chrome's WebGPU) on this machine's CPU, for checking dhoit's passes on a real WebGPU:
# npm's `webgpu` package over Mesa 25's lavapipe, unpacked from Debian's bookworm-backports into
# a private folder ($DAWN_HOME, default target/dawn), so the system's Mesa 22.3 lavapipe (which
# Dawn refuses: it lacks shaderUniformBufferArrayDynamicIndexing) stays as the other tests use
# it. Node 18 or later must be installed (Debian's nodejs; setup installs it where missing).
#   dawn.sh setup          once (about a minute; safe to run again)
#   dawn.sh run FILE.mjs   node with Dawn: the script imports process.env.DAWN_WEBGPU
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dir=${DAWN_HOME:-$root/target/dawn}
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo -n"

setup() {
  mkdir -p "$dir/debs" "$dir/root" "$dir/node"
  if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    echo "dawn: installing nodejs and npm" >&2
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq nodejs npm >/dev/null
  fi
  lib="$dir/root/usr/lib/x86_64-linux-gnu"
  if [ ! -f "$lib/libvulkan_lvp.so" ]; then
    if ! apt-cache policy mesa-vulkan-drivers 2>/dev/null | grep -q bpo12; then
      grep -rqs bookworm-backports /etc/apt/sources.list /etc/apt/sources.list.d/ ||
        echo "deb http://deb.debian.org/debian bookworm-backports main" |
        $sudo tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
      $sudo apt-get update -qq
    fi
    (cd "$dir/debs" && apt-get download -qq mesa-vulkan-drivers/bookworm-backports \
      libdrm2/bookworm-backports libdrm-amdgpu1/bookworm-backports 2>&1 |
      grep -v "^W: Download is performed unsandboxed" || true)
    for f in "$dir"/debs/*.deb; do dpkg -x "$f" "$dir/root"; done
    [ -f "$lib/libvulkan_lvp.so" ] || { echo "dawn: no libvulkan_lvp.so unpacked" >&2; exit 1; }
  fi
  printf '{"file_format_version": "1.0.0", "ICD": {"library_path": "%s", "api_version": "1.4.305"}}\n' \
    "$lib/libvulkan_lvp.so" >"$dir/lvp.json"
  if [ ! -f "$dir/node/node_modules/webgpu/index.js" ]; then
    (cd "$dir/node" && { [ -f package.json ] || npm init -y >/dev/null; } &&
      npm install --no-audit --no-fund webgpu@0.6.2 >/dev/null &&
      { node node_modules/webgpu/build/postinstall.js >/dev/null 2>&1 || true; })
  fi
  echo "dawn: ready in $dir"
}

run() {
  [ -f "$dir/lvp.json" ] || { echo "dawn: run 'scripts/dawn.sh setup' first ($dir)" >&2; exit 1; }
  export LD_LIBRARY_PATH="$dir/root/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export VK_ICD_FILENAMES="$dir/lvp.json"
  export DAWN_WEBGPU="$dir/node/node_modules/webgpu/index.js"
  if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "$XDG_RUNTIME_DIR" ]; then
    XDG_RUNTIME_DIR=$(mktemp -d)
    export XDG_RUNTIME_DIR
  fi
  exec node "$@"
}

case "${1:-}" in
  setup) setup ;;
  run) shift; run "$@" ;;
  *) echo "usage: dawn.sh setup | dawn.sh run FILE.mjs [ARGS...]" >&2; exit 2 ;;
esac
