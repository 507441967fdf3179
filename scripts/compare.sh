#!/usr/bin/env bash
# Warm-path comparison: terrasynth against nginx serving the very same tile bytes from files and
# martin serving them from an MBTiles file, on this machine, over loopback (issue #13).
#
# What it does, in order:
#   1. Makes sure the tools are there, installing what is missing (and saying so): oha
#      (`cargo install oha --locked`), Debian's nginx (`apt-get install nginx-light`, or nginx) and
#      martin 1.14.0 (`cargo install martin --version 1.14.0 --locked --no-default-features
#      --features mbtiles,pmtiles`: newer releases need a newer rustc than this machine's).
#   2. Builds the release binary (skip with --no-build).
#   3. Writes the warm trace: scripts/make_trace.py's pan-and-zoom over the Talas range, elevation
#      tiles of zooms 9-14 only (the same URLs the load test's elevation-only run uses).
#   4. Starts terrasynth on the default world and fetches every trace tile once (this warms its
#      cache), writing the bytes to target/compare/tiles/<same path> and into
#      target/compare/elevation.mbtiles (MBTiles 1.3, TMS rows) with Python's sqlite3.
#   5. Starts nginx (root = that directory, sendfile, access log off, long keep-alive) and martin
#      (the MBTiles file; URLs /elevation/{z}/{x}/{y}), checks that a sample of tiles is
#      byte-identical from all three, then runs `oha -z DURATION -c CONNECTIONS --urls-from-file`
#      against terrasynth, nginx and martin in turn, --rounds times (alternating, so that whatever
#      else the machine does falls on all three alike).
#   6. Prints a markdown table (server, round, req/s, p50, p99, errors) and the ratios of the median
#      req/s (terrasynth / nginx, terrasynth / martin); writes it to target/compare-report.md.
#
# Not part of CI: it is a measurement. Servers it starts are stopped on exit.
#
# Usage: scripts/compare.sh [options]
#   --port N          first of three loopback ports (default 18180: terrasynth N, nginx N+1,
#                     martin N+2)
#   --duration S      seconds of each oha run (default 8)
#   --connections N   connections of each oha run (default 32)
#   --rounds N        rounds of the three runs (default 3)
#   --no-build        do not run `cargo build --release`
#   --bin PATH        terrasynth binary (default target/release/terrasynth)
#   --store-dir DIR   dictionary store reused between runs (default target/loadtest-store)
#   -h, --help        this help

set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PORT=18180
DURATION=8
CONNECTIONS=32
ROUNDS=3
BUILD=1
BIN=""
STORE_DIR="$ROOT/target/loadtest-store"

usage() {
    sed -n '2,/^$/p' "${BASH_SOURCE[0]}" | sed -e 's/^# \{0,1\}//'
}

while [[ $# -gt 0 ]]; do
    case "$1" in
        --port) need_value "$@"; PORT="$2"; shift 2 ;;
        --duration) need_value "$@"; DURATION="$2"; shift 2 ;;
        --connections) need_value "$@"; CONNECTIONS="$2"; shift 2 ;;
        --rounds) need_value "$@"; ROUNDS="$2"; shift 2 ;;
        --no-build) BUILD=0; shift ;;
        --bin) need_value "$@"; BIN="$2"; shift 2 ;;
        --store-dir) need_value "$@"; STORE_DIR="$2"; shift 2 ;;
        -h | --help) usage; exit 0 ;;
        *) die "unknown argument '$1' (see --help)" ;;
    esac
done
for v in PORT DURATION CONNECTIONS ROUNDS; do
    [[ "${!v}" =~ ^[1-9][0-9]*$ ]] || die "--${v,,} must be a positive integer, got '${!v}'"
done
((PORT + 2 <= 65535)) || die "--port must leave room for three ports below 65536"

CARGO_BIN="${CARGO_HOME:-$HOME/.cargo}/bin"
PATH="$CARGO_BIN:$PATH"
HOST=127.0.0.1
TS_PORT=$PORT
NGINX_PORT=$((PORT + 1))
MARTIN_PORT=$((PORT + 2))
WORK="$ROOT/target/compare"
REPORT="$ROOT/target/compare-report.md"
rm -rf "$WORK"
mkdir -p "$WORK/tiles" "$WORK/nginx" "$STORE_DIR"

# 1. Tools.
if ! command -v oha >/dev/null; then
    log "oha is missing: cargo install oha --locked"
    cargo install oha --locked
fi
NGINX="$(command -v nginx || true)"
[[ -z "$NGINX" && -x /usr/sbin/nginx ]] && NGINX=/usr/sbin/nginx
if [[ -z "$NGINX" ]]; then
    log "nginx is missing: apt-get install nginx-light (Debian)"
    SUDO=""
    [[ $(id -u) -eq 0 ]] || SUDO=sudo
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq nginx-light >/dev/null 2>&1 ||
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq nginx >/dev/null
    NGINX=/usr/sbin/nginx
fi
[[ -x "$NGINX" ]] || die "nginx not found after installing it"
if ! command -v martin >/dev/null; then
    log "martin is missing: cargo install martin 1.14.0 (mbtiles, pmtiles; several minutes, once)"
    cargo install martin --version 1.14.0 --locked --no-default-features --features mbtiles,pmtiles
fi
log "tools: $(oha --version), $("$NGINX" -v 2>&1), $(martin --version)"

# 2. Build.
[[ -n "$BIN" ]] || BIN="${CARGO_TARGET_DIR:-$ROOT/target}/release/terrasynth"
if ((BUILD)); then
    (cd "$ROOT" && cargo build --release)
fi
[[ -x "$BIN" ]] || die "terrasynth binary '$BIN' not found (build it, or pass --bin)"

# 3. Trace (paths only).
python3 "$ROOT/scripts/make_trace.py" --base-url '' --hillshade-zooms '' --retina-zooms '' \
    --landscape-zooms '' --splat-zooms '' >"$WORK/paths"
N=$(wc -l <"$WORK/paths")
((N > 0)) || die "the trace is empty"

PIDS=()
cleanup() {
    local rc=$? p
    for p in "${PIDS[@]}"; do
        kill -TERM "$p" 2>/dev/null || true
    done
    for p in "${PIDS[@]}"; do
        wait "$p" 2>/dev/null || true
    done
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

wait_http() {
    # wait_http URL PID NAME LOG: until URL answers (any HTTP status); dies if the process exits
    # first or 300 s pass.
    wait_until_up "$1" "$2" 300 "$4" any || die "$3 did not start (logs in $WORK)"
}

# 4. terrasynth, export of the trace's bytes.
(
    cd "$ROOT"
    exec env TERRASYNTH_STORE_DIR="$STORE_DIR" "$BIN" serve --config "$ROOT/config/default.toml" \
        --listen "$HOST:$TS_PORT"
) >"$WORK/terrasynth.log" 2>&1 &
PIDS+=($!)
wait_http "http://$HOST:$TS_PORT/healthz" "${PIDS[0]}" terrasynth "$WORK/terrasynth.log"
log "fetching the $N trace tiles from terrasynth into $WORK/tiles"
awk -v b="http://$HOST:$TS_PORT" -v d="$WORK/tiles" \
    '{ printf "url = \"%s%s\"\noutput = \"%s%s\"\n", b, $0, d, $0 }' "$WORK/paths" >"$WORK/fetch.curl"
curl -sf --create-dirs --config "$WORK/fetch.curl" || die "fetching the trace tiles failed"
python3 - "$WORK/tiles" "$WORK/paths" "$WORK/elevation.mbtiles" <<'EOF'
import os, sqlite3, sys

root, paths, out = sys.argv[1:4]
db = sqlite3.connect(out)
db.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
db.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB)")
db.execute("CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row)")
zooms = []
for line in open(paths):
    p = line.strip()
    z, x, y = p.split("/")[-3:]
    z, x, y = int(z), int(x), int(y.split(".")[0])
    zooms.append(z)
    data = open(root + p, "rb").read()
    db.execute("INSERT OR REPLACE INTO tiles VALUES (?, ?, ?, ?)", (z, x, (1 << z) - 1 - y, data))
meta = {
    "name": "elevation", "format": "png", "type": "overlay", "version": "1",
    "minzoom": str(min(zooms)), "maxzoom": str(max(zooms)),
    "bounds": "71.0,41.5,76.0,43.5", "center": "73.5,42.5,9",
    "description": "terrasynth trace tiles (terrarium)",
}
db.executemany("INSERT INTO metadata VALUES (?, ?)", meta.items())
db.commit()
EOF

# 5. nginx and martin on the same bytes.
cat >"$WORK/nginx/nginx.conf" <<EOF
worker_processes auto;
daemon off;
pid $WORK/nginx/nginx.pid;
error_log $WORK/nginx/error.log warn;
$( [[ $(id -u) -eq 0 ]] && echo "user root;" )
events { worker_connections 4096; }
http {
    access_log off;
    sendfile on;
    tcp_nopush on;
    keepalive_requests 1000000;
    types { image/png png; }
    client_body_temp_path $WORK/nginx/body;
    proxy_temp_path $WORK/nginx/proxy;
    fastcgi_temp_path $WORK/nginx/fastcgi;
    uwsgi_temp_path $WORK/nginx/uwsgi;
    scgi_temp_path $WORK/nginx/scgi;
    server {
        listen $HOST:$NGINX_PORT;
        root $WORK/tiles;
    }
}
EOF
"$NGINX" -p "$WORK/nginx" -c "$WORK/nginx/nginx.conf" >"$WORK/nginx/stdout.log" 2>&1 &
PIDS+=($!)
wait_http "http://$HOST:$NGINX_PORT/" "${PIDS[1]}" nginx "$WORK/nginx/error.log"
martin --listen-addresses "$HOST:$MARTIN_PORT" "$WORK/elevation.mbtiles" >"$WORK/martin.log" 2>&1 &
PIDS+=($!)
wait_http "http://$HOST:$MARTIN_PORT/health" "${PIDS[2]}" martin "$WORK/martin.log"

sed -e "s#^#http://$HOST:$TS_PORT#" "$WORK/paths" >"$WORK/terrasynth.urls"
sed -e "s#^#http://$HOST:$NGINX_PORT#" "$WORK/paths" >"$WORK/nginx.urls"
sed -e 's#^/tiles/[^/]*/elevation/\([0-9]*\)/\([0-9]*\)/\([0-9]*\)\.png$#\1/\2/\3#' \
    -e "s#^#http://$HOST:$MARTIN_PORT/elevation/#" "$WORK/paths" >"$WORK/martin.urls"

for k in 1 $(((N + 1) / 2)) "$N"; do
    a=$(sed -n "${k}p" "$WORK/terrasynth.urls" | xargs curl -sf | sha256sum)
    b=$(sed -n "${k}p" "$WORK/nginx.urls" | xargs curl -sf | sha256sum)
    c=$(sed -n "${k}p" "$WORK/martin.urls" | xargs curl -sf | sha256sum)
    [[ "$a" == "$b" && "$a" == "$c" ]] || die "tile $k differs between the servers"
done
log "sample tiles byte-identical from terrasynth, nginx and martin"

oha_stats() {
    python3 - "$1" <<'EOF'
import json, sys

r = json.load(open(sys.argv[1]))
codes = r.get("statusCodeDistribution") or {}
n = sum(int(v) for v in codes.values())
errors = n - int(codes.get("200", 0)) + sum(int(v) for v in (r.get("errorDistribution") or {}).values())
pct = r.get("latencyPercentiles") or {}
print("%.0f %.2f %.2f %d" % (float(r["summary"]["requestsPerSec"]), float(pct["p50"]) * 1e3,
                             float(pct["p99"]) * 1e3, errors))
EOF
}

ROWS=()
for ((r = 1; r <= ROUNDS; r++)); do
    for s in terrasynth nginx martin; do
        json="$WORK/oha-$s-$r.json"
        oha -z "${DURATION}s" -c "$CONNECTIONS" -w --no-tui --output-format json \
            --urls-from-file "$WORK/$s.urls" >"$json" 2>"$WORK/oha-$s-$r.stderr" </dev/null ||
            die "oha against $s failed (see $WORK/oha-$s-$r.stderr)"
        read -r rps p50 p99 err < <(oha_stats "$json")
        ROWS+=("$s|$r|$rps|$p50|$p99|$err")
        log "round $r $s: $rps req/s, p50 $p50 ms, p99 $p99 ms, $err errors"
    done
done

{
    echo "Warm comparison on $(nproc) cores: $N elevation tile URLs (zooms 9-14, mean body" \
        "$(( $(du -sb "$WORK/tiles" | cut -f1) / N / 1024 )) KiB), oha ${DURATION}s at" \
        "$CONNECTIONS connections, $ROUNDS alternating rounds ($(date -u +%Y-%m-%d))."
    echo
    echo "| server | round | req/s | p50 ms | p99 ms | errors |"
    echo "| --- | ---: | ---: | ---: | ---: | ---: |"
    for row in "${ROWS[@]}"; do
        echo "| ${row//|/ | } |"
    done
    echo
    printf '%s\n' "${ROWS[@]}" | python3 -c '
import statistics, sys
by = {}
for line in sys.stdin:
    s, _, rps, *_ = line.strip().split("|")
    by.setdefault(s, []).append(float(rps))
med = {s: statistics.median(v) for s, v in by.items()}
print("Median req/s: " + ", ".join("%s %.0f" % (s, med[s]) for s in med) + ".")
print("terrasynth / nginx = %.2f; terrasynth / martin = %.2f." % (
    med["terrasynth"] / med["nginx"], med["terrasynth"] / med["martin"]))
'
} | tee "$REPORT"
log "report written to $REPORT"
