#!/usr/bin/env bash
# Runs every test of the workspace (release profile) and closes with one summary line over all
# test binaries, so the total is visible at the end of a long log.
set -uo pipefail
# Mesa's Vulkan loader warns on stderr without a runtime directory; give it a private one.
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "$XDG_RUNTIME_DIR" ]; then
  XDG_RUNTIME_DIR=$(mktemp -d)
  export XDG_RUNTIME_DIR
fi
log=$(mktemp)
cargo test --release --workspace --all-targets "$@" 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
# The documentation's examples (`--all-targets` leaves doc tests out), the GPU one on lavapipe.
cargo test --release --workspace --doc "$@" 2>&1 | tee -a "$log"
doc_status=${PIPESTATUS[0]}
[ "$status" -eq 0 ] && status=$doc_status
# The GPU tests a second time, on WebGPU's core device (DHOIT_DEVICE=webgpu-core: no optional
# feature, WebGPU's default limits, the portable capture), each held to its twins as on the
# 64-bit device. A check needing what that device lacks (MBOIT's float32-blendable, the f16
# network's shader-f16, the 64-bit one-pass capture) prints NOT CHECKED, naming it; the four
# command-line tests of bench, trade and versus are left out, their figures being pass times
# that need timestamps.
core_skips=(--skip the_gpu_bench_reports_every_method_and_option
  --skip versus_puts_every_method_at_one_memory_and_marks_the_front
  --skip trade_reports_every_network_and_a_non_dominated_front_and_fit_picks_the_fewest_bytes
  --skip record_batches_trade_dkb_s_memory_for_passes_from_the_command_line)
core_tests=(-p dhoit-runtime)
for t in gpu oit_api extremes linked_list wboit mboit materials memory webgpu_core; do
  core_tests+=(--test "$t")
done
echo "GPU tests on WebGPU's core device (DHOIT_DEVICE=webgpu-core):"
DHOIT_DEVICE=webgpu-core cargo test --release "${core_tests[@]}" "$@" -- --nocapture 2>&1 |
  tee -a "$log" | grep -E "^test result|FAILED|panicked|^NOT CHECKED" | sort | uniq -c
core_status=${PIPESTATUS[0]}
DHOIT_DEVICE=webgpu-core cargo test --release -p dhoit --test cli --test equivalence \
  --test bad_inputs --test golden "$@" -- "${core_skips[@]}" 2>&1 | tee -a "$log" |
  grep -E "^test result|FAILED|panicked"
[ "${PIPESTATUS[0]}" -eq 0 ] || core_status=1
[ "$status" -eq 0 ] && status=$core_status
# The viewer example, headless, as a user runs it: an application's own renderer around the
# linked list, the fixed k-buffer, the exact A-buffer, DKB (exact where that is cheaper, and
# at its budget), VKB, WBOIT, MBOIT and MLAB, one PNG a view.
viewer_dir=$(mktemp -d)
viewer() { # NAME ARGS...: the viewer's frames of particles into $viewer_dir/NAME
  local name=$1
  shift
  cargo run --release --quiet --example viewer -- particles --res 160x120 --views 2 "$@" \
    --out "$viewer_dir/$name" >/dev/null && [ -s "$viewer_dir/$name/view0.png" ] &&
    [ -s "$viewer_dir/$name/view1.png" ]
}
for method in linked-list fkb abuffer dkb "dkb --always-approximate" vkb wboit "wboit --wboit-weight eq7" mboit mlab; do
  # shellcheck disable=SC2086 # the method's words are its flags
  if viewer "$(echo "$method" | tr -c 'a-z0-9\n' _)" --method $method; then
    echo "viewer example ($method): wrote its frames"
  else
    echo "viewer example ($method): FAILED" >&2
    [ "$status" -eq 0 ] && status=1
  fi
done
# Its frames against its own exact frame (the A-buffer's, both views): DKB and VKB with a
# budget that holds every fragment, and FKB with more slots than any pixel has fragments, are
# it byte for byte; at 25% of the fragments DKB is within 3 steps of it, and nearer than VKB,
# which is nearer than FKB at 2 slots (the quality order the methods' tests hold).
cargo build --release --quiet --example image_diff
image_diff="${CARGO_TARGET_DIR:-target}/release/examples/image_diff"
diff_sum() { "$image_diff" "$@" --max 255 --pixels 1 | sed -n 's/.*sum \([0-9]*\)$/\1/p'; }
viewer exact-dkb --method dkb --budget 100% && viewer exact-vkb --method vkb --budget 100% &&
  viewer exact-fkb --method fkb --k 256 && viewer dkb25 --method dkb --budget 25% --always-approximate &&
  viewer vkb25 --method vkb --budget 25% --always-approximate && viewer fkb2 --method fkb --k 2 ||
  { echo "viewer example: FAILED to render the frames it is held to" >&2; status=1; }
held=0
for v in 0 1; do
  ref=$viewer_dir/abuffer/view$v.png
  for exact in exact-dkb exact-vkb exact-fkb; do
    "$image_diff" "$ref" "$viewer_dir/$exact/view$v.png" --max 0 >/dev/null &&
      held=$((held + 1))
  done
  "$image_diff" "$ref" "$viewer_dir/dkb25/view$v.png" --max 3 --pixels 0.001 >/dev/null &&
    held=$((held + 1))
  d=$(diff_sum "$ref" "$viewer_dir/dkb25/view$v.png")
  k=$(diff_sum "$ref" "$viewer_dir/vkb25/view$v.png")
  f=$(diff_sum "$ref" "$viewer_dir/fkb2/view$v.png")
  [ -n "$d" ] && [ -n "$k" ] && [ -n "$f" ] && [ "$d" -lt "$k" ] && [ "$k" -lt "$f" ] && held=$((held + 1))
  echo "viewer view $v: summed differences from its A-buffer frame: DKB 25% $d, VKB 25% $k, FKB k=2 $f"
done
if [ "$held" -eq 10 ]; then
  echo "viewer example: its exact frames are its A-buffer's, its approximations in the methods' order"
else
  echo "viewer example: FAILED against its A-buffer frame ($held of 10 checks held)" >&2
  [ "$status" -eq 0 ] && status=1
fi
rm -rf "$viewer_dir"
# The viewer's interactive window (winit) builds; with no display it says so and exits non-zero.
if cargo build --release --example viewer --features window; then
  echo "viewer example (--features window): builds"
  if [ -z "${DISPLAY:-}" ] && [ -z "${WAYLAND_DISPLAY:-}" ]; then
    if window_err=$(cargo run --release --example viewer --features window -- particles --res 160x120 --window 2>&1); then
      echo "viewer --window without a display: exited 0 (FAILED)" >&2
      [ "$status" -eq 0 ] && status=1
    elif grep -q "found no display" <<<"$window_err"; then
      echo "viewer --window without a display: refused, naming the display"
    else
      echo "viewer --window without a display: FAILED without naming the display" >&2
      [ "$status" -eq 0 ] && status=1
    fi
  fi
else
  echo "viewer example (--features window): FAILED to build" >&2
  [ "$status" -eq 0 ] && status=1
fi
# The documents' tables are the generated ones (the README's results and docs/results.md's
# tables: make eval, versus, trade, frame) and the README's sentences on its table hold.
if python3 scripts/results_table.py --check; then
  echo "documents: every table the commands produce is theirs, the README's claims hold"
else
  echo "documents: FAILED: a table differs from its source or a claim from its table" >&2
  [ "$status" -eq 0 ] && status=1
fi
# The modules' imports: no import circle (scripts/module_cycles.py).
if python3 scripts/module_cycles.py; then
  :
else
  echo "modules: FAILED: an import circle" >&2
  [ "$status" -eq 0 ] && status=1
fi
# WebGPU: the wasm32 build, every pipeline of the methods WebGPU runs created on Dawn, the web
# page's frames on Dawn held to the native ones, and the page in a headless Chromium.
if ./scripts/webgpu.sh; then
  echo "webgpu: the wasm32 build, Dawn's pipelines and frames, the page in Chromium: passed"
else
  echo "webgpu: FAILED" >&2
  [ "$status" -eq 0 ] && status=1
fi
read -r passed failed < <(awk '/^test result:/ { for (i = 1; i < NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } } END { print p + 0, f + 0 }' "$log")
rm -f "$log"
scenes_dir=${DHOIT_SCENES:-$(cd "$(dirname "$0")/.." && pwd)/../shared/scenes}
if [ -d "$scenes_dir" ]; then
  real="real scenes from $scenes_dir"
else
  real="no real scenes (built-ins exported as glTF stood in; set DHOIT_SCENES)"
fi
echo
echo "dhoit: ${passed:-0} passed, ${failed:-0} failed; $real"
if [ "${passed:-0}" -eq 0 ] && [ "$status" -eq 0 ]; then
  echo "no test ran" >&2
  exit 1
fi
exit "$status"
