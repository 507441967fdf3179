#!/usr/bin/env bash
# Installs the web map's front-end dependencies from the npm registry, exactly as pinned in
# package-lock.json (`npm ci`): MapLibre GL JS, which terrasynth serves at /vendor/maplibre-gl/
# from node_modules/maplibre-gl/dist, and playwright-core for the browser test. Needs node and npm.
# Skips the install when node_modules was installed after the last change of package-lock.json
# (pass --force to reinstall).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
command -v npm >/dev/null || {
    echo "install_web: npm is not installed (apt-get install nodejs npm)" >&2
    exit 1
}
if [[ "${1:-}" != "--force" && node_modules/.package-lock.json -nt package-lock.json ]]; then
    echo "install_web: node_modules is up to date with package-lock.json"
    exit 0
fi
npm ci --no-audit --no-fund
