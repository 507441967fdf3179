#!/usr/bin/env bash
# First tiles of a fresh server, timed one request at a time with curl (a measurement, not in CI).
#
# Starts the given binary on the default world with empty tile caches (the dictionary store is
# reused, so start-up does not rebuild it), then:
#   landscape: the first colour tile at zoom 10 (it waits for the whole-world layers), a
#              neighbour, the first zoom-14 colour tile and a neighbour, the first zoom-14
#              instance tile, four neighbours, and one 40 tiles away (a fresh chain);
#   elevation: (a second fresh server, started --settle seconds before) one never-visited zoom-14
#              elevation tile, then its 35 neighbours back to back: the first's time and the
#              neighbours' p50 / p90 / max;
#   level:     (a third fresh server, the same settle) every other zoom-14 tile of a 17 x 11 block
#              of another area first, so that the parents are cached, then the 28 tiles in between
#              one at a time: their p50 / p90 and the server's CPU time per tile (from
#              /proc/PID/stat, Linux), the cost of one amplified level and its PNG.
# Compare two builds by running it on each, alternating.
#
# Usage: scripts/first_tiles.sh [--bin PATH] [--store-dir DIR] [--port N] [--settle S]
#                               [--no-stored-layers]
#   --bin PATH        server binary (default target/release/terrasynth)
#   --store-dir DIR   dictionary store reused between runs (default target/first-tiles-store)
#   --no-stored-layers  remove the store's stored whole-world layers before every start (each
#                     server computes them, as on its very first start; without it a server reads
#                     those an earlier start of the same build stored)
#   --port N          port on 127.0.0.1 (default 18095)
#   --settle S        seconds between start and the elevation part's first request (default 8)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN="$ROOT/target/release/terrasynth"
STORE_DIR="$ROOT/target/first-tiles-store"
NO_STORED_LAYERS=""
PORT=18095
SETTLE=8

while [[ $# -gt 0 ]]; do
    case "$1" in
        --bin) need_value "$@"; BIN="$2"; shift 2 ;;
        --store-dir) need_value "$@"; STORE_DIR="$2"; shift 2 ;;
        --no-stored-layers) NO_STORED_LAYERS=1; shift ;;
        --port) need_value "$@"; PORT="$2"; shift 2 ;;
        --settle) need_value "$@"; SETTLE="$2"; shift 2 ;;
        -h|--help) sed -n '2,26p' "$0"; exit 0 ;;
        *) die "unknown argument '$1' (see --help)" ;;
    esac
done
[[ -x "$BIN" ]] || die "no executable at $BIN (cargo build --release, or --bin)"
[[ "$PORT" =~ ^[0-9]+$ && "$PORT" -ge 1 && "$PORT" -le 65535 ]] || die "--port must be 1-65535"
[[ "$SETTLE" =~ ^[0-9]+$ ]] || die "--settle must be whole seconds"
command -v curl >/dev/null || die "curl is needed"
mkdir -p "$STORE_DIR"

S="http://127.0.0.1:$PORT"
LOG="$(mktemp)"
SERVER_PID=""
stop_server() {
    if [[ -n "$SERVER_PID" ]]; then
        stop_process "$SERVER_PID"
        SERVER_PID=""
    fi
}
trap 'stop_server; rm -f "$LOG"' EXIT

start_server() {
    if curl -s -o /dev/null --max-time 2 "$S/"; then
        die "something already listens on $S; pick another --port"
    fi
    [[ -n "$NO_STORED_LAYERS" ]] && rm -rf "$STORE_DIR/landscape"
    (cd "$ROOT" && exec env TERRASYNTH_STORE_DIR="$STORE_DIR" TERRASYNTH_CACHE_MB=512 \
        "$BIN" serve --listen "127.0.0.1:$PORT") >"$LOG" 2>&1 &
    SERVER_PID=$!
    wait_until_up "$S/healthz" "$SERVER_PID" 300 "$LOG" || die "the server did not become healthy"
}

# timed LABEL PATH: one request, its status and seconds.
timed() { curl -s -o /dev/null -w "$1 %{http_code} %{time_total}\n" "$S$2"; }

X=11590 Y=6050 # zoom 14 over the Kyrgyz Ala-Too
echo "# landscape: first tiles of a fresh server (seconds)"
start_server
timed color-z10-first "/tiles/tienshan/color/10/$((X / 16))/$((Y / 16)).png"
timed color-z10-next "/tiles/tienshan/color/10/$((X / 16 + 1))/$((Y / 16)).png"
timed color-z14-first "/tiles/tienshan/color/14/$X/$Y.png"
timed color-z14-next "/tiles/tienshan/color/14/$((X + 1))/$Y.png"
timed instances-z14-first "/tiles/tienshan/instances/14/$X/$Y.mvt"
for i in 1 2 3 4; do
    timed "instances-z14-next$i" "/tiles/tienshan/instances/14/$((X + i))/$Y.mvt"
done
timed instances-z14-far "/tiles/tienshan/instances/14/$((X + 40))/$((Y + 20)).mvt"
stop_server

echo "# elevation: a never-visited zoom-14 area, $SETTLE s after start (ms)"
start_server
sleep "$SETTLE"
X=11600 Y=6060
curl -s -o /dev/null -w "first %{time_total}\n" "$S/tiles/tienshan/elevation/14/$X/$Y.png" |
    awk '{ printf "first %.1f\n", $2 * 1000 }'
for dy in 0 1 2 3 4; do
    for dx in 1 2 3 4 5 6 7; do
        curl -s -o /dev/null -w "%{time_total}\n" \
            "$S/tiles/tienshan/elevation/14/$((X + dx))/$((Y + dy)).png"
    done
done | sort -g | awk '{ v[NR] = $1 * 1000 }
    END { printf "neighbours n %d p50 %.1f p90 %.1f max %.1f\n", NR, v[int((NR + 1) / 2)],
          v[int(0.9 * NR)], v[NR] }'
stop_server

echo "# level: zoom-14 tiles whose parents are cached, $SETTLE s after start (ms)"
start_server
sleep "$SETTLE"
X=11630 Y=6074
for dy in -2 0 2 4 6 8; do
    for dx in -2 0 2 4 6 8 10 12 14; do
        curl -s -o /dev/null "$S/tiles/tienshan/elevation/14/$((X + dx))/$((Y + dy)).png"
    done
done
sleep 4
cpu_ticks() { awk '{ print $14 + $15 }' "/proc/$SERVER_PID/stat"; }
TICKS=$(getconf CLK_TCK)
C0=$(cpu_ticks)
TIMES=$(for dy in 1 3 5 7; do
    for dx in 1 3 5 7 9 11 13; do
        curl -s -o /dev/null -w "%{time_total}\n" \
            "$S/tiles/tienshan/elevation/14/$((X + dx))/$((Y + dy)).png"
    done
done)
C1=$(cpu_ticks)
echo "$TIMES" | sort -g | awk -v cpu="$(((C1 - C0) * 1000 / TICKS))" '{ v[NR] = $1 * 1000 }
    END { printf "level n %d cpu/tile %.1f p50 %.1f p90 %.1f\n", NR, cpu / NR,
          v[int((NR + 1) / 2)], v[int(0.9 * NR)] }'
