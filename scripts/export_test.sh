#!/usr/bin/env bash
# `terrasynth export` checked by independent readers against a live server: exports the default
# world over a small box (zooms 0–10, elevation + colour) to PMTiles and MBTiles, then
#   - reads every PMTiles archive with the `pmtiles` Python package (pinned, installed with pip
#     into a virtualenv under target/): header (v3, clustered, gzip directories, PNG), metadata
#     (`encoding: "terrarium"` for elevation), and every tile equal to the bytes the server
#     serves at /tiles/{world}/{layer}/{z}/{x}/{y}.png; the same with leaf directories forced;
#   - the same for a `--tile-format webp` export against the served `{y}.webp` tiles;
#   - opens the MBTiles archives with Python's sqlite3: metadata (name, format, bounds, center,
#     minzoom, maxzoom) and every tile (TMS row) equal to the served bytes;
#   - vector tiles (`--tile-format mvt`: contours at zooms 8–10 over the box, instances at zoom 14
#     over a corner of it) in both formats: MVT with gzip tile compression (PMTiles header;
#     MBTiles `format` pbf), `vector_layers` in the metadata (MBTiles: its `json` row), every tile
#     equal to the gzip-coded bytes the server sends a client that accepts gzip, and, decompressed
#     by Python's gzip, to the served `.mvt` bytes;
#   - exports two shards and joins them with `export merge`: the same tiles as the whole export;
#   - kills an export (SIGKILL) while it runs: no file with the output's name is left;
#   - the whole-world layers end up stored in the shared store (landscape/), which later exports
#     read instead of computing them.
# Usage: scripts/export_test.sh [--bin PATH] (default target/debug/terrasynth, built by
# `cargo test`/`cargo build`; .ci/run runs it after the tests).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cd "$(dirname "$0")/.."

PMTILES_VERSION=3.8.1
BIN=target/debug/terrasynth
if [[ "${1:-}" == "--bin" ]]; then BIN=$2; shift 2; fi
[[ -x "$BIN" ]] || { echo "export_test: no binary at $BIN (run cargo build)" >&2; exit 1; }

VENV=target/export-venv
pinned_venv "$VENV" pmtiles "$PMTILES_VERSION"

OUT=target/export-test
rm -rf "$OUT"
mkdir -p "$OUT"
# The store persists between runs (the default world's dictionary is built once).
export TERRASYNTH_STORE_DIR=target/export-store TERRASYNTH_CACHE_MB=256
BBOX=72.0,42.25,72.6,42.6
ZOOMS=0-10
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
"$BIN" serve --listen "127.0.0.1:$PORT" >"$OUT/server.log" 2>&1 &
SERVER=$!
EXPORTER=
cleanup() {
    kill "$SERVER" 2>/dev/null || true
    wait "$SERVER" 2>/dev/null || true
    if [[ -n "$EXPORTER" ]]; then kill -9 "$EXPORTER" 2>/dev/null || true; fi
}
trap cleanup EXIT
wait_until_up "http://127.0.0.1:$PORT/healthz" "$SERVER" 300 "$OUT/server.log" ||
    { echo "export-test: the server did not become healthy" >&2; exit 1; }

export_to() { # FORMAT OUTPUT [extra args]
    local format=$1 output=$2
    shift 2
    "$BIN" export --world tienshan --bbox "$BBOX" --zooms "$ZOOMS" --layers elevation,color \
        --format "$format" --output "$output" "$@" >/dev/null
}
export_to pmtiles "$OUT/talas.pmtiles"
export_to mbtiles "$OUT/talas.mbtiles"
export_to pmtiles "$OUT/webp.pmtiles" --tile-format webp
# The colour exports start from the whole-world layers the server (or the first export) stored;
# every later export reads them (the archives' tiles are checked against the served ones below).
[[ -s "$TERRASYNTH_STORE_DIR/landscape/tienshan.layers" ]] ||
    { echo "export-test: the whole-world layers were not stored" >&2; exit 1; }
# Leaf directories forced by a small root (the default keeps this export's root in 16 KiB).
"$BIN" export --world tienshan --bbox "$BBOX" --zooms "$ZOOMS" --layers elevation \
    --format pmtiles --output "$OUT/leaves.pmtiles" --max-root-bytes 120 >/dev/null
# Vector tiles: contours over the box, instances (from zoom 14) over its north-east corner.
VBOX=72.57,42.57,72.6,42.6
for format in pmtiles mbtiles; do
    "$BIN" export --world tienshan --bbox "$BBOX" --zooms 8-10 --layers contours \
        --format "$format" --tile-format mvt --output "$OUT/contours.$format" >/dev/null
    "$BIN" export --world tienshan --bbox "$VBOX" --zooms 14 --layers instances \
        --format "$format" --tile-format mvt --output "$OUT/instances.$format" >/dev/null
done
# Refused before anything is written, with the reason named: instances above their first zoom, a
# vector layer as PNG, a raster layer as MVT.
refused() { # EXPECTED-MESSAGE export-args...
    local want=$1 err
    shift
    if err=$("$BIN" export --world tienshan --bbox "$VBOX" --format pmtiles \
        --output "$OUT/refused.pmtiles" "$@" 2>&1 >/dev/null); then
        die "export $* succeeded"
    fi
    grep -qF "$want" <<<"$err" || die "export $*: \"$want\" not in: $err"
    [[ ! -e "$OUT/refused.pmtiles" ]] || die "export $* left an archive"
}
refused "instance tiles start at zoom 14 (zoom 12 asked)" --zooms 12-14 --layers instances --tile-format mvt
refused "(a vector layer: --tile-format mvt)" --zooms 14 --layers instances
refused "(--tile-format mvt is for instances and contours)" --zooms 10 --layers elevation --tile-format mvt
echo "export_test: vector exports refused where they do not apply, with the reason"
# Two shards of the elevation layer, joined (parts given in any order).
for i in 1 2; do
    for format in pmtiles mbtiles; do
        "$BIN" export --world tienshan --bbox "$BBOX" --zooms "$ZOOMS" --layers elevation \
            --format "$format" --output "$OUT/part$i.$format" --shard "$i/2" >/dev/null
    done
done
"$BIN" export merge --output "$OUT/merged-elevation.pmtiles" "$OUT/part2.pmtiles" "$OUT/part1.pmtiles"
"$BIN" export merge --output "$OUT/merged-elevation.mbtiles" "$OUT/part1.mbtiles" "$OUT/part2.mbtiles"

"$VENV/bin/python" - "$OUT" "http://127.0.0.1:$PORT" "$BBOX" "$ZOOMS" "$VBOX" <<'PY'
import gzip, json, math, sqlite3, sys, urllib.request
from pmtiles.reader import Reader, MmapSource, all_tiles
from pmtiles.tile import TileType, Compression

out, base, bbox, zooms, vbox = sys.argv[1:6]
w, s, e, n = map(float, bbox.split(","))
z0, z1 = map(int, zooms.split("-"))
served = {}

def serve(layer, z, x, y, ext="png"):
    key = (layer, z, x, y) if ext == "png" else (layer, z, x, y, ext)
    if key not in served:
        with urllib.request.urlopen(f"{base}/tiles/tienshan/{layer}/{z}/{x}/{y}.{ext}") as r:
            assert r.status == 200
            served[key] = r.read()
    return served[key]

def serve_coded(layer, z, x, y):
    """The vector tile as sent gzip-coded, and as sent to a client that does not accept gzip."""
    url = f"{base}/tiles/tienshan/{layer}/{z}/{x}/{y}.mvt"
    with urllib.request.urlopen(urllib.request.Request(url, headers={"Accept-Encoding": "gzip"})) as r:
        assert r.status == 200 and r.headers["Content-Encoding"] == "gzip", (url, dict(r.headers))
        coded = r.read()
    with urllib.request.urlopen(url) as r:
        assert r.status == 200 and r.headers.get("Content-Encoding") is None, (url, dict(r.headers))
        return coded, r.read()

def expected(z, w=w, s=s, e=e, n=n):
    """The tiles of the box at zoom z (the default world covers the whole box)."""
    def tx(lon): return (lon + 180) / 360 * 2**z
    def ty(lat):
        r = math.radians(lat)
        return (1 - math.log(math.tan(r) + 1 / math.cos(r)) / math.pi) / 2 * 2**z
    xs = range(int(tx(w)), int(math.ceil(tx(e))))
    ys = range(int(ty(n)), int(math.ceil(ty(s))))
    return {(z, x, y) for x in xs for y in ys}

want = set().union(*(expected(z) for z in range(z0, z1 + 1)))

def read_pmtiles(path, layer, ext="png"):
    with open(path, "rb") as f:
        r = Reader(MmapSource(f))
        h = r.header()
        assert h["tile_type"] == (TileType.PNG if ext == "png" else TileType.WEBP), h
        assert h["clustered"], h
        assert h["internal_compression"] == Compression.GZIP, h
        assert h["tile_compression"] == Compression.NONE, h
        assert (h["min_zoom"], h["max_zoom"]) == (z0, z1), h
        meta = r.metadata()
        assert meta["format"] == ext, meta
        if layer == "elevation":
            assert meta["encoding"] == "terrarium", meta
        else:
            assert "encoding" not in meta, meta
        tiles = {k: v for k, v in all_tiles(r.get_bytes)}
        for (z, x, y), data in tiles.items():
            assert r.get(z, x, y) == data
        return h, tiles

checked = 0
for layer in ("elevation", "color"):
    h, tiles = read_pmtiles(f"{out}/talas-{layer}.pmtiles", layer)
    assert set(tiles) == want, sorted(set(tiles) ^ want)[:10]
    for (z, x, y), data in tiles.items():
        assert data == serve(layer, z, x, y), f"{layer} {z}/{x}/{y} differs from the served tile"
        checked += 1
    if layer == "elevation":
        _, merged = read_pmtiles(f"{out}/merged-{layer}.pmtiles", layer)
        assert merged == tiles, "merged shards differ from the whole export"
        _, part = read_pmtiles(f"{out}/part1.pmtiles", layer)
        assert 0 < len(part) < len(tiles), "a shard holds part of the tiles"

for layer in ("elevation", "color"):
    _, tiles = read_pmtiles(f"{out}/webp-{layer}.pmtiles", layer, "webp")
    assert set(tiles) == want
    for (z, x, y), data in tiles.items():
        assert data[:4] == b"RIFF" and data[8:12] == b"WEBP"
        assert data == serve(layer, z, x, y, "webp"), f"webp {layer} {z}/{x}/{y} differs"
        checked += 1

h, leaves = read_pmtiles(f"{out}/leaves.pmtiles", "elevation")
assert h["leaf_directory_length"] > 0, h
assert leaves == {k: served[("elevation",) + k] for k in want}

for layer in ("elevation", "color"):
    for name in [f"talas-{layer}"] + ([f"merged-{layer}"] if layer == "elevation" else []):
        db = sqlite3.connect(f"{out}/{name}.mbtiles")
        meta = dict(db.execute("SELECT name, value FROM metadata"))
        assert meta["name"] == f"tienshan {layer}", meta
        assert meta["format"] == "png", meta
        assert (int(meta["minzoom"]), int(meta["maxzoom"])) == (z0, z1), meta
        b = list(map(float, meta["bounds"].split(",")))
        assert b == [w, s, e, n], b
        c = list(map(float, meta["center"].split(",")))
        assert b[0] <= c[0] <= b[2] and b[1] <= c[1] <= b[3] and z0 <= c[2] <= z1, c
        if layer == "elevation":
            assert meta["encoding"] == "terrarium", meta
        rows = db.execute("SELECT zoom_level, tile_column, tile_row, tile_data FROM tiles").fetchall()
        got = {(z, x, (1 << z) - 1 - row): data for z, x, row, data in rows}
        assert set(got) == want
        for (z, x, y), data in got.items():
            assert data == serve(layer, z, x, y), f"mbtiles {layer} {z}/{x}/{y} differs"
            checked += 1
# Vector tiles: gzip-compressed MVT, the bytes the server sends gzip-coded.
vw, vs, ve, vn = map(float, vbox.split(","))
vector = {
    "contours": set().union(*(expected(z) for z in range(8, 11))),
    "instances": expected(14, vw, vs, ve, vn),
}
for layer, want_v in vector.items():
    with open(f"{out}/{layer}.pmtiles", "rb") as f:
        r = Reader(MmapSource(f))
        h = r.header()
        assert h["tile_type"] == TileType.MVT, h
        assert h["tile_compression"] == Compression.GZIP, h
        meta = r.metadata()
        assert meta["format"] == "pbf", meta
        ids = [l["id"] for l in meta["vector_layers"]]
        pm = {k: v for k, v in all_tiles(r.get_bytes)}
    db = sqlite3.connect(f"{out}/{layer}.mbtiles")
    mmeta = dict(db.execute("SELECT name, value FROM metadata"))
    assert mmeta["format"] == "pbf", mmeta
    assert [l["id"] for l in json.loads(mmeta["json"])["vector_layers"]] == ids, mmeta
    rows = db.execute("SELECT zoom_level, tile_column, tile_row, tile_data FROM tiles").fetchall()
    mb = {(z, x, (1 << z) - 1 - row): data for z, x, row, data in rows}
    assert set(pm) == want_v and set(mb) == want_v, (layer, sorted(set(pm) ^ want_v)[:5])
    assert ids == (["contours"] if layer == "contours" else ["trees", "grass", "rocks"]), ids
    for key, data in pm.items():
        coded, plain = serve_coded(layer, *key)
        assert data == coded and mb[key] == coded, f"{layer} {key} differs from the served gzip bytes"
        assert gzip.decompress(data) == plain, f"{layer} {key} decompresses to other bytes"
        checked += 2
print(f"export_test: {len(want)} tiles per layer; {checked} archive tiles equal the served bytes; "
      f"PMTiles read by pmtiles {__import__('importlib.metadata').metadata.version('pmtiles')}, "
      f"MBTiles by sqlite {sqlite3.sqlite_version}")
PY

# A killed export leaves no file under the output's name (a deeper export, killed while it runs).
# Zooms 0-14 over this box are 4,730 tiles: 37 s at this machine's 128 elevation tiles/s,
# so the kill 3 s in lands mid-export on any machine we run on (zooms 0-12, 360 tiles, could end first).
for format in pmtiles mbtiles; do
    "$BIN" export --world tienshan --bbox 71.5,42.1,73.5,42.7 --zooms 0-14 --layers elevation \
        --format "$format" --output "$OUT/killed.$format" >/dev/null 2>&1 &
    EXPORTER=$!
    sleep 3
    kill -0 "$EXPORTER" 2>/dev/null || { echo "export_test: the export to be killed ended first" >&2; exit 1; }
    kill -9 "$EXPORTER"
    wait "$EXPORTER" 2>/dev/null || true
    EXPORTER=
    if [[ -e "$OUT/killed.$format" ]]; then
        echo "export_test: a killed $format export left $OUT/killed.$format" >&2
        exit 1
    fi
done
echo "export_test: killed exports left no archive under the output name"
left=$(ls -a "$OUT" | grep -c '^\.killed\.mbtiles\.tmp-' || true)
echo "export_test: $left temporary file(s) left by the killed MBTiles export (a hidden name)"
# The next export to the same name removes what the killed one left, and writes its archive.
"$BIN" export --world tienshan --bbox 71.5,42.1,73.5,42.7 --zooms 0-2 --layers elevation \
    --format mbtiles --output "$OUT/killed.mbtiles" >/dev/null 2>"$OUT/rerun.err"
if ls -a "$OUT" | grep -q '^\.killed\.mbtiles\.tmp-' || [[ ! -s "$OUT/killed.mbtiles" ]]; then
    echo "export_test: the export after a killed one left a temporary file or no archive" >&2
    exit 1
fi
if [[ $left -gt 0 ]] && ! grep -q "removed $left temporary file" "$OUT/rerun.err"; then
    echo "export_test: the export after a killed one did not say it removed $left file(s)" >&2
    exit 1
fi
echo "export_test: the next export to that name removed them and wrote its archive"
