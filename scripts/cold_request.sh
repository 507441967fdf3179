#!/usr/bin/env bash
# One request of the load test's cold in-order replay, taken apart (a measurement, not in CI).
#
# Starts the given binary on the default world with empty tile caches (the dictionary store is
# reused, so start-up does not rebuild it) and with the level tiles' debug log on
# (RUST_LOG=info,terrasynth_tiles::levels=debug), replays the trace's requests before line N in
# order, one at a time over one connection (as scripts/loadtest.sh's cold replay does), then asks
# for line N and reports:
#   - its status and wall time, and the server's CPU time while it ran (/proc/PID/stat, Linux):
#     CPU over wall near 2 on a 2-core machine means the request was bound by the work, not by
#     waiting;
#   - the level tiles it computed, from the server's log: per layer and zoom, how many and when
#     the first started and the last ended, then every one in the order it finished with its
#     wall time (the level tiles it waited for included), start and end (milliseconds from the
#     moment the script launched curl for the request: curl's own start-up, a few milliseconds,
#     comes first, so a tile may end a little after the request's wall time).
# --repeat K starts K fresh servers and reports the request's times for each (the level tiles of
# the last): run it on two builds, alternating, to compare them on one request.
#
# Usage: scripts/cold_request.sh --line N [--bin PATH] [--store-dir DIR] [--trace FILE]
#                                [--trace-args "ARGS"] [--repeat K] [--port N]
#   --line N          the trace line to take apart (1-based)
#   --bin PATH        server binary (default target/release/terrasynth)
#   --store-dir DIR   dictionary store reused between runs (default target/loadtest-store, the
#                     load test's)
#   --trace FILE      a URL or path per line (default: scripts/make_trace.py with --trace-args)
#   --trace-args "ARGS"  arguments of make_trace.py (default "--instance-zooms 14", the trace of
#                     the README's cold-replay figures)
#   --repeat K        fresh servers, one after the other (default 1)
#   --port N          port on 127.0.0.1 (default 18098)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN="$ROOT/target/release/terrasynth"
STORE_DIR="$ROOT/target/loadtest-store"
TRACE=""
TRACE_ARGS="--instance-zooms 14"
LINE=""
REPEAT=1
PORT=18098

while [[ $# -gt 0 ]]; do
    case "$1" in
        --line) need_value "$@"; LINE="$2"; shift 2 ;;
        --bin) need_value "$@"; BIN="$2"; shift 2 ;;
        --store-dir) need_value "$@"; STORE_DIR="$2"; shift 2 ;;
        --trace) need_value "$@"; TRACE="$2"; shift 2 ;;
        --trace-args) [[ $# -ge 2 ]] || die "--trace-args needs a value"; TRACE_ARGS="$2"; shift 2 ;;
        --repeat) need_value "$@"; REPEAT="$2"; shift 2 ;;
        --port) need_value "$@"; PORT="$2"; shift 2 ;;
        -h|--help) sed -n '2,30p' "$0"; exit 0 ;;
        *) die "unknown argument '$1' (see --help)" ;;
    esac
done
[[ -n "$LINE" ]] || die "--line N is needed (see --help)"
[[ "$LINE" =~ ^[0-9]+$ && "$LINE" -ge 1 ]] || die "--line must be a line number (1 or more)"
[[ "$REPEAT" =~ ^[0-9]+$ && "$REPEAT" -ge 1 ]] || die "--repeat must be 1 or more"
[[ "$PORT" =~ ^[0-9]+$ && "$PORT" -ge 1 && "$PORT" -le 65535 ]] || die "--port must be 1-65535"
[[ -x "$BIN" ]] || die "no executable at $BIN (cargo build --release, or --bin)"
[[ -r /proc/self/stat ]] || die "needs Linux's /proc for the server's CPU time"
command -v curl >/dev/null || die "curl is needed"
command -v python3 >/dev/null || die "python3 is needed (scripts/make_trace.py)"
mkdir -p "$STORE_DIR"

S="http://127.0.0.1:$PORT"
WORK="$(mktemp -d)"
SERVER_PID=""
stop_server() {
    if [[ -n "$SERVER_PID" ]]; then
        stop_process "$SERVER_PID"
        SERVER_PID=""
    fi
}
trap 'stop_server; rm -rf "$WORK"' EXIT

# The trace as bare paths (a recorded file's scheme and host are dropped).
if [[ -n "$TRACE" ]]; then
    [[ -r "$TRACE" ]] || die "cannot read $TRACE"
    sed -E 's#^[a-z]+://[^/]+##' "$TRACE" | grep -v '^$' >"$WORK/paths" || true
else
    eval "python3 \"\$ROOT/scripts/make_trace.py\" --base-url '' $TRACE_ARGS" >"$WORK/paths"
fi
TOTAL=$(wc -l <"$WORK/paths")
[[ "$LINE" -le "$TOTAL" ]] || die "--line $LINE: the trace has $TOTAL lines"
TARGET=$(sed -n "${LINE}p" "$WORK/paths")
head -n $((LINE - 1)) "$WORK/paths" |
    awk -v s="$S" '{ printf "url = \"%s%s\"\noutput = \"/dev/null\"\n", s, $0 }' >"$WORK/before.curl"

TICKS=$(getconf CLK_TCK)
cpu_ms() { awk -v t="$TICKS" '{ printf "%d", ($14 + $15) * 1000 / t }' "/proc/$SERVER_PID/stat"; }

echo "# line $LINE of $TOTAL: $TARGET"
for run in $(seq 1 "$REPEAT"); do
    if curl -s -o /dev/null --max-time 2 "$S/"; then
        die "something already listens on $S; pick another --port"
    fi
    (cd "$ROOT" && exec env TERRASYNTH_STORE_DIR="$STORE_DIR" TERRASYNTH_CACHE_MB=512 \
        RUST_LOG="info,terrasynth_tiles::levels=debug" \
        "$BIN" serve --listen "127.0.0.1:$PORT") >"$WORK/server.log" 2>&1 &
    SERVER_PID=$!
    wait_until_up "$S/healthz" "$SERVER_PID" 300 "$WORK/server.log" ||
        die "the server did not become healthy"
    if [[ "$LINE" -gt 1 ]]; then
        curl -s --config "$WORK/before.curl" || die "the replay before line $LINE failed"
    fi
    # Whatever the replay left running finishes before the request is timed.
    sleep 1
    MARK=$(wc -l <"$WORK/server.log")
    C0=$(cpu_ms)
    T0=$(date -u +%s.%N)
    TIMED=$(curl -s -o /dev/null -w "%{http_code} %{time_total}" "$S$TARGET")
    C1=$(cpu_ms)
    # Level tiles the request started may still be logging their end.
    sleep 0.3
    stop_server
    read -r STATUS WALL <<<"$TIMED"
    awk -v r="$run" -v st="$STATUS" -v w="$WALL" -v c="$((C1 - C0))" 'BEGIN {
        printf "run %d: status %s, wall %.1f ms, server CPU %d ms (%.2f x wall)\n",
            r, st, w * 1000, c, (w > 0 ? c / (w * 1000) : 0) }'
done

# Each computed level tile as "layer zoom x y ms start end": its start and end in milliseconds
# from the moment curl was launched for the request (the log's UTC timestamp is the end).
tail -n +$((MARK + 1)) "$WORK/server.log" | grep 'level tile computed' |
    sed -E 's/^[0-9-]+T([0-9]+):([0-9]+):([0-9.]+)Z.*layer="([a-z]+)" z=([0-9]+) x=(-?[0-9]+) y=(-?[0-9]+) ms=([0-9.]+).*/\1 \2 \3 \4 \5 \6 \7 \8/' |
    awk -v t0="$T0" '{
        day = t0 - 86400 * int(t0 / 86400)
        end = ($1 * 3600 + $2 * 60 + $3 - day) * 1000
        if (end < -43200000) end += 86400000
        printf "%s %s %s %s %.1f %.1f %.1f\n", $4, $5, $6, $7, $8, end - $8, end }' \
        >"$WORK/levels" || true
echo "# level tiles the last run's request computed: $(wc -l <"$WORK/levels")"
echo "# layer zoom: count, first start, last end (ms from the launch of the request)"
sort -k1,1 -k2,2n "$WORK/levels" | awk '
    { k = $1 " " $2; if (!(k in n)) { o[++c] = k; s[k] = $6; e[k] = $7 }
      n[k]++; if ($6 < s[k]) s[k] = $6; if ($7 > e[k]) e[k] = $7 }
    END { for (i = 1; i <= c; i++) printf "%s: %d, %.1f, %.1f\n", o[i], n[o[i]], s[o[i]], e[o[i]] }'
echo "# in the order they finished: layer zoom x y ms start end"
cat "$WORK/levels"
