#!/usr/bin/env python3
"""Write a control-rich variant of the default world for measurements (issue #15, acceptance 6).

Writes, under OUT (default target/controls):
  landcover.tif  a class raster on the default base's grid (float32 GeoTIFF, deflate): 1 steppe
                 below 1,500 m, 2 forest to 2,800 m, 3 alpine meadow to 3,600 m, 4 rock above;
  alpine.tif, steppe.tif  biome weights: alpine rising from 0 at 1,200 m to 1 at 2,000 m, steppe
                 the rest;
  karatau.tif    the steppe biome's exemplar, the low-relief crop 256,0,512,512 of the base;
  controls.toml  the world `controls`: the default world's base, two painted biomes, a sea at
                 SEA_LEVEL_M (default 900 m: the Chui valley below Bishkek and the Syr Darya
                 lowlands), lakes on, the class raster with a legend and 1 km smoothing, and
                 materials and species that take `class.<name>` ranges;
  config.toml    a server configuration serving that world alone.

The class raster is made from the base itself: `terrasynth crop` writes the whole base as an
uncompressed-predictor float32 GeoTIFF, which this script decodes (zlib), classifies and writes
back with the same georeference. Only the Python 3 standard library is used.

Usage: scripts/controls_world.py [--bin target/release/terrasynth] [--out target/controls]
                                 [--sea-level-m 900]
"""

import argparse
import os
import struct
import subprocess
import zlib

BASE = "config/data/tienshan_west_gebco15s.tif"
COLS, ROWS = 2816, 2014

TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1, 11: 4, 12: 8, 16: 8}


def read_tiff(path):
    """Tags {tag: (type, count, raw bytes)} and the decoded float32 samples of a stripped,
    deflate-compressed (no predictor) little-endian TIFF."""
    b = open(path, "rb").read()
    assert b[:4] == b"II*\x00", "little-endian TIFF expected"
    off = struct.unpack("<I", b[4:8])[0]
    (n,) = struct.unpack("<H", b[off:off + 2])
    tags = {}
    for i in range(n):
        e = off + 2 + 12 * i
        tag, typ, count = struct.unpack("<HHI", b[e:e + 8])
        size = TYPE_SIZE[typ] * count
        if size <= 4:
            raw = b[e + 8:e + 8 + size]
        else:
            (at,) = struct.unpack("<I", b[e + 8:e + 12])
            raw = b[at:at + size]
        tags[tag] = (typ, count, raw)
    assert tags[259][2][:2] == struct.pack("<H", 8), "deflate expected"
    assert tags[273][0] == 4 and tags[279][0] == 4, "LONG strip offsets expected"
    offsets = struct.unpack(f"<{tags[273][1]}I", tags[273][2])
    sizes = struct.unpack(f"<{tags[279][1]}I", tags[279][2])
    data = b"".join(zlib.decompress(b[o:o + n]) for o, n in zip(offsets, sizes))
    values = struct.unpack(f"<{len(data) // 4}f", data)
    return tags, values


def write_tiff(path, tags, values):
    """Writes `values` (float32) as a one-strip deflate TIFF with `tags` (strip tags replaced)."""
    strip = zlib.compress(struct.pack(f"<{len(values)}f", *values), 6)
    tags = dict(tags)
    tags[273] = (4, 1, struct.pack("<I", 0))
    tags[279] = (4, 1, struct.pack("<I", len(strip)))
    (rows,) = struct.unpack("<I", tags[257][2]) if tags[257][0] == 4 else struct.unpack("<H", tags[257][2])
    tags[278] = (4, 1, struct.pack("<I", rows))
    order = sorted(tags)
    ifd_size = 2 + 12 * len(order) + 4
    extra_at = 8 + ifd_size
    extra = b""
    entries = []
    for tag in order:
        typ, count, raw = tags[tag]
        if len(raw) <= 4:
            entries.append((tag, typ, count, raw.ljust(4, b"\x00")))
        else:
            if (extra_at + len(extra)) % 2:
                extra += b"\x00"
            entries.append((tag, typ, count, struct.pack("<I", extra_at + len(extra))))
            extra += raw
    strip_at = extra_at + len(extra)
    out = bytearray(b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", len(order)))
    for tag, typ, count, value in entries:
        if tag == 273:
            value = struct.pack("<I", strip_at)
        out += struct.pack("<HHI", tag, typ, count) + value
    out += struct.pack("<I", 0) + extra + strip
    open(path, "wb").write(out)


def land_cover(elevation_m):
    if elevation_m < 1500.0:
        return 1.0
    if elevation_m < 2800.0:
        return 2.0
    if elevation_m < 3600.0:
        return 3.0
    return 4.0


WORLD = """# A control-rich variant of the default world (scripts/controls_world.py; measurements only).
name = "controls"
title = "Western Tien Shan with water and land cover"
base = "embedded:tienshan"
z_base = 8
max_zoom = 16
fill_m = 0.0
center = [74.55, 42.55]
sea_level_m = {sea}

# Painted biomes: the default dictionary on the ranges, a Karatau/steppe one on the plains.
[[biomes]]
name = "alpine"
weight = "alpine.tif"
[biomes.dictionary]
exemplars = ["embedded:tienshan"]
atoms = 256
patch = 16
stride = 8
seed = 1

[[biomes]]
name = "steppe"
weight = "steppe.tif"
[biomes.dictionary]
exemplars = ["karatau.tif"]
atoms = 256
patch = 16
stride = 8
seed = 1

[water]
lakes = true

[classes]
raster = "landcover.tif"
legend = {{ "1" = "steppe", "2" = "forest", "3" = "meadow", "4" = "rock" }}
smoothing_m = 1000.0

[weights]
elevation = 0.8
altitude = 0.1
slope = 0.1

[landscape]
[[landscape.materials]]
name = "steppe"
biome.steppe = {{ min = 0.5, max = 1.0 }}
colour = [176, 160, 110]
class.steppe = {{ min = 0.5, max = 1.0 }}
[[landscape.materials]]
name = "woods"
colour = [40, 110, 50]
class.forest = {{ min = 0.5, max = 1.0 }}
[[landscape.materials]]
name = "meadow"
colour = [120, 150, 80]
class.meadow = {{ min = 0.5, max = 1.0 }}
[[landscape.materials]]
name = "scree"
colour = [150, 145, 140]
class.rock = {{ min = 0.0, max = 2.0, falloff = 1.0 }}
[[landscape.species]]
name = "steppe"
elevation = {{ min = 300, max = 2600, falloff = 300 }}
class.steppe = {{ min = 0.2, max = 1.0, falloff = 0.2 }}
[[landscape.species]]
name = "spruce"
elevation = {{ min = 1500, max = 3000, falloff = 200 }}
class.forest = {{ min = 0.5, max = 1.0 }}
"""

CONFIG = """# Serves the control-rich world alone (scripts/controls_world.py).
listen = "127.0.0.1:8080"
cache_mb = 512
store_dir = "store"
worlds = ["controls.toml"]
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bin", default="target/release/terrasynth")
    parser.add_argument("--out", default="target/controls")
    parser.add_argument("--sea-level-m", type=float, default=900.0)
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    whole = os.path.join(args.out, "base.tif")
    subprocess.run([args.bin, "crop", "--input", BASE, "--window", f"0,0,{COLS},{ROWS}",
                    "--output", whole], check=True, stdout=subprocess.DEVNULL)
    tags, elevation = read_tiff(whole)
    classes = [land_cover(v) for v in elevation]
    write_tiff(os.path.join(args.out, "landcover.tif"), tags, classes)
    alpine = [min(1.0, max(0.0, (v - 1200.0) / 800.0)) for v in elevation]
    write_tiff(os.path.join(args.out, "alpine.tif"), tags, alpine)
    write_tiff(os.path.join(args.out, "steppe.tif"), tags, [1.0 - a for a in alpine])
    subprocess.run([args.bin, "crop", "--input", BASE, "--window", "256,0,512,512",
                    "--output", os.path.join(args.out, "karatau.tif")], check=True,
                   stdout=subprocess.DEVNULL)
    counts = {c: classes.count(c) for c in (1.0, 2.0, 3.0, 4.0)}
    with open(os.path.join(args.out, "controls.toml"), "w") as f:
        f.write(WORLD.format(sea=args.sea_level_m))
    with open(os.path.join(args.out, "config.toml"), "w") as f:
        f.write(CONFIG)
    print(f"wrote {args.out}/controls.toml, config.toml, landcover.tif, alpine.tif, steppe.tif "
          f"and karatau.tif "
          f"(cells per class: {counts})")


if __name__ == "__main__":
    main()
