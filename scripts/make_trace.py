#!/usr/bin/env python3
"""Generate a deterministic pan-and-zoom tile trace for the terrasynth load test.

The trace imitates what a web map (MapLibre, Leaflet) requests while a user browses the western
Tien Shan: a viewport of 4 x 3 tiles starts over the Talas range (72.5 E, 42.4 N) at zoom 9, pans
east to Bishkek (74.6 E, 42.87 N), then zooms in step by step to zoom 14, each zoom's viewport centred
on where the previous zoom ended, panning a fixed route at every zoom: west along the Kyrgyz
Ala-Too back to the Talas range, then around the Talas range (zooms 11-14, about 72.1-72.7 E,
42.4-42.9 N).

Like a real client it requests each tile once (it keeps what it has already loaded), and inside a
viewport it requests the tiles nearest the centre first. Most requests are terrarium elevation
PNGs; at some zooms the hillshade overlay is visible (its tiles are requested right after the
elevation tile of the same position) and at others the client is a high-DPI one asking for `@2x`
elevation tiles. The landscape layers are in the mix too: at the --landscape-zooms the map shows
the MapLibre style of the world (colour map and drainage overlay, requested after each elevation
tile), and at the --splat-zooms a game-engine client streams splat sets 0 and 1 and the vegetation
channels with its heightmaps. Pass empty lists to leave them out.

The output is one URL per line (`BASE/tiles/WORLD/LAYER/Z/X/Y.png`), in request order. The same
arguments always give the same file. Only the Python 3 standard library is used.

Usage: make_trace.py [--base-url URL] [--world NAME] [--hillshade-zooms 11,13]
                     [--retina-zooms 12] [--landscape-zooms 10,14] [--splat-zooms 13]
                     [--instance-zooms 14] [--water-zooms 10,14] [--stats]
"""

import argparse
import math
import sys

# Where the route starts (Talas range) and where zoom 9 ends (Bishkek), lon/lat degrees.
TALAS = (72.5, 42.4)
BISHKEK = (74.6, 42.87)

# Viewport size in tiles (columns, rows).
VIEW_W, VIEW_H = 4, 3

# Pan route at each zoom, as a string of one-tile steps: E, W, N (up), S (down).
# Zoom 9 pans from Talas to Bishkek (computed from the coordinates), then follows its own route.
# The routes stay well inside the default world (lon 66.14-77.87 E, lat 36.32-44.71 N).
ROUTES = {
    9: "",
    10: "WWWWWS",
    11: "WWWWWWNNN",
    12: "SSSEEEEEEEEE",
    13: "NNNNWWWWWWWW",
    14: "EEEEEEESSSSSSS",
}

STEP = {"E": (1, 0), "W": (-1, 0), "N": (0, -1), "S": (0, 1)}


def lonlat_to_tile(lon, lat, zoom):
    """Fractional slippy-map tile coordinates (x, y) of a point at `zoom` (Web Mercator)."""
    n = 2.0**zoom
    lat_r = math.radians(lat)
    x = (lon + 180.0) / 360.0 * n
    y = (1.0 - math.asinh(math.tan(lat_r)) / math.pi) / 2.0 * n
    return x, y


def tile_to_lonlat(x, y, zoom):
    """Lon/lat of the fractional tile coordinates (x, y) at `zoom`."""
    n = 2.0**zoom
    lon = x / n * 360.0 - 180.0
    lat = math.degrees(math.atan(math.sinh(math.pi * (1.0 - 2.0 * y / n))))
    return lon, lat


def snap(cx, cy):
    """Snap a viewport centre so that the viewport covers exactly VIEW_W x VIEW_H whole tiles."""
    sx = round(cx) if VIEW_W % 2 == 0 else math.floor(cx) + 0.5
    sy = round(cy) if VIEW_H % 2 == 0 else math.floor(cy) + 0.5
    return sx, sy


def viewport(cx, cy):
    """Tiles (x, y) of the viewport centred on (cx, cy), nearest the centre first."""
    x0 = int(math.floor(cx - VIEW_W / 2.0 + 0.5))
    y0 = int(math.floor(cy - VIEW_H / 2.0 + 0.5))
    tiles = [(x, y) for y in range(y0, y0 + VIEW_H) for x in range(x0, x0 + VIEW_W)]
    # Distance from the tile centre to the viewport centre; ties broken by (y, x) for determinism.
    tiles.sort(key=lambda t: ((t[0] + 0.5 - cx) ** 2 + (t[1] + 0.5 - cy) ** 2, t[1], t[0]))
    return tiles


def pan_steps(start, end):
    """One-tile steps (E/W/N/S) from tile centre `start` to `end`, alternating axes."""
    dx = int(round(end[0] - start[0]))
    dy = int(round(end[1] - start[1]))
    steps = []
    while dx or dy:
        if dx:
            steps.append("E" if dx > 0 else "W")
            dx -= 1 if dx > 0 else -1
        if dy:
            steps.append("S" if dy > 0 else "N")
            dy -= 1 if dy > 0 else -1
    return "".join(steps)


def parse_zooms(text):
    return {int(z) for z in text.split(",") if z.strip()}


def generate(hillshade_zooms, retina_zooms, landscape_zooms=frozenset(), splat_zooms=frozenset(),
             instance_zooms=frozenset(), water_zooms=frozenset()):
    """Yield (zoom, layer, suffix, x, y) in request order; `suffix` is what follows the tile
    row in the URL (`@2x`, a query such as `?set=1`, or another format such as `.mvt`)."""
    cx, cy = snap(*lonlat_to_tile(*TALAS, 9))
    for zoom in range(9, 15):
        if zoom > 9:
            # Zoom in one level around the current centre.
            cx, cy = snap(cx * 2.0, cy * 2.0)
        route = ROUTES[zoom]
        if zoom == 9:
            route = pan_steps((cx, cy), lonlat_to_tile(*BISHKEK, 9)) + route
        loaded = set()
        positions = [(cx, cy)]
        for step in route:
            dx, dy = STEP[step]
            cx, cy = cx + dx, cy + dy
            positions.append((cx, cy))
        for px, py in positions:
            for x, y in viewport(px, py):
                if (x, y) in loaded:
                    continue
                loaded.add((x, y))
                suffix = "@2x" if zoom in retina_zooms else ""
                yield zoom, "elevation", suffix, x, y
                if zoom in hillshade_zooms:
                    yield zoom, "hillshade", "", x, y
                if zoom in landscape_zooms:
                    yield zoom, "color", "", x, y
                    yield zoom, "drainage", "", x, y
                if zoom in splat_zooms:
                    yield zoom, "splat", "", x, y
                    yield zoom, "splat", "?set=1", x, y
                    yield zoom, "vegetation", "", x, y
                if zoom in instance_zooms:
                    yield zoom, "instances", ".mvt", x, y
                if zoom in water_zooms:
                    yield zoom, "water", "", x, y


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base-url", default="http://127.0.0.1:18080",
                        help="prefix of every URL (default %(default)s); '' for bare paths")
    parser.add_argument("--world", default="tienshan", help="world name (default %(default)s)")
    parser.add_argument("--hillshade-zooms", default="11,13",
                        help="zooms at which the hillshade overlay is visible (default %(default)s)")
    parser.add_argument("--retina-zooms", default="12",
                        help="zooms browsed by a high-DPI client asking for @2x elevation "
                             "(default %(default)s)")
    parser.add_argument("--landscape-zooms", default="10,14",
                        help="zooms at which the colour map and drainage overlay are shown "
                             "(default %(default)s)")
    parser.add_argument("--splat-zooms", default="13",
                        help="zooms at which splat sets 0-1 and vegetation are streamed "
                             "(default %(default)s)")
    parser.add_argument("--instance-zooms", default="",
                        help="zooms at which the plant and rock instances (.mvt) are streamed "
                             "(default: none)")
    parser.add_argument("--water-zooms", default="",
                        help="zooms at which the water layer (.png) is shown (default: none)")
    parser.add_argument("--stats", action="store_true",
                        help="print request counts per zoom and layer to stderr")
    args = parser.parse_args()

    base = args.base_url.rstrip("/")
    hillshade = parse_zooms(args.hillshade_zooms)
    retina = parse_zooms(args.retina_zooms)
    landscape = parse_zooms(args.landscape_zooms)
    splat = parse_zooms(args.splat_zooms)
    instances = parse_zooms(args.instance_zooms)
    water = parse_zooms(args.water_zooms)
    counts = {}
    out = sys.stdout
    for zoom, layer, suffix, x, y in generate(hillshade, retina, landscape, splat, instances, water):
        if suffix.startswith("."):
            url = f"{base}/tiles/{args.world}/{layer}/{zoom}/{x}/{y}{suffix}"
        elif suffix.startswith("?"):
            url = f"{base}/tiles/{args.world}/{layer}/{zoom}/{x}/{y}.png{suffix}"
        else:
            url = f"{base}/tiles/{args.world}/{layer}/{zoom}/{x}/{y}{suffix}.png"
        out.write(url + "\n")
        key = (zoom, layer + suffix)
        counts[key] = counts.get(key, 0) + 1
    if args.stats:
        total = sum(counts.values())
        for (zoom, kind), n in sorted(counts.items()):
            print(f"z{zoom:<3} {kind:<14} {n:4d}", file=sys.stderr)
        print(f"total {total} requests", file=sys.stderr)


if __name__ == "__main__":
    main()
