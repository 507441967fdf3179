#!/usr/bin/env python3
"""The README picture of contour tiles over the hillshade (tests/pictures/contours.png).

Fetches an N×N block of hillshade PNGs and contour MVTs from a running server, decodes the MVTs
with the small reader below (protobuf wire format by hand, from the Mapbox Vector Tile 2.1
specification) and draws the lines over the shade, index lines thicker, tile borders dotted so
that the seams can be checked by eye.

    scripts/contours_picture.py --base http://127.0.0.1:8080 --world tienshan \
        --z 13 --x 5792 --y 3023 --n 2 --out tests/pictures/contours.png

Needs python3 with Pillow.
"""
import argparse
import io
import urllib.request

from PIL import Image, ImageDraw


def varint(b, i):
    v, shift = 0, 0
    while True:
        byte = b[i]
        i += 1
        v |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return v, i
        shift += 7


def fields(b):
    i = 0
    while i < len(b):
        key, i = varint(b, i)
        f, w = key >> 3, key & 7
        if w == 0:
            v, i = varint(b, i)
            yield f, v
        elif w == 1:
            yield f, b[i:i + 8]
            i += 8
        elif w == 2:
            n, i = varint(b, i)
            yield f, b[i:i + n]
            i += n
        elif w == 5:
            yield f, b[i:i + 4]
            i += 4
        else:
            raise ValueError(f"wire type {w}")


def packed(b):
    out, i = [], 0
    while i < len(b):
        v, i = varint(b, i)
        out.append(v)
    return out


def zigzag(v):
    return (v >> 1) ^ -(v & 1)


def lines(tile):
    """(index, [(x, y), ...]) of every part of every feature, in tile units."""
    import struct
    out = []
    for f, layer in fields(tile):
        if f != 3:
            continue
        keys, values, feats = [], [], []
        for lf, v in fields(layer):
            if lf == 3:
                keys.append(v.decode())
            elif lf == 4:
                (vf, vv), = list(fields(v))
                values.append(bool(vv) if vf == 7 else (struct.unpack("<d", vv)[0] if vf == 3 else vv))
            elif lf == 2:
                feats.append(v)
        for fb in feats:
            tags, geom = [], []
            for ff, v in fields(fb):
                if ff == 2:
                    tags = packed(v)
                elif ff == 4:
                    geom = packed(v)
            props = {keys[tags[k]]: values[tags[k + 1]] for k in range(0, len(tags), 2)}
            x = y = i = 0
            parts = []
            while i < len(geom):
                cmd, count = geom[i] & 7, geom[i] >> 3
                i += 1
                for _ in range(count if cmd in (1, 2) else 0):
                    x += zigzag(geom[i])
                    y += zigzag(geom[i + 1])
                    i += 2
                    if cmd == 1:
                        parts.append([])
                    parts[-1].append((x, y))
            for p in parts:
                out.append((props.get("index") is True, p))
    return out


def get(url):
    with urllib.request.urlopen(url, timeout=600) as r:
        return r.read()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", default="http://127.0.0.1:8080")
    ap.add_argument("--world", default="tienshan")
    ap.add_argument("--z", type=int, default=13)
    ap.add_argument("--x", type=int, default=5792)
    ap.add_argument("--y", type=int, default=3023)
    ap.add_argument("--n", type=int, default=2)
    ap.add_argument("--out", default="tests/pictures/contours.png")
    a = ap.parse_args()
    n = a.n
    img = Image.new("RGB", (256 * n, 256 * n))
    for dy in range(n):
        for dx in range(n):
            x, y = a.x + dx, a.y + dy
            shade = Image.open(io.BytesIO(get(f"{a.base}/tiles/{a.world}/hillshade/{a.z}/{x}/{y}.png")))
            img.paste(shade.convert("RGB"), (256 * dx, 256 * dy))
    draw = ImageDraw.Draw(img)
    for dy in range(n):
        for dx in range(n):
            x, y = a.x + dx, a.y + dy
            mvt = get(f"{a.base}/tiles/{a.world}/contours/{a.z}/{x}/{y}.mvt")
            # Each tile's lines clipped to its own square, so a seam would show as a jump.
            draw_clip = Image.new("RGBA", img.size, (0, 0, 0, 0))
            d2 = ImageDraw.Draw(draw_clip)
            for index, pts in lines(mvt):
                xy = [(256 * dx + px / 16.0, 256 * dy + py / 16.0) for px, py in pts]
                d2.line(xy, fill=(120, 50, 10, 255) if index else (150, 80, 30, 230),
                        width=2 if index else 1)
            mask = Image.new("L", img.size, 0)
            ImageDraw.Draw(mask).rectangle([256 * dx, 256 * dy, 256 * dx + 255, 256 * dy + 255], fill=255)
            img.paste(draw_clip, (0, 0), Image.composite(draw_clip, Image.new("RGBA", img.size), mask))
    for k in range(1, n):
        for t in range(0, 256 * n, 6):
            draw.point((256 * k, t), fill=(40, 40, 200))
            draw.point((t, 256 * k), fill=(40, 40, 200))
    img.save(a.out)
    print(a.out)


if __name__ == "__main__":
    main()
