#!/usr/bin/env bash
# Architecture check (run by .ci/run): the layers stay layered.
#
# 1. Dependency trees: the numeric pipeline (terrasynth-core) has no async runtime, HTTP stack or
#    cache crate anywhere in its dependency tree — normal, build and dev edges, every depth
#    (tokio, axum, hyper, tower, moka); the tiles and store crates have no HTTP framework (axum,
#    hyper). The compiler already forbids a lower crate from importing a higher one (Cargo has
#    no dependency cycles); this guards what the lower crates pull in.
# 2. Module cycles: inside each crate, no module imports one that imports it back (directly or
#    through others), counting `use crate::a`, `crate::a::` paths and `super::` imports between
#    top-level modules; and in the root package the command line (`cli`) never imports the
#    server, nor the server the command line.
set -euo pipefail
cd "$(dirname "$0")/.."
status=0

banned_in() {
    local pkg=$1 edges=$2 pattern=$3
    local found
    found=$(cargo tree -p "$pkg" -e "$edges" --prefix none --format '{p}' 2>/dev/null |
        awk '{print $1}' | sort -u | grep -E "^(${pattern})\$" || true)
    if [ -n "$found" ]; then
        echo "check_layers: $pkg depends on: $(echo "$found" | tr '\n' ' ')" >&2
        status=1
    else
        echo "check_layers: $pkg ($edges): none of ${pattern//|/, }"
    fi
}

banned_in terrasynth-core normal,build,dev 'tokio|axum|axum-core|hyper|hyper-util|tower|tower-http|tower-layer|tower-service|moka'
banned_in terrasynth-tiles normal,build 'axum|axum-core|hyper|hyper-util|tower-http'
banned_in terrasynth-store normal,build 'axum|axum-core|hyper|hyper-util|tower-http'

python3 - <<'PY' || status=1
import os, re, sys

def modules(src):
    """Top-level module of every .rs file under src, and its text."""
    out = {}
    for root, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            path = os.path.join(root, f)
            rel = os.path.relpath(path, src)
            parts = rel[:-3].split(os.sep)
            top = parts[0]
            if top in ("lib", "main"):
                continue
            out.setdefault(top, "")
            out[top] += open(path, encoding="utf-8").read()
    return out

def edges(mods):
    graph = {m: set() for m in mods}
    for m, text in mods.items():
        # Strip comments so that doc links do not count.
        code = "\n".join(l.split("//")[0] for l in text.splitlines())
        code = re.sub(r"#\[cfg\(test\)\]\s*mod tests\s*\{.*", "", code, flags=re.S)
        for target in re.findall(r"\bcrate::([a-z_][a-z0-9_]*)", code):
            if target in mods and target != m:
                graph[m].add(target)
        # `super::x` from a top-level module file names a sibling module.
        for target in re.findall(r"\bsuper::([a-z_][a-z0-9_]*)", code):
            if target in mods and target != m:
                graph[m].add(target)
    return graph

def cycle(graph):
    state = {}
    stack = []
    def visit(n):
        state[n] = 1
        stack.append(n)
        for t in sorted(graph[n]):
            if state.get(t) == 1:
                return stack[stack.index(t):] + [t]
            if t not in state:
                c = visit(t)
                if c:
                    return c
        stack.pop()
        state[n] = 2
        return None
    for n in sorted(graph):
        if n not in state:
            c = visit(n)
            if c:
                return c
    return None

bad = False
crates = {"terrasynth": "src"}
for c in sorted(os.listdir("crates")):
    if os.path.isdir(os.path.join("crates", c, "src")):
        crates[c] = os.path.join("crates", c, "src")
for name, src in crates.items():
    graph = edges(modules(src))
    c = cycle(graph)
    if c:
        print(f"check_layers: module cycle in {name}: {' -> '.join(c)}", file=sys.stderr)
        bad = True
    else:
        print(f"check_layers: {name}: {len(graph)} top-level modules, no cycle")
root = edges(modules("src"))
for a, b in (("cli", "server"), ("server", "cli")):
    if b in root.get(a, set()):
        print(f"check_layers: `{a}` imports `{b}`", file=sys.stderr)
        bad = True
# The server's submodules: admin handlers never reach into the command line either.
for root_dir, _, files in os.walk("src/server"):
    for f in files:
        text = open(os.path.join(root_dir, f), encoding="utf-8").read()
        if re.search(r"\bcrate::cli\b", text):
            print(f"check_layers: {os.path.join(root_dir, f)} imports the command line", file=sys.stderr)
            bad = True
sys.exit(1 if bad else 0)
PY
exit $status
