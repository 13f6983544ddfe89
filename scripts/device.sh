#!/usr/bin/env bash
# The GPU measurements and checks, on a machine lent with a real GPU (see the device tool's
# README), in one call: `make devbin` here first (the release binary and the GPU test binaries,
# stripped, into .devbin/, the Vulkan loader package into .gl/, both ignored by git), then run
# this there with `carry: [".gl", ".devbin"]`:
#
#   scripts/device.sh     # writes $OUT/bench-1080p.json, bench-4k.json, bench-1080p-bytes.json,
#                         # tests.txt and log.txt
#
# 1. Every method's steady-state frames at 1920x1080, 2 fragments a pixel, every built-in scene,
#    with the per-pass GPU times, DKB/VKB and DKB/A-buffer (`dhoit bench --gpu-only`).
# 2. The GPU tests (every pass held to its CPU twin, 4K and 8K frames, burn = twin = shader) on
#    that GPU instead of lavapipe.
# 3. The same bench at 3840x2160, and at 1920x1080 with one byte budget for every method.
# Each step has its own time limit, so a slow one cannot take the others' results with it; a
# bench stopped by its limit leaves the scenes it finished (its JSON marked "partial").
set -uo pipefail
out="${OUT:-out/device}"
mkdir -p "$out"
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
# The NVIDIA Vulkan driver lives in libGLX_nvidia, which needs glvnd's dispatch library.
ldd /usr/local/nvidia/lib64/libGLX_nvidia.so.0 2>&1 | grep "not found" || true
export VK_DRIVER_FILES="${VK_DRIVER_FILES:-/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json}"
# The test binaries find the repository (weights, the CLI) where they were built.
built="$(cat .devbin/built-in 2>/dev/null || echo /work/main)"
if [ "$built" != "$PWD" ] && [ ! -e "$built" ]; then
  mkdir -p "$(dirname "$built")" && ln -s "$PWD" "$built"
fi
mkdir -p target/release && cp .devbin/dhoit target/release/dhoit
{
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
  nproc
  VK_LOADER_DEBUG=error .devbin/dhoit bench --gpu-only --scenes shells --res 64x48 --repeat 1 2>&1 >/dev/null | head -8
  echo "== bench 1920x1080 2fpp"
  timeout 190 .devbin/dhoit bench --gpu-only --res 1920x1080 --budget 2fpp --repeat 7 --out "$out/bench-1080p.json" >/dev/null
  echo "== GPU tests"
  for t in gpu extremes equivalence; do
    [ -x ".devbin/test-$t" ] || continue
    timeout 100 ".devbin/test-$t" --test-threads 8 2>&1 | tee -a "$out/tests.txt" | grep -E "^test result|FAILED|panicked|GPU tests on|8K|7680" 
  done
  echo "== bench 3840x2160 2fpp"
  timeout 120 .devbin/dhoit bench --gpu-only --scenes particles,plates,shells,foliage --res 3840x2160 --budget 2fpp --repeat 3 --out "$out/bench-4k.json" >/dev/null
  echo "== bench 1920x1080 160MB"
  timeout 90 .devbin/dhoit bench --gpu-only --res 1920x1080 --budget 160MB --repeat 3 --out "$out/bench-1080p-bytes.json" >/dev/null
} 2>&1 | tee "$out/log.txt"
