#!/usr/bin/env bash
# `cargo install --path .` works (part of .ci/run): the installed binary, run from a directory
# with no configuration, serves the default world (embedded data and configuration) and the web
# map with its MapLibre GL JS files. CI installs the test profile into the shared target
# directory (`--profile test --target-dir target`) so that it reuses the build `cargo test` has just
# made (Cargo.toml keeps the two builds' features and build-script settings the same, so nothing
# is recompiled); a user's plain `cargo install --path .` builds the release profile, with the
# same code.
#
# Usage: scripts/install_test.sh
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cd "$(dirname "$0")/.."
src=$PWD
root=$(mktemp -d)
elsewhere=$(mktemp -d)
pid=
cleanup() {
    [ -n "$pid" ] && kill "$pid" 2>/dev/null && wait "$pid" 2>/dev/null
    rm -rf "$root" "$elsewhere"
}
trap cleanup EXIT
echo "install-test: cargo install --path . --root $root"
cargo install --path "$src" --root "$root" --profile test --locked --target-dir "$src/target" \
    2>"$root/install.log" || { cat "$root/install.log" >&2; exit 1; }
# Not a failure, a hint for whoever finds this step slow: the build should be the test build's.
recompiled=$(grep -c '^ *Compiling ' "$root/install.log" || true)
[ "$recompiled" -eq 0 ] ||
    echo "install-test: note: $recompiled crates recompiled; the features of the test build and of the server alone differ (see the feature-unification block in Cargo.toml)" >&2
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cd "$elsewhere"
TERRASYNTH_STORE_DIR="$elsewhere/store" "$root/bin/terrasynth" serve --listen "127.0.0.1:$port" \
    >"$elsewhere/server.log" 2>&1 &
pid=$!
S=http://127.0.0.1:$port
wait_until_up "$S/healthz" "$pid" 600 "$elsewhere/server.log" ||
    { echo "install-test: the server did not become healthy" >&2; exit 1; }
check() { # path expected-content-type
    local got
    got=$(curl -s -o /dev/null -w '%{http_code} %{content_type}' "$S$1")
    case $got in
        "200 $2"*) echo "install-test: $1: $got" ;;
        *) echo "install-test: FAIL $1: $got (expected 200 $2)" >&2; exit 1 ;;
    esac
}
check /worlds/tienshan application/json
check /tiles/tienshan/elevation/10/723/377.png image/png
check / text/html
check /minimal.html text/html
check /vendor/maplibre-gl/maplibre-gl.mjs text/javascript
check /vendor/maplibre-gl/maplibre-gl.css text/css
[ ! -e "$elsewhere/config" ] || { echo "install-test: a config directory appeared" >&2; exit 1; }
echo "install-test: passed"
