#!/usr/bin/env bash
# The WebGPU checks (`make webgpu`, and `make test` through scripts/test.sh):
# 1. dhoit-runtime builds for wasm32-unknown-unknown with wgpu's WebGPU backend (without the
#    FLIP metric, C++);
# 2. every pipeline dhoit's renderer builds for the methods WebGPU runs, recorded on WebGPU's
#    core device (examples/webgpu_pipelines.rs), is created on Dawn (Chrome's WebGPU) with no
#    optional feature and WebGPU's default limits, without a validation error
#    (scripts/webgpu_pipelines.mjs);
# 3. the web page (examples/web): its wasm build's frames on Dawn, every method a page runs, held
#    to the native frames bit for bit, and the page itself in a headless Chromium
#    (scripts/web.sh test).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "$XDG_RUNTIME_DIR" ]; then
  XDG_RUNTIME_DIR=$(mktemp -d)
  export XDG_RUNTIME_DIR
fi
rustup target list --installed | grep -qx wasm32-unknown-unknown || rustup target add wasm32-unknown-unknown
cargo build --release -p dhoit-runtime --target wasm32-unknown-unknown --no-default-features --features gpu
echo "webgpu: dhoit-runtime builds for wasm32 (wgpu's WebGPU backend)"
./scripts/dawn.sh setup
manifest=target/webgpu-pipelines.json
cargo run --release --example webgpu_pipelines -- "$manifest"
# Dawn's start-up notes on the limits it reduces are not ours.
./scripts/dawn.sh run scripts/webgpu_pipelines.mjs "$manifest" 2> >(grep -v "^Warning: max" >&2)
./scripts/web.sh test
