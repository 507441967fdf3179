#!/usr/bin/env bash
# The mutation run of issue #14 (acceptance 3), over loopback only; not part of CI.
#
# Starts the release binary without worlds (nothing to build) with an admin token and a fresh
# store under target/, then runs scripts/examples/mutation_run.rs: COUNT uploads (default 100,000)
# of mutated GeoTIFF, 16-bit PNG and OpenEXR files (bit flips, truncations, header edits, slices
# duplicated or removed), deleting again every upload that is accepted. It fails when an upload
# is answered 5xx or breaks its connection, or when the store's files differ from what they were
# before (checked every 1,000 uploads and at the end). Afterwards the server log is searched for
# panics and ERROR lines, and the server's peak RSS is read.
#
# Usage: scripts/mutation_run.sh [--count N] [--threads N] [--seed N] [--port N] [--no-build]
# (threads must not exceed max_concurrent_uploads, 2 by default: beyond, uploads are 503).
set -euo pipefail
cd "$(dirname "$0")/.."

COUNT=100000
THREADS=2
SEED=14
PORT=""
BUILD=1
while (($#)); do
    case "$1" in
    --count) COUNT="$2"; shift 2 ;;
    --threads) THREADS="$2"; shift 2 ;;
    --seed) SEED="$2"; shift 2 ;;
    --port) PORT="$2"; shift 2 ;;
    --no-build) BUILD=0; shift ;;
    *) echo "mutation_run.sh: unknown option $1" >&2; exit 2 ;;
    esac
done

[[ -n "$PORT" ]] || PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')

if ((BUILD)); then
    cargo build --release --quiet
    # The client is not what is measured: the dev profile (dependencies at opt-level 2) will do.
    cargo build --quiet --example mutation_run
fi
TARGET="${CARGO_TARGET_DIR:-target}"
BIN="$TARGET/release/terrasynth"
TOOL="$TARGET/debug/examples/mutation_run"

OUT=target/mutation
rm -rf "$OUT"
mkdir -p "$OUT"
STORE="$OUT/store"
LOG="$OUT/server.log"
printf 'worlds = []\n' >"$OUT/config.toml"
TOKEN="mutation-$RANDOM$RANDOM"

PID=""
cleanup() {
    if [[ -n "$PID" ]] && kill -0 "$PID" 2>/dev/null; then
        kill -TERM "$PID" 2>/dev/null || true
        for _ in $(seq 50); do kill -0 "$PID" 2>/dev/null || break; sleep 0.2; done
        kill -KILL "$PID" 2>/dev/null || true
    fi
}
trap cleanup EXIT INT TERM

TERRASYNTH_ADMIN_TOKEN="$TOKEN" TERRASYNTH_STORE_DIR="$STORE" \
    "$BIN" serve --config "$OUT/config.toml" --listen "127.0.0.1:$PORT" >"$LOG" 2>&1 &
PID=$!
for _ in $(seq 200); do
    curl -sf "http://127.0.0.1:$PORT/healthz" >/dev/null 2>&1 && break
    sleep 0.1
done

status=0
"$TOOL" --base "http://127.0.0.1:$PORT" --token "$TOKEN" --store "$STORE" \
    --count "$COUNT" --threads "$THREADS" --seed "$SEED" 2>"$OUT/tool.log" || status=$?
kill -0 "$PID" 2>/dev/null || { echo "the server died (see $LOG)"; status=1; }
PEAK=$(awk '/VmHWM/{printf "%.0f", $2/1024}' "/proc/$PID/status" 2>/dev/null || echo "?")
PANICS=$(grep -c "panicked" "$LOG" || true)
ERRORS=$(grep -c "ERROR" "$LOG" || true)
echo "server: peak RSS ${PEAK} MB; panics ${PANICS}; ERROR lines ${ERRORS} (log $LOG, tool log $OUT/tool.log)"
if ((PANICS > 0 || ERRORS > 0)); then status=1; fi
exit "$status"
