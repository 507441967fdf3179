#!/usr/bin/env bash
# Runs schemathesis against a live `terrasynth serve` with the committed OpenAPI description
# (openapi/openapi.json): checks that no response is a 5xx and that every response conforms to
# its schema. Installs a pinned schemathesis with pip into a virtualenv under target/ (nothing
# global), starts the binary with an admin token on a free port and a store under target/, and
# stops the server when done. The binary is target/debug/terrasynth (built by `cargo build`, or by
# `cargo test`, which .ci/run runs first: then `--no-build` reuses it), or the release one.
# Usage: scripts/schemathesis.sh [--release] [--no-build] [extra schemathesis args]
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cd "$(dirname "$0")/.."

SCHEMATHESIS_VERSION=4.32.5
PROFILE=debug
BUILD=1
while [[ "${1:-}" == "--release" || "${1:-}" == "--no-build" ]]; do
    if [[ "$1" == "--release" ]]; then PROFILE=release; else BUILD=0; fi
    shift
done

VENV=target/schemathesis-venv
pinned_venv "$VENV" schemathesis "$SCHEMATHESIS_VERSION"

if ((BUILD)); then
    if [[ "$PROFILE" == release ]]; then cargo build --release --quiet; else cargo build --quiet; fi
fi
BIN="target/$PROFILE/terrasynth"
[[ -x "$BIN" ]] || { echo "schemathesis: no binary at $BIN (drop --no-build)" >&2; exit 1; }

PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
TOKEN="schemathesis-$RANDOM$RANDOM"
# The store persists between runs (the default world's dictionary is built once); the objects
# schemathesis creates are removed at the start of each run.
STORE=target/schemathesis-store
rm -rf "$STORE/exemplars" "$STORE/worlds" "$STORE/jobs" "$STORE/corrupt"
rm -f "$STORE"/aliases/exemplar.* "$STORE"/aliases/world.* "$STORE"/aliases/dictionary.*
LOG=target/schemathesis-server.log
# schemathesis deliberately sends wrong and missing tokens from one address: without a higher
# failed-authentication limit, most admin operations would only ever see 429.
TERRASYNTH_ADMIN_TOKEN="$TOKEN" TERRASYNTH_STORE_DIR="$STORE" TERRASYNTH_CACHE_MB=128 \
    TERRASYNTH_AUTH_FAILURES_PER_MINUTE=1000000 \
    "$BIN" serve --listen "127.0.0.1:$PORT" >"$LOG" 2>&1 &
SERVER=$!
trap 'kill "$SERVER" 2>/dev/null || true; wait "$SERVER" 2>/dev/null || true' EXIT

wait_until_up "http://127.0.0.1:$PORT/healthz" "$SERVER" 300 "$LOG" ||
    { echo "schemathesis: the server did not become healthy" >&2; exit 1; }

# One worker: with several, CPython 3.11's `ast` module (used by hypothesis to describe strategies)
# is not thread-safe and schemathesis intermittently reports an internal "AST constructor recursion
# depth mismatch" runtime error in the coverage phase.
"$VENV/bin/schemathesis" run openapi/openapi.json \
    --url "http://127.0.0.1:$PORT" \
    --header "Authorization: Bearer $TOKEN" \
    --checks not_a_server_error,response_schema_conformance \
    --max-examples "${SCHEMATHESIS_MAX_EXAMPLES:-25}" \
    --seed 1 \
    --workers 1 \
    --request-timeout 60 \
    --no-color \
    "$@"
