#!/usr/bin/env bash
# Rewrites tests/data/default_world_tiles.sha256 (the tile-hash list `tests/it/tile_hashes.rs`
# checks) from a release server of the default world: the same 65 paths, their new SHA-256.
# Run it only in a commit that means to change the amplifier or a layer, and say so there.
#
# Usage: scripts/tile_hashes.sh [PORT]   (default 18473; a fresh store under target/)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh
PORT=${1:-18473}
LIST=tests/data/default_world_tiles.sha256
WORK=$(mktemp -d target/tile-hash.XXXXXX)
# The store directory must be new or empty (the server refuses foreign directories).
STORE=$WORK/store
cargo build --release --quiet --bin terrasynth
TERRASYNTH_STORE_DIR=$STORE target/release/terrasynth serve --listen "127.0.0.1:$PORT" \
    >"$WORK/server.log" 2>&1 &
pid=$!
trap 'stop_process $pid; rm -rf "$WORK"' EXIT
wait_until_up "http://127.0.0.1:$PORT/worlds" "$pid" 600 "$WORK/server.log" || die "the server did not start"
tmp=$(mktemp)
while read -r _ path; do
    [[ -z "$path" ]] && continue
    hash=$(curl -sf "http://127.0.0.1:$PORT$path" | sha256sum | cut -d' ' -f1)
    echo "$hash $path" >>"$tmp"
done <"$LIST"
mv "$tmp" "$LIST"
echo "rewrote $LIST ($(wc -l <"$LIST") tiles)"
