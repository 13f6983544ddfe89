#!/usr/bin/env bash
# dhoit's web page (examples/web): its wasm build and, with `test`, its frames on Dawn.
#   web.sh build   the page's wasm and glue into examples/web/pkg (wasm-bindgen's CLI, of the
#                  version Cargo.lock pins, installed into target/wasm-bindgen once)
#   web.sh test    build, then render the page's frames natively on WebGPU's core device
#                  (dhoit-web) and with the wasm build on Dawn, Chrome's WebGPU (scripts/web_test.mjs),
#                  and hold them to each other; then load the page in a headless Chromium (Debian's
#                  chromium-headless-shell, its WebGPU on SwiftShader) and drive it
#                  (scripts/web_page.mjs)
#   web.sh record  test, then keep what it measured (target/web/measured.md, scripts/web_summary.py)
#                  as docs/web-measured.md, which docs/web.md copies
#   web.sh picture as test's last step, keeping its screenshot as docs/web.png
#   web.sh serve   build, then serve the page on http://localhost:8000 (python3)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "$XDG_RUNTIME_DIR" ]; then
  XDG_RUNTIME_DIR=$(mktemp -d)
  export XDG_RUNTIME_DIR
fi
target=${CARGO_TARGET_DIR:-$root/target}
pkg=$root/examples/web/pkg

build() {
  rustup target list --installed | grep -qx wasm32-unknown-unknown || rustup target add wasm32-unknown-unknown
  version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/[^0-9.]/, ""); print; exit }' Cargo.lock)
  bindgen=$target/wasm-bindgen/bin/wasm-bindgen
  if [ ! -x "$bindgen" ] || [ "$("$bindgen" --version | awk '{ print $2 }')" != "$version" ]; then
    echo "web: installing wasm-bindgen-cli $version (once, about two minutes)" >&2
    cargo install --quiet wasm-bindgen-cli --version "$version" --root "$target/wasm-bindgen"
  fi
  cargo build --release -p dhoit-web --lib --target wasm32-unknown-unknown
  "$bindgen" --target web --out-dir "$pkg" "$target/wasm32-unknown-unknown/release/dhoit_web.wasm"
  echo "web: the page's wasm in examples/web/pkg ($(du -k "$pkg/dhoit_web_bg.wasm" | cut -f1) KiB)"
}

# Chromium's headless shell (Debian's) and puppeteer-core to drive it (npm, into target/web/node).
browser_setup() {
  if ! command -v chromium-headless-shell >/dev/null; then
    echo "web: installing chromium-headless-shell (once)" >&2
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo -n"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium-headless-shell >/dev/null
  fi
  node_dir=$target/web/node
  if [ ! -f "$node_dir/node_modules/puppeteer-core/package.json" ]; then
    mkdir -p "$node_dir"
    (cd "$node_dir" && { [ -f package.json ] || npm init -y >/dev/null; } &&
      npm install --no-audit --no-fund puppeteer-core@23 >/dev/null)
  fi
  export PUPPETEER_FROM=$node_dir/package.json
}

# The page served from examples/web on a free port, for as long as this script runs.
serve_page() {
  port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  python3 -m http.server --bind 127.0.0.1 --directory examples/web "$port" >/dev/null 2>&1 &
  server=$!
  trap 'kill $server 2>/dev/null || true' EXIT
  for _ in $(seq 50); do curl -fs "http://127.0.0.1:$port/" >/dev/null 2>&1 && break; sleep 0.1; done
  url=http://127.0.0.1:$port/
}

# The native frames, the wasm ones on Dawn held to them, the page in Chromium; what they measured
# into target/web/measured.md.
run_test() {
  build
  ./scripts/dawn.sh setup
  # The page's three methods at its first budget, then every method a page runs at one slot a
  # pixel (FKB, MLAB and the list take no share of the fragments).
  for run in "page --budget 25%" "all --methods all --budget 1fpp"; do
    set -- $run
    name=$1
    native=$target/web/native-$name
    shift
    cargo run --release --quiet -p dhoit-web -- "$native" "$@"
    WEB_SUMMARY=$target/web/summary-$name.json \
      ./scripts/dawn.sh run scripts/web_test.mjs "$pkg" "$native" 2> >(grep -v "^Warning: max" >&2)
  done
  browser_setup
  serve_page
  WEB_PAGE_SUMMARY=$target/web/page.json node scripts/web_page.mjs "$url"
  python3 scripts/web_summary.py "$target/web" > "$target/web/measured.md"
  echo "web: what it measured in $target/web/measured.md (web.sh record keeps it in docs/)"
}

case "${1:-}" in
  build) build ;;
  picture)
    build
    browser_setup
    serve_page
    node scripts/web_page.mjs "$url" docs/web.png
    ;;
  test) run_test ;;
  record)
    run_test
    cp "$target/web/measured.md" docs/web-measured.md
    python3 scripts/results_table.py --write
    ;;
  serve)
    build
    echo "web: open http://localhost:8000 in a browser with WebGPU (Ctrl-C stops)"
    exec python3 -m http.server --directory examples/web 8000
    ;;
  *) echo "usage: web.sh build | test | record | picture | serve" >&2; exit 2 ;;
esac
