#!/usr/bin/env bash
# The WMTS capabilities checked by an independent client against a live server: OWSLib (pinned,
# installed with pip into a virtualenv under target/) reads
# /worlds/tienshan/WMTSCapabilities.xml as a GIS client would and the script checks that
#   - every raster layer of /worlds/tienshan is there, as image/png, with the world's bounds;
#   - the tile matrix set is EPSG:3857 with zooms 0..maxzoom, each with the scale denominator,
#     top-left corner and matrix size of the GoogleMapsCompatible scale set (computed here from
#     the Earth's radius);
#   - at every zoom from the world's minimum to 10, the tiles OWSLib fetches at the four corners
#     of the layer's tile limits are the bytes the XYZ route serves, and the tiles one beyond
#     each limit (inside the zoom's matrix) are 404: the limits are exactly the tiles served.
# Usage: scripts/wmts_test.sh [--bin PATH] (default target/debug/terrasynth; .ci/run runs it
# after the tests).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cd "$(dirname "$0")/.."

OWSLIB_VERSION=0.35.0
BIN=target/debug/terrasynth
if [[ "${1:-}" == "--bin" ]]; then BIN=$2; shift 2; fi
[[ -x "$BIN" ]] || die "no binary at $BIN (run cargo build)"

VENV=target/wmts-venv
pinned_venv "$VENV" OWSLib "$OWSLIB_VERSION"

OUT=target/wmts-test
rm -rf "$OUT"
mkdir -p "$OUT"
# The store persists between runs (the default world's dictionary is built once).
export TERRASYNTH_STORE_DIR=target/wmts-store TERRASYNTH_CACHE_MB=256
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
"$BIN" serve --listen "127.0.0.1:$PORT" >"$OUT/server.log" 2>&1 &
SERVER=$!
trap 'stop_process "$SERVER"' EXIT
wait_until_up "http://127.0.0.1:$PORT/healthz" "$SERVER" 300 "$OUT/server.log" ||
    die "the server did not become healthy"

"$VENV/bin/python" - "http://127.0.0.1:$PORT" <<'PY'
import json
import math
import sys
import urllib.error
import urllib.request

from owslib.wmts import WebMapTileService

base = sys.argv[1]


def fetch(url):
    try:
        with urllib.request.urlopen(url) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, b""


world = json.loads(fetch(f"{base}/worlds/tienshan")[1])
wmts = WebMapTileService(f"{base}/worlds/tienshan/WMTSCapabilities.xml")
assert wmts.identification.type == "OGC WMTS", wmts.identification.type
assert wmts.identification.version == "1.0.0"
assert wmts.identification.title == world["title"], wmts.identification.title
raster = [l for l in world["layers"]]
assert sorted(wmts.contents) == sorted(raster), (sorted(wmts.contents), raster)

tms = wmts.tilematrixsets["WebMercatorQuad"]
assert tms.crs == "urn:ogc:def:crs:EPSG::3857", tms.crs
assert sorted(tms.tilematrix, key=int) == [str(z) for z in range(world["maxzoom"] + 1)]
half = math.pi * 6378137.0
for z, m in tms.tilematrix.items():
    z = int(z)
    scale = 2 * math.pi * 6378137.0 / 256 / 0.00028 / 2**z
    assert abs(m.scaledenominator - scale) <= 1e-6 * scale, (z, m.scaledenominator, scale)
    assert abs(m.topleftcorner[0] + half) < 1e-3 and abs(m.topleftcorner[1] - half) < 1e-3
    assert (m.tilewidth, m.tileheight) == (256, 256)
    assert (m.matrixwidth, m.matrixheight) == (2**z, 2**z), (z, m.matrixwidth)

for name, layer in wmts.contents.items():
    assert layer.formats == ["image/png"], (name, layer.formats)
    got = layer.boundingBoxWGS84
    assert all(abs(a - b) < 1e-9 for a, b in zip(got, world["bounds"])), (name, got)
    limits = layer.tilematrixsetlinks["WebMercatorQuad"].tilematrixlimits
    assert sorted(limits, key=int) == [
        str(z) for z in range(world["minzoom"], world["maxzoom"] + 1)
    ], (name, sorted(limits))

checked = 0
for layer in ["hillshade", "color"]:
    limits = wmts.contents[layer].tilematrixsetlinks["WebMercatorQuad"].tilematrixlimits
    for z in range(world["minzoom"], 11):
        lim = limits[str(z)]
        rows = (lim.mintilerow, lim.maxtilerow)
        cols = (lim.mintilecol, lim.maxtilecol)
        for row in rows:
            for col in cols:
                tile = wmts.gettile(
                    layer=layer, tilematrixset="WebMercatorQuad", tilematrix=str(z),
                    row=row, column=col, format="image/png",
                ).read()
                status, direct = fetch(f"{base}/tiles/tienshan/{layer}/{z}/{col}/{row}.png")
                assert status == 200 and tile == direct, (layer, z, col, row, status)
                checked += 1
        n = 2**z
        beyond = [(cols[0] - 1, rows[0]), (cols[1] + 1, rows[0]), (cols[0], rows[0] - 1),
                  (cols[0], rows[1] + 1)]
        for col, row in beyond:
            if 0 <= col < n and 0 <= row < n:
                status, _ = fetch(f"{base}/tiles/tienshan/{layer}/{z}/{col}/{row}.png")
                assert status == 404, (layer, z, col, row, status)
                checked += 1
print(f"wmts-test: OWSLib read {len(wmts.contents)} layers and {len(tms.tilematrix)} tile "
      f"matrices; {checked} tiles at and beyond the limits as declared")
PY
