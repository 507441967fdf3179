#!/usr/bin/env bash
# Load test of the terrasynth tile server on this machine, over loopback only (127.0.0.1).
#
# What it does, in order:
#   1. Makes sure `oha` (an HTTP load generator) is on PATH; if not, installs it with
#      `cargo install oha --locked` (it says so first).
#   2. Builds the release binary with `cargo build --release` (skip with --no-build).
#   3. Writes a deterministic pan-and-zoom trace with scripts/make_trace.py: the tile URLs a web map
#      requests while a user pans a 4x3-tile viewport over the Tien Shan (Talas range, Bishkek) and
#      zooms in from 9 to 14, each tile once, elevation mostly, some hillshade and @2x. Replay a
#      recorded URL file instead with --trace FILE (the scheme and host of its URLs are replaced by
#      http://127.0.0.1:PORT; the paths and queries are kept).
#   4. Cold run: starts a fresh server (empty tile caches; the dictionary store under
#      target/loadtest-store is kept between runs, so only the first run ever builds it), waits for
#      /healthz, and replays the trace once, in order, one request at a time over one connection
#      (curl), like a single map client. Reports per-request latency p50/p99 and req/s, and the same
#      for the zoom-14 requests of that replay.
#   5. Warm run, on the same server: replays the trace once more (everything is then cached), then
#      runs oha for --duration seconds with --connections connections over the trace's URLs.
#   6. Cold zoom 14: a second fresh server replays only the trace's zoom-14 URLs, in order, with
#      nothing cached (every tile pays for its whole chain of levels above the base).
#   7. Reads each server's peak RSS (VmHWM in /proc/PID/status) before stopping it, and prints a
#      markdown table (run, requests, errors, req/s, p50, p99, peak RSS) with the configured cache_mb;
#      the table is also written to target/loadtest-report.md. Server logs, the trace, per-request
#      timings, oha's JSON and a /metrics snapshot are kept in target/loadtest/.
#
# Servers it starts are stopped on exit (also on errors and Ctrl-C); nothing is left running. The
# whole test takes a few minutes (the cold replays dominate; each request is capped by
# --request-timeout and each replay by --replay-timeout).
#
# Usage: scripts/loadtest.sh [options]
#   --port N             port on 127.0.0.1 the servers listen on (default 18080)
#   --duration S         seconds of the warm oha run (default 10)
#   --connections N      connections of the warm oha run (default 32)
#   --trace FILE         replay this URL file (one URL or path a line) instead of the generated trace
#   --trace-args "ARGS"  extra arguments of make_trace.py, e.g. "--landscape-zooms '' --splat-zooms ''"
#                        for elevation and hillshade only (default: its mix, landscape layers included)
#   --no-build           do not run `cargo build --release`
#   --bin PATH           server binary (default $CARGO_TARGET_DIR or target, /release/terrasynth)
#   --config FILE        server configuration (default config/default.toml)
#   --cache-mb N         TERRASYNTH_CACHE_MB for the servers (default: $TERRASYNTH_CACHE_MB, else the
#                        config's cache_mb)
#   --store-dir DIR      dictionary store reused between runs (default target/loadtest-store)
#   --no-stored-layers   remove the store's stored whole-world layers (landscape/) before every
#                        start, so that each fresh server computes them as on its very first start
#   --request-timeout S  cap of one request in the cold replays (default 60)
#   --replay-timeout S   cap of one whole replay with curl (default 600)
#   --health-timeout S   how long to wait for /healthz after a start (default 300: the first
#                        start ever builds the dictionary)
#   --during-build       after the warm run, upload the default exemplar through the admin API,
#                        start a default dictionary build (256 atoms) and repeat the warm oha run
#                        while it runs (row "warm during a dictionary build"; acceptance 6 of
#                        issue #5: its p99 should stay within 3x of the warm run's)
#   -h, --help           this help
#
# Needs bash, curl, python3 (standard library only), cargo (to build and to install oha).

set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

PORT=18080
DURATION=10
CONNECTIONS=32
TRACE_IN=""
TRACE_ARGS=""
BUILD=1
DURING_BUILD=0
ADMIN_TOKEN="loadtest-$RANDOM$RANDOM"
BIN=""
CONFIG="$ROOT/config/default.toml"
CACHE_MB="${TERRASYNTH_CACHE_MB:-}"
STORE_DIR="$ROOT/target/loadtest-store"
NO_STORED_LAYERS=""
REQUEST_TIMEOUT=60
REPLAY_TIMEOUT=600
HEALTH_TIMEOUT=300

usage() {
    # Print the header comment (from the second line to the first blank line) without the '# '.
    sed -n '2,/^$/p' "${BASH_SOURCE[0]}" | sed -e 's/^# \{0,1\}//'
}


while [[ $# -gt 0 ]]; do
    case "$1" in
        --port) need_value "$@"; PORT="$2"; shift 2 ;;
        --duration) need_value "$@"; DURATION="$2"; shift 2 ;;
        --connections) need_value "$@"; CONNECTIONS="$2"; shift 2 ;;
        --trace) need_value "$@"; TRACE_IN="$2"; shift 2 ;;
        --trace-args) need_value "$@"; TRACE_ARGS="$2"; shift 2 ;;
        --no-build) BUILD=0; shift ;;
        --during-build) DURING_BUILD=1; shift ;;
        --bin) need_value "$@"; BIN="$2"; shift 2 ;;
        --config) need_value "$@"; CONFIG="$2"; shift 2 ;;
        --cache-mb) need_value "$@"; CACHE_MB="$2"; shift 2 ;;
        --store-dir) need_value "$@"; STORE_DIR="$2"; shift 2 ;;
        --no-stored-layers) NO_STORED_LAYERS=1; shift ;;
        --request-timeout) need_value "$@"; REQUEST_TIMEOUT="$2"; shift 2 ;;
        --replay-timeout) need_value "$@"; REPLAY_TIMEOUT="$2"; shift 2 ;;
        --health-timeout) need_value "$@"; HEALTH_TIMEOUT="$2"; shift 2 ;;
        -h | --help) usage; exit 0 ;;
        *) die "unknown argument '$1' (see --help)" ;;
    esac
done

is_positive() {
    [[ "$1" =~ ^[1-9][0-9]*$ ]]
}

if ! is_positive "$PORT" || ((PORT > 65535)); then
    die "--port must be 1-65535, got '$PORT'"
fi
for v in DURATION CONNECTIONS REQUEST_TIMEOUT REPLAY_TIMEOUT HEALTH_TIMEOUT; do
    if ! is_positive "${!v}"; then
        opt="${v,,}"
        die "--${opt//_/-} must be a positive integer, got '${!v}'"
    fi
done
[[ -z "$TRACE_IN" || -r "$TRACE_IN" ]] || die "trace file '$TRACE_IN' is not readable"
[[ -r "$CONFIG" ]] || die "configuration '$CONFIG' is not readable"
if [[ -z "$CACHE_MB" ]]; then
    CACHE_MB="$(awk -F= '/^[[:space:]]*cache_mb[[:space:]]*=/ { gsub(/[[:space:]"]/, "", $2); print $2; exit }' "$CONFIG")"
    CACHE_MB="${CACHE_MB:-512}"
fi
[[ "$CACHE_MB" =~ ^[0-9]+$ ]] || die "--cache-mb must be a non-negative integer, got '$CACHE_MB'"

for tool in curl python3; do
    command -v "$tool" >/dev/null || die "'$tool' is required but not on PATH"
done

# Always loopback: the servers bind it and every request goes to it.
HOST=127.0.0.1
BASE="http://$HOST:$PORT"
WORK="$ROOT/target/loadtest"
REPORT="$ROOT/target/loadtest-report.md"
mkdir -p "$WORK" "$STORE_DIR"
STORE_DIR="$(cd "$STORE_DIR" && pwd)"
CONFIG="$(cd "$(dirname "$CONFIG")" && pwd)/$(basename "$CONFIG")"

# ---------------------------------------------------------------------------------------------
# Server processes: started in the background, stopped on exit whatever happens.

SERVER_PID=""
SERVER_RSS_KB=""

stop_server() {
    # Records the peak RSS of the running server in SERVER_RSS_KB, then stops it.
    [[ -n "$SERVER_PID" ]] || return 0
    local pid="$SERVER_PID"
    SERVER_PID=""
    SERVER_RSS_KB="$(awk '/^VmHWM:/ { print $2 }' "/proc/$pid/status" 2>/dev/null || true)"
    stop_process "$pid"
}

cleanup() {
    local rc=$?
    stop_server
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

port_in_use() {
    # curl exits 7 when nothing accepts the connection.
    local rc=0
    curl -s -o /dev/null --max-time 2 "$BASE/" || rc=$?
    [[ $rc -ne 7 ]]
}

start_server() {
    # start_server NAME: starts a fresh server (empty caches) and waits until /healthz answers 200.
    local name="$1"
    local logfile="$WORK/server-$name.log"
    port_in_use && die "something already listens on $HOST:$PORT; pick another --port"
    log "starting server '$name' on $BASE (cache_mb=$CACHE_MB, store $STORE_DIR, log $logfile)"
    [[ -n "$NO_STORED_LAYERS" ]] && rm -rf "$STORE_DIR/landscape"
    (
        cd "$ROOT"
        exec env TERRASYNTH_LISTEN="$HOST:$PORT" TERRASYNTH_CACHE_MB="$CACHE_MB" \
            TERRASYNTH_STORE_DIR="$STORE_DIR" TERRASYNTH_ADMIN_TOKEN="$ADMIN_TOKEN" \
            "$BIN" serve --config "$CONFIG" --listen "$HOST:$PORT"
    ) >"$logfile" 2>&1 &
    SERVER_PID=$!
    local start=$SECONDS
    wait_until_up "$BASE/healthz" "$SERVER_PID" "$HEALTH_TIMEOUT" "$logfile" ||
        die "server '$name' did not become healthy (log: $logfile)"
    log "server '$name' (pid $SERVER_PID) healthy after $((SECONDS - start)) s"
}

# ---------------------------------------------------------------------------------------------
# Measurements. Every result is one table row: run|requests|errors|req/s|p50 ms|p99 ms|rss.

ROWS=()

# stats FILE: FILE has lines "CODE SECONDS BYTES URL"; prints "requests errors p50_ms p99_ms"
# (nearest-rank percentiles; errors are responses other than 200, empty bodies (a raster-dem tile is
# never empty) and failed transfers).
stats() {
    local file="$1"
    local n errors
    n=$(wc -l <"$file")
    errors=$(awk '$1 != "200" || $3 == 0 { e++ } END { print e + 0 }' "$file")
    if ((n == 0)); then
        echo "0 0 - -"
        return
    fi
    awk '{ print $2 * 1000 }' "$file" | sort -g | awk -v n="$n" -v e="$errors" '
        function rank(p,   r) { r = int(p * n); if (r < p * n) r++; if (r < 1) r = 1; return r }
        { v[NR] = $1 }
        END { printf "%d %d %.1f %.1f\n", n, e, v[rank(0.50)], v[rank(0.99)] }'
}

# by_layer FILE: markdown rows "| layer | requests | first ms | p50 ms | p99 ms |" of a timings
# file, one per layer (the path segment after the world), in order of first appearance; "first"
# is the layer's first request of the replay (on a cold server, the one that pays for its levels).
by_layer() {
    local file="$1" layer ms n first
    awk '{ split($4, p, "/"); print p[6] }' "$file" | awk '!seen[$0]++' | while read -r layer; do
        ms=$(awk -v l="$layer" '{ split($4, p, "/"); if (p[6] == l) print $2 * 1000 }' "$file")
        n=$(wc -l <<<"$ms")
        first=$(head -1 <<<"$ms")
        sort -g <<<"$ms" | awk -v n="$n" -v l="$layer" -v f="$first" '
            function rank(p,   r) { r = int(p * n); if (r < p * n) r++; if (r < 1) r = 1; return r }
            { v[NR] = $1 }
            END { printf "| %s | %d | %.1f | %.1f | %.1f |\n", l, n, f, v[rank(0.50)], v[rank(0.99)] }'
    done
}

# replay NAME URLFILE: requests the URLs in order over one connection, one at a time, and writes
# "CODE SECONDS BYTES URL" lines to $WORK/NAME.timings; sets REPLAY_WALL (seconds, wall clock).
REPLAY_WALL=0
replay() {
    local name="$1" urls="$2"
    local cfg="$WORK/$name.curl" out="$WORK/$name.timings"
    local n
    n=$(wc -l <"$urls")
    awk '{ printf "url = \"%s\"\noutput = \"/dev/null\"\n", $0 }' "$urls" >"$cfg"
    log "replaying $n URLs in order, concurrency 1 ($name)"
    local t0 t1 rc=0
    t0=$(date +%s.%N)
    timeout "$REPLAY_TIMEOUT" curl -s --max-time "$REQUEST_TIMEOUT" --config "$cfg" \
        -w '%{http_code} %{time_total} %{size_download} %{url_effective}\n' >"$out" || rc=$?
    t1=$(date +%s.%N)
    REPLAY_WALL=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
    if ((rc == 124)); then
        log "warning: replay '$name' stopped after --replay-timeout ${REPLAY_TIMEOUT}s; $(wc -l <"$out") of $n requests done"
    elif ((rc != 0)); then
        log "warning: curl exited $rc during '$name' (failed requests count as errors)"
    fi
}

# add_row RUN TIMINGS WALL: adds a row from a timings file and the wall time it took.
add_row() {
    local run="$1" file="$2" wall="$3"
    local n errors p50 p99 rps
    read -r n errors p50 p99 < <(stats "$file")
    rps=$(awk -v n="$n" -v w="$wall" 'BEGIN { if (w > 0) printf "%.1f", n / w; else print "-" }')
    ROWS+=("$run|$n|$errors|$rps|$p50|$p99|RSS")
    log "$run: $n requests, $errors errors, $rps req/s, p50 $p50 ms, p99 $p99 ms"
}

# set_rss KB: fills the peak RSS of the rows added since the last call.
set_rss() {
    local kb="$1" mib i
    if [[ -n "$kb" ]]; then
        mib=$(awk -v k="$kb" 'BEGIN { printf "%.0f MiB", k / 1024 }')
    else
        mib="?"
    fi
    for i in "${!ROWS[@]}"; do
        ROWS[i]="${ROWS[i]/%|RSS/|$mib}"
    done
}

# ---------------------------------------------------------------------------------------------
# 1. oha.

if ! command -v oha >/dev/null; then
    if [[ -x "${CARGO_HOME:-$HOME/.cargo}/bin/oha" ]]; then
        PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
    else
        command -v cargo >/dev/null || die "oha is not on PATH and cargo is missing to install it"
        log "oha is not on PATH: installing it with 'cargo install oha --locked' (a few minutes, once)"
        cargo install oha --locked
        PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
        command -v oha >/dev/null || die "oha still not on PATH after cargo install"
    fi
fi
OHA_HELP="$(oha --help 2>&1 || true)"
log "using $(oha --version 2>/dev/null || echo oha) at $(command -v oha)"

# 2. Build.

if [[ -z "$BIN" ]]; then
    BIN="${CARGO_TARGET_DIR:-$ROOT/target}/release/terrasynth"
fi
if ((BUILD)); then
    log "building the release binary (cargo build --release)"
    (cd "$ROOT" && cargo build --release)
fi
[[ -x "$BIN" ]] || die "server binary '$BIN' not found (build it, or pass --bin PATH)"
log "server binary: $BIN"

# 3. Trace.

TRACE="$WORK/trace.urls"
if [[ -n "$TRACE_IN" ]]; then
    # Keep the path and query of each URL, put our loopback origin in front; skip blank lines and
    # comments.
    sed -e 's/\r$//' -e '/^[[:space:]]*$/d' -e '/^[[:space:]]*#/d' \
        -e 's#^[a-zA-Z][a-zA-Z0-9+.-]*://[^/]*##' -e 's#^\([^/]\)#/\1#' -e "s#^#$BASE#" \
        "$TRACE_IN" >"$TRACE"
    TRACE_DESC="$TRACE_IN"
else
    # shellcheck disable=SC2086 # TRACE_ARGS is a list of words on purpose.
    eval "python3 \"\$ROOT/scripts/make_trace.py\" --base-url \"\$BASE\" $TRACE_ARGS --stats" \
        >"$TRACE" 2>"$WORK/trace.stats"
    sed -e 's/^/loadtest: trace: /' "$WORK/trace.stats" >&2
    TRACE_DESC="scripts/make_trace.py $TRACE_ARGS (pan-and-zoom, z9-14, landscape layers at z10/13/14)"
fi
TRACE_N=$(wc -l <"$TRACE")
((TRACE_N > 0)) || die "the trace is empty"
TRACE_Z14="$WORK/trace-z14.urls"
grep -E '/14/[0-9]+/[0-9]+[^/]*$' "$TRACE" >"$TRACE_Z14" || true
log "trace: $TRACE_N URLs ($(wc -l <"$TRACE_Z14") at zoom 14) in $TRACE"

# 4-5. Cold then warm on one server.

start_server main
replay cold "$TRACE"
add_row "cold: trace in order, c=1" "$WORK/cold.timings" "$REPLAY_WALL"
if [[ -s "$TRACE_Z14" ]]; then
    grep -E '/14/[0-9]+/[0-9]+[^/]*$' "$WORK/cold.timings" >"$WORK/cold-z14.timings" || true
    # The wall time of the z14 subset is the sum of its request times (requests are sequential).
    wall=$(awk '{ s += $2 } END { printf "%.3f", s }' "$WORK/cold-z14.timings")
    add_row "cold: z14 requests of that replay" "$WORK/cold-z14.timings" "$wall"
fi

replay warm-replay "$TRACE"
add_row "warm: trace in order, c=1" "$WORK/warm-replay.timings" "$REPLAY_WALL"

oha_stats() {
    # oha_stats FILE: "requests errors req/s p50 p99" of an oha JSON report.
    python3 - "$1" <<'EOF'
import json, sys

with open(sys.argv[1]) as f:
    r = json.load(f)
codes = r.get("statusCodeDistribution") or {}
n = sum(int(v) for v in codes.values())
ok = int(codes.get("200", 0))
errors = sum(int(v) for v in (r.get("errorDistribution") or {}).values())
pct = r.get("latencyPercentiles") or {}


def ms(key):
    v = pct.get(key)
    return "-" if v is None else "%.1f" % (float(v) * 1000.0)


print(n + errors, n - ok + errors, "%.1f" % float(r["summary"]["requestsPerSec"]), ms("p50"), ms("p99"))
EOF
}

OHA_JSON="$WORK/warm-oha.json"
oha_args=(-z "${DURATION}s" -c "$CONNECTIONS")
# Requests in flight at the deadline are waited for, not counted as errors.
if grep -q -- '--wait-ongoing-requests-after-deadline' <<<"$OHA_HELP"; then
    oha_args+=(-w)
fi
if grep -q -- '--no-tui' <<<"$OHA_HELP"; then
    oha_args+=(--no-tui)
fi
if grep -q -- '--output-format' <<<"$OHA_HELP"; then
    oha_args+=(--output-format json)
else
    oha_args+=(-j)
fi
if grep -q -- '--urls-from-file' <<<"$OHA_HELP"; then
    # A flag: the URL argument is then the file.
    oha_args+=(--urls-from-file "$TRACE")
    oha_desc="all $TRACE_N trace URLs"
else
    # Older oha takes one URL: use the middle URL of the trace.
    one_url=$(sed -n "$(((TRACE_N + 1) / 2))p" "$TRACE")
    oha_args+=("$one_url")
    oha_desc="one URL ($one_url): this oha has no --urls-from-file"
fi
log "warm load: oha ${oha_args[*]}"
oha_rc=0
timeout $((DURATION + 60)) oha "${oha_args[@]}" >"$OHA_JSON" 2>"$WORK/warm-oha.stderr" </dev/null || oha_rc=$?
((oha_rc == 0)) || { cat "$WORK/warm-oha.stderr" >&2; die "oha failed (exit $oha_rc)"; }
read -r oha_n oha_err oha_rps oha_p50 oha_p99 < <(oha_stats "$OHA_JSON")
ROWS+=("warm: oha ${DURATION}s, c=$CONNECTIONS|$oha_n|$oha_err|$oha_rps|$oha_p50|$oha_p99|RSS")
log "warm oha: $oha_n requests, $oha_err errors, $oha_rps req/s, p50 $oha_p50 ms, p99 $oha_p99 ms ($oha_desc)"

if ((DURING_BUILD)); then
    AUTH="Authorization: Bearer $ADMIN_TOKEN"
    log "during-build: uploading the default exemplar and starting a default dictionary build"
    ex_json=$(curl -fsS -H "$AUTH" -H 'Content-Type: image/tiff' \
        --data-binary @"$ROOT/config/data/tienshan_west_gebco15s.tif" \
        "$BASE/admin/exemplars?name=loadtest-exemplar") || die "exemplar upload failed"
    ex_id=$(python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])' <<<"$ex_json")
    job_json=$(curl -fsS -H "$AUTH" -H 'Content-Type: application/json' "$BASE/admin/dictionaries" \
        -d "{\"name\": \"loadtest-build\", \"exemplars\": [\"$ex_id\"], \"seed\": $RANDOM}") \
        || die "dictionary build request failed"
    job_id=$(python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])' <<<"$job_json")
    job_state() {
        curl -fsS -H "$AUTH" "$BASE/admin/jobs/$job_id" |
            python3 -c 'import json,sys; j=json.load(sys.stdin); print(j["state"], j["progress"])'
    }
    until [[ "$(job_state)" != queued* ]]; do sleep 0.2; done
    OHA_BUILD_JSON="$WORK/warm-build-oha.json"
    log "during-build: job $job_id running; warm load again: oha ${oha_args[*]}"
    oha_rc=0
    timeout $((DURATION + 60)) oha "${oha_args[@]}" >"$OHA_BUILD_JSON" 2>"$WORK/warm-build-oha.stderr" </dev/null || oha_rc=$?
    ((oha_rc == 0)) || { cat "$WORK/warm-build-oha.stderr" >&2; die "oha failed (exit $oha_rc)"; }
    read -r state_after progress_after < <(job_state)
    read -r b_n b_err b_rps b_p50 b_p99 < <(oha_stats "$OHA_BUILD_JSON")
    ROWS+=("warm during a dictionary build: oha ${DURATION}s, c=$CONNECTIONS|$b_n|$b_err|$b_rps|$b_p50|$b_p99|RSS")
    log "during-build oha: $b_n requests, $b_err errors, $b_rps req/s, p50 $b_p50 ms, p99 $b_p99 ms (job $state_after at progress $progress_after after the run; p99 without a build: $oha_p99 ms)"
    curl -fsS -X DELETE -H "$AUTH" "$BASE/admin/jobs/$job_id" >/dev/null 2>&1 || true
fi

curl -s --max-time 5 "$BASE/metrics" >"$WORK/metrics-main.txt" || log "warning: could not read /metrics"
stop_server
MAIN_RSS_KB="$SERVER_RSS_KB"
set_rss "$MAIN_RSS_KB"

# 6. Cold zoom 14 alone on a fresh server.

if [[ -s "$TRACE_Z14" ]]; then
    start_server z14
    replay cold-z14-only "$TRACE_Z14"
    add_row "cold: z14 URLs only, fresh server, c=1" "$WORK/cold-z14-only.timings" "$REPLAY_WALL"
    stop_server
    set_rss "$SERVER_RSS_KB"
else
    log "no zoom-14 URLs in the trace: skipping the cold z14 run"
fi

# 7. Report.

commit="$(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)"
if [[ -n "$(git -C "$ROOT" status --porcelain --untracked-files=no 2>/dev/null)" ]]; then
    commit="$commit (with local changes)"
fi
{
    echo "# terrasynth load test"
    echo
    echo "- date: $(date -u '+%Y-%m-%d %H:%M:%S UTC'); commit $commit; $(nproc) CPUs; $(oha --version 2>/dev/null || echo oha)"
    echo "- server: \`$BIN\`, cache_mb=$CACHE_MB, listening on $HOST:$PORT"
    echo "- trace: $TRACE_DESC, $TRACE_N URLs, $(wc -l <"$TRACE_Z14") at zoom 14"
    if [[ -n "$NO_STORED_LAYERS" ]]; then
        echo "- cold = freshly started server (empty tile caches; dictionary store reused from \`$STORE_DIR\`,"
        echo "  its stored whole-world layers removed before each start: each server computes them);"
    else
        echo "- cold = freshly started server (empty tile caches; dictionary store reused from \`$STORE_DIR\`,"
        echo "  with the whole-world layers an earlier start of this build stored, if any);"
    fi
    echo "  c=1 = one request at a time over one connection (curl); warm oha: $oha_desc"
    echo "- peak RSS = VmHWM of the server process of that run (the first four rows share one server)"
    echo
    echo "| run | requests | errors | req/s | p50 ms | p99 ms | peak RSS |"
    echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"
    for row in "${ROWS[@]}"; do
        echo "| ${row//|/ | } |"
    done
    for run in cold cold-z14-only; do
        [[ -s "$WORK/$run.timings" ]] || continue
        echo
        echo "By layer, $run (first = the layer's first request of the replay):"
        echo
        echo "| layer | requests | first ms | p50 ms | p99 ms |"
        echo "| --- | ---: | ---: | ---: | ---: |"
        by_layer "$WORK/$run.timings"
    done
} >"$REPORT"
echo
cat "$REPORT"
echo
log "report written to $REPORT; details in $WORK/"
