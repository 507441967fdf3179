#!/usr/bin/env python3
"""Abuse scenarios against a running terrasynth server on loopback (driven by scripts/abuse.sh).

One scenario per run; while it runs, a prober GETs /healthz on a fresh connection every 25 ms and a
sampler reads the server's VmRSS every 100 ms. Prints one JSON object: the scenario's own figures,
/healthz latencies (p50, p99, max, failures), the peak RSS, and the lines (and ERROR lines) the
server logged meanwhile. Standard library only. Every scenario is bounded by --seconds.

Scenarios:
  slowloris  N trickling connections (one header line a second, reconnecting when closed) and M
             connections that say nothing (reconnecting when closed)
  metrics    requests with random method tokens on keep-alive connections; /metrics size before
             and after
  overload   C concurrent clients requesting cold zoom-16 tiles of every layer, each giving up after
             5 s; CPU seconds the server spends in the 10 s after the clients left
  upload     4 parallel uploads of a deflate GeoTIFF bomb (8192x8192 zeros in ~260 KB) in a loop,
             and one chunked body of zeros streamed past max_body_mb
  bomb-file  writes the bomb GeoTIFF to --out (no server needed)
"""

import argparse
import asyncio
import json
import multiprocessing
import os
import random
import socket
import struct
import time
import zlib

# --- measurements -------------------------------------------------------------------------


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / ticks


def log_counts(path):
    lines = errors = 0
    with open(path, "rb") as f:
        for line in f:
            lines += 1
            if b" ERROR " in line or b"ERROR" in line[:64]:
                errors += 1
    return lines, errors


def percentile(values, p):
    if not values:
        return None
    s = sorted(values)
    k = min(len(s) - 1, int(round(p / 100.0 * (len(s) - 1))))
    return s[k]


def monitor(host, port, pid, stop, out):
    """The /healthz prober and the RSS sampler, run in their own process (so that the load the
    scenario generates in this one does not delay the probes)."""
    latencies, failures, peak = [], 0, 0.0
    req = f"GET /healthz HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode()
    next_sample = 0.0
    while not stop.is_set():
        now = time.monotonic()
        if now >= next_sample:
            try:
                peak = max(peak, rss_mb(pid))
            except OSError:
                pass
            next_sample = now + 0.1
        t0 = time.perf_counter()
        try:
            with socket.create_connection((host, port), timeout=2.0) as s:
                s.sendall(req)
                data = b""
                while True:
                    chunk = s.recv(4096)
                    if not chunk:
                        break
                    data += chunk
            if data.startswith(b"HTTP/1.1 200"):
                latencies.append((time.perf_counter() - t0) * 1000.0)
            else:
                failures += 1
        except OSError:
            failures += 1
        time.sleep(0.025)
    out.put(
        {
            "healthz_probes": len(latencies) + failures,
            "healthz_failures": failures,
            "healthz_p50_ms": round(percentile(latencies, 50) or -1, 2),
            "healthz_p99_ms": round(percentile(latencies, 99) or -1, 2),
            "healthz_max_ms": round(max(latencies) if latencies else -1, 2),
            "peak_rss_mb": round(peak, 1),
        }
    )


class Monitor:
    """Runs [`monitor`] in a child process for the duration of a `with` block."""

    def __init__(self, host, port, pid):
        self.stop = multiprocessing.Event()
        self.out = multiprocessing.Queue()
        self.proc = multiprocessing.Process(
            target=monitor, args=(host, port, pid, self.stop, self.out), daemon=True
        )
        self.result = {}

    def __enter__(self):
        self.proc.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.result = self.out.get(timeout=30)
        self.proc.join(timeout=5)

    def figures(self):
        return self.result


# --- HTTP helpers ---------------------------------------------------------------------------


async def read_response(reader):
    """Reads one HTTP/1.1 response; returns (status, body)."""
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split()[1])
    length = 0
    chunked = False
    for line in lines[1:]:
        k, _, v = line.partition(":")
        if k.lower() == "content-length":
            length = int(v.strip())
        elif k.lower() == "transfer-encoding" and "chunked" in v.lower():
            chunked = True
    if chunked:
        body = b""
        while True:
            size = int((await reader.readuntil(b"\r\n")).strip().split(b";")[0], 16)
            if size == 0:
                await reader.readuntil(b"\r\n")
                break
            body += await reader.readexactly(size)
            await reader.readexactly(2)
        return status, body
    return status, await reader.readexactly(length)


def http_get(host, port, path):
    with socket.create_connection((host, port), timeout=30) as s:
        s.sendall(f"GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
        data = b""
        while True:
            c = s.recv(65536)
            if not c:
                break
            data += c
    head, _, body = data.partition(b"\r\n\r\n")
    return head, body


# --- scenarios ------------------------------------------------------------------------------


async def slowloris(a, deadline):
    stats = {"trickle_connections": 0, "idle_connections": 0, "closed_by_server": 0}

    async def trickler(i):
        while time.monotonic() < deadline:
            try:
                r, w = await asyncio.open_connection(a.host, a.port)
            except OSError:
                await asyncio.sleep(0.5)
                continue
            stats["trickle_connections"] += 1
            try:
                w.write(b"GET /healthz HTTP/1.1\r\nHost: x\r\n")
                await w.drain()
                while time.monotonic() < deadline:
                    await asyncio.sleep(1.0)
                    w.write(f"X-Trickle-{i}: {random.random()}\r\n".encode())
                    await w.drain()
                    if r.at_eof():
                        break
                else:
                    w.close()
                    return
            except OSError:
                pass
            stats["closed_by_server"] += 1
            w.close()

    async def mute():
        while time.monotonic() < deadline:
            try:
                r, w = await asyncio.open_connection(a.host, a.port)
            except OSError:
                await asyncio.sleep(0.5)
                continue
            stats["idle_connections"] += 1
            try:
                left = deadline - time.monotonic()
                data = await asyncio.wait_for(r.read(1), timeout=max(0.1, left))
                if data == b"":
                    stats["closed_by_server"] += 1
            except asyncio.TimeoutError:
                pass
            except OSError:
                stats["closed_by_server"] += 1
            w.close()

    await asyncio.gather(
        *[trickler(i) for i in range(a.trickle)], *[mute() for _ in range(a.idle)]
    )
    return stats


async def metrics_flood(a, deadline):
    _, before = http_get(a.host, a.port, "/metrics")
    sent = {"n": 0}

    async def worker(k):
        r, w = await asyncio.open_connection(a.host, a.port)
        while time.monotonic() < deadline and sent["n"] < a.requests:
            sent["n"] += 1
            m = f"M{random.randrange(1 << 30)}{k}"
            path = random.choice(["/healthz", f"/x/{random.randrange(1 << 30)}"])
            w.write(f"{m} {path} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
            await w.drain()
            try:
                await read_response(r)
            except (asyncio.IncompleteReadError, OSError):
                r, w = await asyncio.open_connection(a.host, a.port)
        w.close()

    await asyncio.gather(*[worker(k) for k in range(8)])
    _, after = http_get(a.host, a.port, "/metrics")
    return {
        "requests": sent["n"],
        "metrics_bytes_before": len(before),
        "metrics_bytes_after": len(after),
    }


def cold_urls(n):
    """Distinct zoom-16 tiles over the Kyrgyz Ala-Too, every layer, in a random order."""
    import math

    z = 16
    lon0, lat0 = 74.2, 42.4
    x0 = int((lon0 + 180.0) / 360.0 * (1 << z))
    y0 = int((1.0 - math.asinh(math.tan(math.radians(lat0))) / math.pi) / 2.0 * (1 << z))
    layers = [
        "elevation/{}.png",
        "hillshade/{}.png",
        "color/{}.png",
        "vegetation/{}.png",
        "drainage/{}.png",
        "splat/{}.png",
    ]
    rng = random.Random(14)
    seen, out = set(), []
    while len(out) < n:
        # 128 × 64 tiles: 74.2–74.9°E, 42.15–42.4°N, well inside the world.
        x = x0 + rng.randrange(128)
        y = y0 + rng.randrange(64)
        layer = rng.choice(layers)
        key = (x, y, layer)
        if key in seen:
            continue
        seen.add(key)
        out.append(f"/tiles/tienshan/" + layer.format(f"{z}/{x}/{y}"))
    return out


async def overload(a, deadline):
    urls = cold_urls(40000)
    next_url = {"i": 0}
    statuses = {}

    async def client():
        while time.monotonic() < deadline:
            url = urls[next_url["i"] % len(urls)]
            next_url["i"] += 1
            w = None
            try:
                r, w = await asyncio.open_connection(a.host, a.port)
                w.write(f"GET {url} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n".encode())
                await w.drain()
                left = max(0.1, min(5.0, deadline - time.monotonic()))
                st, _ = await asyncio.wait_for(read_response(r), timeout=left)
                statuses[str(st)] = statuses.get(str(st), 0) + 1
            except asyncio.TimeoutError:
                statuses["gave_up"] = statuses.get("gave_up", 0) + 1
            except (OSError, asyncio.IncompleteReadError):
                statuses["io_error"] = statuses.get("io_error", 0) + 1
                await asyncio.sleep(0.05)
            finally:
                if w is not None:
                    w.close()

    await asyncio.gather(*[client() for _ in range(a.clients)])
    return {"responses": statuses}


def bomb_tiff(side=8192, rows_per_strip=64):
    """A GeoTIFF of side x side float32 zeros, deflate-compressed strips (EPSG:4326)."""
    strips = side // rows_per_strip
    strip = zlib.compress(bytes(side * rows_per_strip * 4), 9)
    entries = []  # (tag, type, count, value bytes)

    def short(tag, v):
        entries.append((tag, 3, 1, struct.pack("<HH", v, 0)))

    def long_(tag, v):
        entries.append((tag, 4, 1, struct.pack("<I", v)))

    data = bytearray()
    header_size = 8
    # Layout: header, strips, then arrays, then the IFD.
    offsets = []
    body = bytearray()
    for _ in range(strips):
        offsets.append(header_size + len(body))
        body += strip
    if len(body) % 2:
        body.append(0)
    extra = bytearray()
    base = header_size + len(body)

    def array(fmt, values):
        off = base + len(extra)
        extra.extend(struct.pack("<" + fmt * len(values), *values))
        if len(extra) % 2:
            extra.append(0)
        return off

    so = array("I", offsets)
    sbc = array("I", [len(strip)] * strips)
    scale = array("d", [1.0 / 3600, 1.0 / 3600, 0.0])
    tie = array("d", [0.0, 0.0, 0.0, 74.0, 43.0, 0.0])
    geokeys = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326]
    gk = array("H", geokeys)
    long_(256, side)
    long_(257, side)
    short(258, 32)
    short(259, 8)
    short(262, 1)
    entries.append((273, 4, strips, struct.pack("<I", so)))
    short(277, 1)
    long_(278, rows_per_strip)
    entries.append((279, 4, strips, struct.pack("<I", sbc)))
    short(284, 1)
    short(339, 3)
    entries.append((33550, 12, 3, struct.pack("<I", scale)))
    entries.append((33922, 12, 6, struct.pack("<I", tie)))
    entries.append((34735, 3, len(geokeys), struct.pack("<I", gk)))
    entries.sort()
    ifd_off = base + len(extra)
    data += b"II*\0" + struct.pack("<I", ifd_off)
    data += body + extra
    data += struct.pack("<H", len(entries))
    for tag, typ, count, value in entries:
        data += struct.pack("<HHI", tag, typ, count) + value
    data += struct.pack("<I", 0)
    return bytes(data)


async def upload(a, deadline):
    bomb = bomb_tiff()
    statuses = {}
    chunked = {}

    def count(d, k):
        d[str(k)] = d.get(str(k), 0) + 1

    async def post_bomb(k):
        n = 0
        while time.monotonic() < deadline:
            n += 1
            w = None
            try:
                r, w = await asyncio.open_connection(a.host, a.port)
                w.write(
                    (
                        f"POST /admin/exemplars?name=bomb{k}x{n} HTTP/1.1\r\nHost: x\r\n"
                        f"Authorization: Bearer {a.token}\r\nContent-Type: image/tiff\r\n"
                        f"Content-Length: {len(bomb)}\r\nConnection: close\r\n\r\n"
                    ).encode()
                    + bomb
                )
                await w.drain()
                st, body = await asyncio.wait_for(read_response(r), timeout=120)
                count(statuses, st)
                if st == 201:
                    # Remove it again, so that the loop measures uploads, not the store growing.
                    ident = json.loads(body)["id"]
                    r2, w2 = await asyncio.open_connection(a.host, a.port)
                    w2.write(
                        (
                            f"DELETE /admin/exemplars/{ident} HTTP/1.1\r\nHost: x\r\n"
                            f"Authorization: Bearer {a.token}\r\nConnection: close\r\n\r\n"
                        ).encode()
                    )
                    await w2.drain()
                    await read_response(r2)
                    w2.close()
                elif st == 503:
                    await asyncio.sleep(0.2)
            except (OSError, asyncio.IncompleteReadError, asyncio.TimeoutError) as e:
                count(statuses, type(e).__name__)
            finally:
                if w is not None:
                    w.close()

    async def post_chunked():
        w = None
        sent = 0
        try:
            r, w = await asyncio.open_connection(a.host, a.port)
            w.write(
                (
                    "POST /admin/exemplars?name=endless HTTP/1.1\r\nHost: x\r\n"
                    f"Authorization: Bearer {a.token}\r\nContent-Type: image/tiff\r\n"
                    "Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n"
                ).encode()
            )
            chunk = b"%x\r\n" % (1 << 20) + bytes(1 << 20) + b"\r\n"
            reading = asyncio.ensure_future(read_response(r))
            try:
                while not reading.done() and sent < (1 << 30) and time.monotonic() < deadline:
                    w.write(chunk)
                    await w.drain()
                    sent += 1 << 20
            except OSError:
                pass  # the server answered and closed: read its answer
            st, _ = await asyncio.wait_for(reading, timeout=30)
            chunked["status"] = st
        except (OSError, asyncio.IncompleteReadError, asyncio.TimeoutError) as e:
            chunked["status"] = type(e).__name__
        finally:
            chunked["mib_sent_before_the_answer"] = sent >> 20
            if w is not None:
                w.close()

    # The endless body first, alone (with every upload slot taken it would be refused at once),
    # then the bombs for the rest of the time.
    await post_chunked()
    await asyncio.gather(*[post_bomb(k) for k in range(4)])
    return {
        "bomb_bytes": len(bomb),
        "bomb_responses": statuses,
        "chunked_body": chunked,
    }


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("scenario", choices=["slowloris", "metrics", "overload", "upload", "bomb-file"])
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=False, default=0)
    p.add_argument("--pid", type=int)
    p.add_argument("--log")
    p.add_argument("--token", default="")
    p.add_argument("--seconds", type=float, default=20)
    p.add_argument("--trickle", type=int, default=600)
    p.add_argument("--idle", type=int, default=1100)
    p.add_argument("--requests", type=int, default=20000)
    p.add_argument("--clients", type=int, default=400)
    p.add_argument("--out")
    a = p.parse_args()
    if a.host not in ("127.0.0.1", "localhost", "::1"):
        raise SystemExit("abuse.py only targets loopback")
    if a.scenario == "bomb-file":
        with open(a.out, "wb") as f:
            f.write(bomb_tiff())
        return
    run = {"slowloris": slowloris, "metrics": metrics_flood, "overload": overload, "upload": upload}[
        a.scenario
    ]
    lines0, errors0 = log_counts(a.log)
    t0 = time.monotonic()
    with Monitor(a.host, a.port, a.pid) as mon:
        figures = asyncio.run(run(a, t0 + a.seconds))
    elapsed = time.monotonic() - t0
    out = {"scenario": a.scenario, "seconds": round(elapsed, 1)}
    out.update(figures)
    out.update(mon.figures())
    if a.scenario == "overload":
        # CPU the server spends after every client left (abandoned work must stop).
        c0 = cpu_seconds(a.pid)
        time.sleep(10)
        out["cpu_seconds_in_10s_after"] = round(cpu_seconds(a.pid) - c0, 2)
    lines1, errors1 = log_counts(a.log)
    out["log_lines"] = lines1 - lines0
    out["error_lines"] = errors1 - errors0
    print(json.dumps(out))


if __name__ == "__main__":
    main()
