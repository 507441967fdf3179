#!/usr/bin/env bash
# Two terrasynth replicas behind nginx on this machine, without docker: what docker/compose.yml
# runs, checked.
#
#   1. Installs Debian's nginx with apt-get if `nginx` is missing (as root, or with sudo), and
#      finds oha (~/.cargo/bin/oha, else `cargo install oha --locked`, as scripts/loadtest.sh).
#   2. Starts replica 1 (`terrasynth serve` on a loopback port, the default world, an admin
#      token, store in a temporary directory) and, once it is healthy (its first start builds
#      the default dictionary into the store), replica 2 on another port with the same
#      TERRASYNTH_STORE_DIR; then nginx on a third port with docker/nginx/terrasynth.conf.template
#      (proxy_cache with proxy_cache_lock, stale-on-error, proxy_next_upstream for failover).
#   3. Checks, failing on the first miss:
#      a. a world created through the admin API of replica 1 (a crop of the default exemplar as
#         base, the default world's dictionary) is served by replica 2 within 5 s, no restart;
#      b. tiles (several layers and zooms, and the new world's) are byte-identical from replica
#         1, replica 2 and nginx (a miss, then a hit);
#      c. an oha run through nginx over --duration seconds, replica 1 killed (SIGKILL) a third of
#         the way in, answers every request with 2xx (0 other statuses, 0 errors).
#   4. Prints the oha figures (requests, req/s through nginx) and nginx's cache hit ratio over
#      that run (from $upstream_cache_status in its access log).
#
# Usage: scripts/replicas_test.sh [--bin PATH] [--store DIR] [--duration S] [--connections N] [--keep]
#   --bin PATH        terrasynth binary (default: cargo build --release, target/release/terrasynth)
#   --store DIR       the replicas' store (default: a fresh one in the work directory; an existing
#                     store with the default dictionary skips its build)
#   --duration S      seconds of the oha run (default 15)
#   --connections N   oha connections (default 16)
#   --keep            keep the work directory (logs, store, nginx cache)
#
# Needs bash, curl, python3 (standard library), cargo (to build), apt-get (for nginx). Not in
# .ci/run: the first start builds the default dictionary, and the whole run takes minutes.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN=""
STORE=""
DURATION=15
CONNECTIONS=16
KEEP=0
while (($#)); do
    case "$1" in
        --bin) BIN="$2"; shift ;;
        --store) STORE="$2"; shift ;;
        --duration) DURATION="$2"; shift ;;
        --connections) CONNECTIONS="$2"; shift ;;
        --keep) KEEP=1 ;;
        -h | --help) sed -n '2,/^set -e/p' "${BASH_SOURCE[0]}" | sed -e '$d' -e 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "replicas_test: unknown option $1" >&2; exit 2 ;;
    esac
    shift
done

# 1. Tools.
if ! command -v nginx >/dev/null && [[ ! -x /usr/sbin/nginx ]]; then
    SUDO=""
    [[ "$(id -u)" -eq 0 ]] || SUDO="sudo"
    log "installing Debian's nginx with apt-get"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq nginx-light >/dev/null 2>&1 ||
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq nginx >/dev/null
fi
NGINX="$(command -v nginx || echo /usr/sbin/nginx)"
if ! command -v oha >/dev/null; then
    if [[ -x "${CARGO_HOME:-$HOME/.cargo}/bin/oha" ]]; then
        PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
    else
        log "oha is not on PATH: installing it with 'cargo install oha --locked' (a few minutes, once)"
        cargo install oha --locked
        PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
    fi
fi
command -v oha >/dev/null || die "oha is not available"
if [[ -z "$BIN" ]]; then
    (cd "$ROOT" && cargo build --release --quiet --bin terrasynth)
    BIN="$ROOT/target/release/terrasynth"
fi
[[ -x "$BIN" ]] || die "no binary at $BIN"

WORK="$(mktemp -d /tmp/terrasynth-replicas.XXXXXX)"
chmod 755 "$WORK"
PIDS=()
cleanup() {
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
    [[ -f "$WORK/nginx/nginx.pid" ]] && kill "$(cat "$WORK/nginx/nginx.pid")" 2>/dev/null || true
    if ((KEEP)); then log "work directory kept: $WORK"; else rm -rf "$WORK"; fi
}
trap cleanup EXIT

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
P1=$(free_port); P2=$(free_port); P3=$(free_port)
while [[ "$P2" == "$P1" ]]; do P2=$(free_port); done
while [[ "$P3" == "$P1" || "$P3" == "$P2" ]]; do P3=$(free_port); done
R1="http://127.0.0.1:$P1"; R2="http://127.0.0.1:$P2"; NX="http://127.0.0.1:$P3"
TOKEN="replicas-test-token"
[[ -n "$STORE" ]] || STORE="$WORK/store"
NEW="replica-made-$$"

# 2. Replicas and nginx.
start_replica() {
    # start_replica PORT LOG: a replica on PORT sharing $STORE; its pid in PIDS.
    (cd "$ROOT" && TERRASYNTH_STORE_DIR="$STORE" TERRASYNTH_ADMIN_TOKEN="$TOKEN" \
        TERRASYNTH_CACHE_MB=512 exec "$BIN" serve --listen "127.0.0.1:$1") >"$2" 2>&1 &
    PIDS+=($!)
}
wait_healthy() {
    # wait_healthy URL PID LOG: until URL/healthz answers 200 (up to 900 s: the first start may
    # build the default dictionary); dies if the process exits first.
    wait_until_up "$1/healthz" "$2" 900 "$3" || die "$1 did not become healthy"
}
log "replica 1 on $R1 (store $STORE)"
start_replica "$P1" "$WORK/replica1.log"
R1_PID=${PIDS[-1]}
wait_healthy "$R1" "$R1_PID" "$WORK/replica1.log"
log "replica 2 on $R2 (same store)"
start_replica "$P2" "$WORK/replica2.log"
wait_healthy "$R2" "${PIDS[-1]}" "$WORK/replica2.log"

mkdir -p "$WORK/nginx/cache" "$WORK/nginx/tmp"
chmod -R 777 "$WORK/nginx"
sed -e "s|\${UPSTREAM_1}|127.0.0.1:$P1|" -e "s|\${UPSTREAM_2}|127.0.0.1:$P2|" \
    -e "s|\${LISTEN}|127.0.0.1:$P3|" -e "s|\${CACHE_DIR}|$WORK/nginx/cache|" \
    -e "s|\${ACCESS_LOG}|$WORK/nginx/access.log|" \
    "$ROOT/docker/nginx/terrasynth.conf.template" >"$WORK/nginx/terrasynth.conf"
cat >"$WORK/nginx/nginx.conf" <<EOF
worker_processes 2;
pid $WORK/nginx/nginx.pid;
error_log $WORK/nginx/error.log warn;
events { worker_connections 1024; }
http {
    client_body_temp_path $WORK/nginx/tmp/body;
    proxy_temp_path $WORK/nginx/tmp/proxy;
    fastcgi_temp_path $WORK/nginx/tmp/fastcgi;
    uwsgi_temp_path $WORK/nginx/tmp/uwsgi;
    scgi_temp_path $WORK/nginx/tmp/scgi;
    include $WORK/nginx/terrasynth.conf;
}
EOF
"$NGINX" -e "$WORK/nginx/error.log" -t -q -p "$WORK/nginx" -c "$WORK/nginx/nginx.conf" || die "nginx refuses the configuration"
"$NGINX" -e "$WORK/nginx/error.log" -p "$WORK/nginx" -c "$WORK/nginx/nginx.conf"
# nginx daemonises: its master's pid is in its pid file.
wait_healthy "$NX" "$(cat "$WORK/nginx/nginx.pid")" "$WORK/nginx/error.log"
log "nginx on $NX in front of both"

# 3a. A world created on replica 1 is served by replica 2.
"$BIN" crop --input "$ROOT/config/data/tienshan_west_gebco15s.tif" --window 1700,700,256,256 \
    --down 4 --output "$WORK/base.tif" >/dev/null 2>&1 || die "crop failed"
AUTH="Authorization: Bearer $TOKEN"
base=$(curl -fsS -H "$AUTH" -H 'Content-Type: image/tiff' --data-binary @"$WORK/base.tif" \
    "$R1/admin/exemplars?name=replica-base" | python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])')
dict=$(curl -fsS "$R1/worlds/tienshan" | python3 -c 'import json,sys; print(json.load(sys.stdin)["dictionaries"][0])')
[[ "$(curl -s -o /dev/null -w '%{http_code}' "$R2/worlds/$NEW")" == 404 ]] ||
    die "replica 2 serves $NEW before it exists"
curl -fsS -H "$AUTH" -H 'Content-Type: application/json' "$R1/admin/worlds" \
    -d "{\"name\": \"$NEW\", \"base\": \"$base\", \"dictionaries\": [\"$dict\"], \"max_zoom\": 12}" \
    >"$WORK/created.json" || die "world creation on replica 1 failed"
created=$(date +%s.%N)
until [[ "$(curl -s -o "$WORK/r2-world.json" -w '%{http_code}' "$R2/worlds/$NEW")" == 200 ]]; do
    python3 -c "import sys,time; sys.exit(time.time() - $created > 5)" || die "replica 2 did not serve the new world within 5 s"
    sleep 0.1
done
PICKUP=$(python3 -c "import time; print('%.2f' % (time.time() - $created))")
log "(a) replica 2 serves the world created on replica 1 after ${PICKUP} s"
new_tile=$(python3 - "$WORK/r2-world.json" "$NEW" <<'EOF'
import json, math, sys
w = json.load(open(sys.argv[1]))
lon, lat = w["center"][0], w["center"][1]
z = 10
n = 2 ** z
x = int((lon + 180) / 360 * n)
y = int((1 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2 * n)
print(f"/tiles/{sys.argv[2]}/elevation/{z}/{x}/{y}.png")
EOF
)

# 3b. Byte identity across replicas and through nginx.
PATHS=(
    /tiles/tienshan/elevation/10/724/378.png
    /tiles/tienshan/elevation/12/2896/1512.exr
    /tiles/tienshan/hillshade/10/724/378.png
    /tiles/tienshan/color/10/724/378.png
    /tiles/tienshan/drainage/10/724/378.png
    /tiles/tienshan/contours/11/1448/756.mvt
    "$new_tile"
)
for p in "${PATHS[@]}"; do
    sums=()
    for base_url in "$R1" "$R2" "$NX" "$NX"; do
        s=$(curl -fsS "$base_url$p" | sha256sum | cut -d' ' -f1) || die "GET $base_url$p failed"
        sums+=("$s")
    done
    [[ "${sums[0]}" == "${sums[1]}" && "${sums[0]}" == "${sums[2]}" && "${sums[0]}" == "${sums[3]}" ]] ||
        die "$p differs: ${sums[*]}"
done
log "(b) ${#PATHS[@]} tiles byte-identical from replica 1, replica 2 and nginx (miss and hit)"

# 3c. Failover under load: oha through nginx, replica 1 killed a third of the way in.
URLS="$WORK/urls.txt"
python3 - "$NX" >"$URLS" <<'EOF'
import sys
base = sys.argv[1]
for y in range(752, 760):
    for x in range(1444, 1452):
        for layer, ext in (("elevation", "png"), ("color", "png"), ("contours", "mvt")):
            print(f"{base}/tiles/tienshan/{layer}/11/{x}/{y}.{ext}")
EOF
: >"$WORK/nginx/access.log.run"
lines_before=$(wc -l <"$WORK/nginx/access.log")
OHA_JSON="$WORK/oha.json"
oha -z "${DURATION}s" -c "$CONNECTIONS" -w --no-tui --output-format json --urls-from-file "$URLS" \
    >"$OHA_JSON" 2>"$WORK/oha.stderr" </dev/null &
OHA_PID=$!
sleep "$(python3 -c "print($DURATION / 3)")"
log "killing replica 1 (pid $R1_PID) during the run"
kill -9 "$R1_PID"
wait "$OHA_PID" || { cat "$WORK/oha.stderr" >&2; die "oha failed"; }
tail -n +"$((lines_before + 1))" "$WORK/nginx/access.log" >"$WORK/nginx/access.log.run"
read -r n bad rps hits total < <(python3 - "$OHA_JSON" "$WORK/nginx/access.log.run" <<'EOF'
import json, re, sys
r = json.load(open(sys.argv[1]))
codes = {int(k): int(v) for k, v in (r.get("statusCodeDistribution") or {}).items()}
errors = sum(int(v) for v in (r.get("errorDistribution") or {}).values())
n = sum(codes.values()) + errors
bad = sum(v for k, v in codes.items() if not 200 <= k < 300) + errors
statuses = re.findall(r" cache=(\S+)", open(sys.argv[2]).read())
hits = sum(1 for s in statuses if s == "HIT")
print(n, bad, "%.1f" % float(r["summary"]["requestsPerSec"]), hits, len(statuses))
EOF
)
((n > 0)) || die "oha sent no request"
((bad == 0)) || die "$bad of $n requests failed or were not 2xx during failover (see $OHA_JSON)"
RATIO=$(python3 -c "print('%.1f' % (100.0 * $hits / max($total, 1)))")
log "(c) failover: $n requests in ${DURATION}s through nginx, 0 failed, replica 1 killed after $((DURATION / 3)) s"
echo "replicas_test: pickup ${PICKUP} s; oha ${DURATION}s c=${CONNECTIONS}: ${n} requests, 0 failed, ${rps} req/s through nginx; nginx cache hits ${hits}/${total} (${RATIO}%)"
