#!/usr/bin/env bash
# The GPU measurements, on a machine lent with a real GPU (see the device tool's README), in one
# call: `make devbin` here first (the release binary into .devbin/, the Vulkan loader packages
# into .gl/, both ignored by git), then run this there with `carry: [".gl", ".devbin"]`:
#
#   scripts/device.sh            # writes $OUT/bench-1080p.json, $OUT/bench-4k.json, $OUT/log.txt
#
# Every method's steady-state frames at 1920x1080 and 3840x2160, 2 fragments a pixel, every
# built-in scene, with the per-pass GPU times, DKB/VKB and DKB/A-buffer (dhoit bench).
set -euo pipefail
out="${OUT:-out/device}"
mkdir -p "$out"
if ! ldconfig -p | grep -q libvulkan; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
export VK_DRIVER_FILES="${VK_DRIVER_FILES:-/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json}"
{
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
  .devbin/dhoit bench --res 1920x1080 --budget 2fpp --repeat 5 --out "$out/bench-1080p.json"
  .devbin/dhoit bench --res 3840x2160 --budget 2fpp --repeat 3 --out "$out/bench-4k.json"
} 2>&1 | tee "$out/log.txt"
