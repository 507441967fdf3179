#!/usr/bin/env bash
# Abuse test of the terrasynth server (issue #14, acceptance 2), over loopback only (127.0.0.1),
# bounded in time. Not part of CI.
#
# Starts the release binary on the default configuration (the Tien Shan world, cache_mb from the
# configuration, an admin token) with its soft open-file limit set to 1024 (the usual default; the
# server raises it to fit max_connections, up to the hard limit), then runs four scenarios
# one after the other (scripts/abuse.py does the work, standard library only):
#
#   slowloris  600 connections trickling one header line a second and 1,100 connections that say
#              nothing, all reconnecting when closed (more sockets than file descriptors)
#   metrics    20,000 requests with random method tokens and random paths on keep-alive
#              connections; the size of /metrics before and after
#   overload   400 concurrent clients requesting distinct cold zoom-16 tiles of every layer, each
#              giving up after 5 s; then the CPU seconds the server spends in the 10 s after the
#              clients left (abandoned synthesis must stop)
#   upload     4 parallel uploads of a 260 KB deflate GeoTIFF of 8192² zeros in a loop (each
#              stored one is deleted again) and one chunked body of zeros streamed past max_body_mb
#
# During each scenario a prober GETs /healthz on a fresh connection every 25 ms and a sampler reads
# the server's VmRSS every 100 ms. Reported per scenario: its own figures, /healthz p50/p99/max and
# failures, peak RSS, and the lines (and ERROR lines) the server logged. Targets: /healthz p99
# under 50 ms, RSS within cache_mb + 300 MB, zero ERROR lines. The report is printed and written to
# target/abuse-report.md; the server log and the JSON lines are kept in target/abuse/.
#
# Usage: scripts/abuse.sh [options]
#   --port N          port on 127.0.0.1 (default: a free one)
#   --seconds S       length of each scenario (default 20; the overload one adds 10 s of watching)
#   --store-dir DIR   store reused between runs (default target/abuse-store; the first run builds the
#                     default world's dictionary, a few minutes)
#   --bin PATH        server binary (default target/release/terrasynth)
#   --no-build        do not run `cargo build --release`
#   --only NAMES      comma-separated subset of slowloris,metrics,overload,upload
#   -h, --help        this help
#
# Needs bash, python3 (standard library) and cargo. The server it starts is stopped on exit.

set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

PORT=""
SECONDS_EACH=20
STORE="target/abuse-store"
BIN="${CARGO_TARGET_DIR:-target}/release/terrasynth"
BUILD=1
ONLY="slowloris,metrics,overload,upload"
while (($#)); do
    case "$1" in
    --port) PORT="$2"; shift 2 ;;
    --seconds) SECONDS_EACH="$2"; shift 2 ;;
    --store-dir) STORE="$2"; shift 2 ;;
    --bin) BIN="$2"; shift 2 ;;
    --no-build) BUILD=0; shift ;;
    --only) ONLY="$2"; shift 2 ;;
    -h | --help) sed -n '2,/^$/p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "abuse.sh: unknown option $1" >&2; exit 2 ;;
    esac
done

[[ -n "$PORT" ]] || PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')

if ((BUILD)); then
    cargo build --release --quiet
fi
[[ -x "$BIN" ]] || { echo "abuse.sh: no binary at $BIN" >&2; exit 1; }

OUT=target/abuse
mkdir -p "$OUT" "$STORE"
LOG="$OUT/server.log"
: >"$LOG"
TOKEN="abuse-$RANDOM$RANDOM"
CACHE_MB=$(sed -n 's/^cache_mb *= *\([0-9]*\).*/\1/p' config/default.toml)
CACHE_MB="${TERRASYNTH_CACHE_MB:-$CACHE_MB}"

PID=""
cleanup() {
    if [[ -n "$PID" ]] && kill -0 "$PID" 2>/dev/null; then
        kill -TERM "$PID" 2>/dev/null || true
        for _ in $(seq 50); do kill -0 "$PID" 2>/dev/null || break; sleep 0.2; done
        kill -KILL "$PID" 2>/dev/null || true
    fi
}
trap cleanup EXIT INT TERM

# The server's soft open-file limit: 1024, as in the issue's reproduction.
(
    ulimit -Sn 1024
    exec env TERRASYNTH_ADMIN_TOKEN="$TOKEN" TERRASYNTH_STORE_DIR="$STORE" \
        TERRASYNTH_CACHE_MB="$CACHE_MB" RUST_LOG="${RUST_LOG:-info}" \
        "$BIN" serve --listen "127.0.0.1:$PORT"
) >>"$LOG" 2>&1 &
PID=$!
echo "abuse.sh: server pid $PID on 127.0.0.1:$PORT (log $LOG); waiting for /healthz"
wait_until_up "http://127.0.0.1:$PORT/healthz" "$PID" 600 "$LOG" ||
    { echo "abuse.sh: the server did not become healthy" >&2; exit 1; }
# Let the whole-world layers (computed in the background at start) finish: wait until the CPU
# time stops growing.
prev=-1
for _ in $(seq 600); do
    now=$(awk '{print $14+$15}' "/proc/$PID/stat")
    [[ "$now" == "$prev" ]] && break
    prev=$now
    sleep 1
done
BASE_RSS=$(awk '/VmRSS/{printf "%.0f", $2/1024}' "/proc/$PID/status")
echo "abuse.sh: ready; RSS at rest ${BASE_RSS} MB; cache_mb ${CACHE_MB}"

RESULTS="$OUT/results.jsonl"
: >"$RESULTS"
IFS=',' read -r -a SCENARIOS <<<"$ONLY"
for sc in "${SCENARIOS[@]}"; do
    echo "abuse.sh: scenario $sc (${SECONDS_EACH} s)"
    python3 scripts/abuse.py "$sc" --port "$PORT" --pid "$PID" --log "$LOG" --token "$TOKEN" \
        --seconds "$SECONDS_EACH" | tee -a "$RESULTS"
    kill -0 "$PID" 2>/dev/null || { echo "abuse.sh: the server died during $sc; see $LOG" >&2; exit 1; }
    sleep 3
done
ERRORS_TOTAL=$(grep -c "ERROR" "$LOG" || true)

python3 - "$RESULTS" "$CACHE_MB" "$BASE_RSS" "$ERRORS_TOTAL" <<'EOF' | tee target/abuse-report.md
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
cache_mb, base, errors = int(sys.argv[2]), sys.argv[3], sys.argv[4]
print(f"cache_mb = {cache_mb} (RSS target {cache_mb + 300} MB); RSS at rest {base} MB; "
      f"ERROR lines in the whole log: {errors}\n")
print("| scenario | /healthz p50 / p99 / max ms | /healthz failures | peak RSS MB | log lines (ERROR) | figures |")
print("| --- | --- | --- | --- | --- | --- |")
skip = {"scenario", "seconds", "healthz_probes", "healthz_failures", "healthz_p50_ms",
        "healthz_p99_ms", "healthz_max_ms", "peak_rss_mb", "log_lines", "error_lines"}
for r in rows:
    figs = "; ".join(f"{k} {json.dumps(v)}" for k, v in r.items() if k not in skip)
    print(f"| {r['scenario']} | {r['healthz_p50_ms']} / {r['healthz_p99_ms']} / {r['healthz_max_ms']} "
          f"| {r['healthz_failures']} of {r['healthz_probes']} | {r['peak_rss_mb']} "
          f"| {r['log_lines']} ({r['error_lines']}) | {figs} |")
EOF
