#!/usr/bin/env bash
# Issue #12's served-tile figures for a world created through the admin API (acceptance 3: a
# world from another exemplar and base than the default's). Not in CI: a measurement.
#
# Cuts two crops of the committed Tien Shan grid (exemplar: the Alai crop 1400,1400,512,512;
# base: 1500,500,768,640, 15″, native zoom 8), starts a release server on a new store with an
# admin token, uploads both (POST /admin/exemplars), builds a dictionary from the exemplar (POST
# /admin/dictionaries {"name": "alai", "exemplars": [E], "seed": 1}, defaults otherwise),
# creates the world `alatoo` (POST /admin/worlds, max_zoom 14), stops the server and runs the `served_realism`
# example on that store around the corner of zoom-10 tile 722/382 (the middle of the base); it
# prints the exemplar's own anisotropy first, since the served mosaics inherit it.
#
# Usage: scripts/admin_world_realism.sh [PORT]   (default 18491; work under target/admin-realism)
# EXEMPLAR_WINDOW=COL,ROW,WIDTH,HEIGHT takes the exemplar from another window of the same grid.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cd "$(dirname "$0")/.."
PORT=${1:-18491}
WORK=target/admin-realism
rm -rf "$WORK" && mkdir -p "$WORK"
T=config/data/tienshan_west_gebco15s.tif
cargo build --release --quiet --bin terrasynth --example served_realism
B=target/release/terrasynth
"$B" crop --input "$T" --window "${EXEMPLAR_WINDOW:-1400,1400,512,512}" --output "$WORK/exemplar.tif" >/dev/null
"$B" crop --input "$T" --window 1500,500,768,640 --output "$WORK/base.tif" >/dev/null

export TERRASYNTH_ADMIN_TOKEN=realism
A="Authorization: Bearer $TERRASYNTH_ADMIN_TOKEN"
S=http://127.0.0.1:$PORT
TERRASYNTH_STORE_DIR=$WORK/store "$B" serve --listen "127.0.0.1:$PORT" >"$WORK/server.log" 2>&1 &
pid=$!
trap 'kill $pid 2>/dev/null || true' EXIT
wait_until_up "$S/healthz" "$pid" 600 "$WORK/server.log" || exit 1
field() { python3 -c "import json, sys; print(json.load(sys.stdin)['$1'])"; }
upload() {
    curl -sf -H "$A" -H 'Content-Type: image/tiff' --data-binary "@$1" \
        "$S/admin/exemplars?name=$2" | field id
}
E=$(upload "$WORK/exemplar.tif" alai)
BASE=$(upload "$WORK/base.tif" alatoo-base)
J=$(curl -sf -H "$A" -H 'Content-Type: application/json' "$S/admin/dictionaries" \
    -d '{"name": "alai", "exemplars": ["'"$E"'"], "seed": 1}' | field id)
while :; do
    state=$(curl -sf -H "$A" "$S/admin/jobs/$J" | field state)
    case $state in
        succeeded) break ;;
        failed | cancelled) echo "dictionary job $state" >&2; exit 1 ;;
    esac
    sleep 1
done
D=$(curl -sf -H "$A" "$S/admin/jobs/$J" | field result)
curl -sf -H "$A" -H 'Content-Type: application/json' "$S/admin/worlds" \
    -d '{"name": "alatoo", "base": "'"$BASE"'", "dictionaries": ["'"$D"'"], "max_zoom": 14}' \
    >/dev/null
kill $pid
wait $pid 2>/dev/null || true
target/release/examples/served_realism "$WORK/store" alatoo 722 382 "$WORK/exemplar.tif"
