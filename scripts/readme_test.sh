#!/usr/bin/env bash
# The README's shell examples, run as written (part of .ci/run): the "Tile server", "Landscape
# layers", "Command line" and "Admin API" blocks, in that order (the admin flow uploads the
# crop the command-line examples cut), against a live server with a fresh store in a
# temporary directory. Every curl's status must be 2xx and its content type the one its URL
# promises (PNG, EXR, JSON, Prometheus text); every command must succeed.
#
# What is adapted, and only this: the server's address (a free port instead of 8080), the
# binary (`cargo run --release --` and `./target/release/terrasynth` become --bin, so that one
# build serves the whole suite), and the admin example's `serve &` line (the server is already
# running with the same token). Outputs go to target/examples/, which git ignores.
#
# Usage: scripts/readme_test.sh [--bin PATH]   (default: target/release/terrasynth, built if absent)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cd "$(dirname "$0")/.."
root=$PWD
bin=target/release/terrasynth
while [ $# -gt 0 ]; do
    case $1 in
        --bin) bin=$2; shift 2 ;;
        *) echo "usage: $0 [--bin PATH]" >&2; exit 2 ;;
    esac
done
[ -x "$bin" ] || cargo build --release --quiet
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")

work=$(mktemp -d)
server_pid=
cleanup() {
    [ -n "$server_pid" ] && kill "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
    rm -rf "$work"
}
trap cleanup EXIT

port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export TERRASYNTH_ADMIN_TOKEN=change-me
export TERRASYNTH_STORE_DIR=$work/store
"$bin" serve --listen "127.0.0.1:$port" >"$work/server.log" 2>&1 &
server_pid=$!
echo "readme-test: server on port $port (log: $work/server.log)"
wait_until_up "http://127.0.0.1:$port/healthz" "$server_pid" 600 "$work/server.log" ||
    { echo "readme-test: the server did not become healthy" >&2; exit 1; }

# The blocks, adapted as described above, one file each.
python3 - "$work" "$port" "$bin" <<'PY'
import re, sys
work, port, binary = sys.argv[1:]
text = open("README.md", encoding="utf-8").read()
wanted = ["Tile server", "Landscape layers", "Command line", "Admin API"]
blocks = {}
heading = None
for m in re.finditer(r"^## ([^\n]*)$|^```sh\n(.*?)^```$", text, flags=re.M | re.S):
    if m.group(1) is not None:
        heading = m.group(1)
    else:
        for w in wanted:
            if heading and heading.startswith(w):
                blocks.setdefault(w, []).append(m.group(2))
for i, w in enumerate(wanted):
    if w not in blocks:
        sys.exit(f"readme-test: no shell block under '## {w}'")
    body = "\n".join(blocks[w])
    body = body.replace("http://127.0.0.1:8080", f"http://127.0.0.1:{port}")
    body = body.replace("cargo run --release --", binary)
    body = re.sub(r"^\./target/release/terrasynth serve &.*$", ": the server is already running",
                  body, flags=re.M)
    if "terrasynth serve" in body or "8080" in body:
        sys.exit(f"readme-test: '{w}' still names a server of its own")
    open(f"{work}/block{i}.sh", "w").write(body)
    print(f"readme-test: '{w}': {len(blocks[w])} block(s), {body.count(chr(10)) + 1} lines")
PY

# Every curl appends "status<TAB>method<TAB>url<TAB>content-type" to the report; a failure stops
# the block.
cat >"$work/prelude.sh" <<EOF
set -euo pipefail
curl() {
    local out
    out=\$(command curl -sS --fail-with-body -w '\n%{http_code}\t%{method}\t%{url_effective}\t%{content_type}' "\$@") || {
        echo "readme-test: curl \$* failed: \$out" >&2; return 1; }
    printf '%s\n' "\${out##*$'\n'}" >>"$work/report"
    local body=\${out%$'\n'*}
    [ "\$body" = "\$out" ] || [ -z "\$body" ] || printf '%s\n' "\$body"
}
EOF
: >"$work/report"
for f in "$work"/block*.sh; do
    echo "readme-test: running $(basename "$f")"
    (cd "$root" && timeout 1200 bash -c "source '$work/prelude.sh'; source '$f'") >"$f.out" 2>&1 || {
        tail -40 "$f.out"
        echo "readme-test: FAILED in $(basename "$f")" >&2
        exit 1
    }
done

python3 - "$work/report" <<'PY'
import sys
bad, n = [], 0
for line in open(sys.argv[1]):
    parts = line.rstrip("\n").split("\t")
    if len(parts) != 4:
        continue
    status, method, url, ctype = parts
    n += 1
    path = url.split("?")[0]
    if not status.startswith("2"):
        bad.append(f"{status} {method} {url}")
        continue
    if method == "DELETE" or status == "204":
        continue
    want = ("image/png" if path.endswith(".png") else "image/x-exr" if path.endswith(".exr")
            else "text/plain" if path.endswith("/metrics") else "application/json")
    if not ctype.startswith(want):
        bad.append(f"{method} {url}: content type {ctype!r}, expected {want}")
if n < 20:
    bad.append(f"only {n} requests ran")
for b in bad:
    print("readme-test: FAIL", b, file=sys.stderr)
print(f"readme-test: {n} requests checked")
sys.exit(1 if bad else 0)
PY
echo "readme-test: passed"
