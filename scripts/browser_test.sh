#!/usr/bin/env bash
# Browser test of the web map: the page at / in a real headless Chromium with software WebGL2.
#
#   1. Installs Debian's `chromium` with apt-get if /usr/bin/chromium is missing (as root, or with
#      sudo), and the pinned npm dependencies (MapLibre GL JS, playwright-core) with
#      scripts/install_web.sh.
#   2. Builds the release binary (skip with --no-build, or run another with --bin PATH: .ci/run
#      passes the binary `cargo test` built) and starts it on 127.0.0.1:PORT with the default
#      world (its dictionary store under target/browser-store is kept between runs).
#   3. Runs tests/browser/map_test.mjs: no console errors or failed requests, tiles of every layer
#      answered 200/304, the canvas drawn, a fly-to at zoom 13 still drawn, the elevation readout
#      plausible. Screenshots and the recorded tile trace (browser-trace.txt, replayable with
#      scripts/loadtest.sh --trace) go to OUT.
#   4. Stops the server (also on failure or Ctrl-C) and exits with the test's status.
#
# Usage: scripts/browser_test.sh [--no-build] [--bin PATH] [--port N] [--out DIR]
#        (defaults: target/release/terrasynth, 18090, target/browser)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
PORT=18090
OUT="$ROOT/target/browser"
BUILD=1
BIN="${CARGO_TARGET_DIR:-$ROOT/target}/release/terrasynth"
while (($#)); do
    case "$1" in
        --no-build) BUILD=0 ;;
        --bin) BIN="$2"; BUILD=0; shift ;;
        --port) PORT="$2"; shift ;;
        --out) OUT="$2"; shift ;;
        -h | --help) sed -n '2,/^$/p' "${BASH_SOURCE[0]}" | sed -e 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "browser_test: unknown option $1" >&2; exit 2 ;;
    esac
    shift
done

if [[ ! -x /usr/bin/chromium ]]; then
    SUDO=""
    [[ "$(id -u)" -eq 0 ]] || SUDO="sudo"
    log "installing Debian's chromium with apt-get"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi
command -v node >/dev/null || { log "node is not installed"; exit 1; }
bash scripts/install_web.sh

if ((BUILD)); then
    cargo build --release --quiet
fi
[[ -x "$BIN" ]] || { log "no binary at $BIN (drop --no-build)"; exit 1; }

mkdir -p "$OUT"
SERVER_LOG="$OUT/server.log"
TERRASYNTH_LISTEN="127.0.0.1:$PORT" TERRASYNTH_STORE_DIR="$ROOT/target/browser-store" \
    "$BIN" serve --config "$ROOT/config/default.toml" >"$SERVER_LOG" 2>&1 &
SERVER_PID=$!
trap 'kill "$SERVER_PID" 2>/dev/null; wait "$SERVER_PID" 2>/dev/null || true' EXIT
wait_until_up "http://127.0.0.1:$PORT/healthz" "$SERVER_PID" 300 "$SERVER_LOG" ||
    { log "the server did not become healthy"; exit 1; }
log "server up on port $PORT; running the browser test"
node ${MAP_TEST:-tests/browser/map_test.mjs} --url "http://127.0.0.1:$PORT" --out "$OUT"
# The instance tiles (#17) rendered by MapLibre at zooms 15 and 16 (the README picture).
[[ -n "${MAP_TEST:-}" ]] || node tests/browser/instances_test.mjs --url "http://127.0.0.1:$PORT" --out "$OUT"
