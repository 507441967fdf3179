#!/usr/bin/env bash
# The gradient amplifier's measurements (issue #20), release build:
#  1. the held-out realism suite of scripts/realism.sh with a gradient tile set built from the
#     default exemplar with the suite's windows kept out (table: $OUT/realism/table.md);
#  2. the gradient-tile paper's flood-extent experiment: 128² crops of the real Tien Shan grid,
#     box-down-sampled by 8, 16 and 32 and amplified back (3, 4, 5 levels); the share of cells
#     holding water at steady state (`eval`'s flood_extent_pct) of the result, per crop and mean
#     ($OUT/flood.md).
# Usage: scripts/gradient_eval.sh    OUT=dir (default target/gradient-eval), BIN=terrasynth binary
set -euo pipefail
cd "$(dirname "$0")/.."

OUT=${OUT:-target/gradient-eval}
T=config/data/tienshan_west_gebco15s.tif
mkdir -p "$OUT/realism" "$OUT/flood"
if [[ -z "${BIN:-}" ]]; then
    cargo build --release --quiet
    BIN=target/release/terrasynth
fi

ex=()
for w in 1600,600,1024,512 1280,1280,1024,512 256,0,1024,512; do ex+=(--exclude "$w"); done
start=$(date +%s.%N)
"$BIN" dictionary build --kind gradient --default "${ex[@]}" --output "$OUT/heldout.grad"
echo "held-out gradient tile set built in $(echo "$(date +%s.%N) - $start" | bc) s" >&2

DICT="$OUT/heldout.grad" OUT="$OUT/realism" BIN="$BIN" scripts/realism.sh

# Flood extent at 128² (crops inside the held-out windows).
CROPS=("talas 1700,700" "kyrgyz 2200,800" "alai 1400,1400" "pamir 1900,1500" "karatau 400,100" "steppe 900,200")
for entry in "${CROPS[@]}"; do
    read -r name at <<<"$entry"
    "$BIN" crop --input "$T" --window "$at,128,128" --output "$OUT/flood/$name.truth.tif" >/dev/null
    for f in 8 16 32; do
        levels=$(python3 -c "import math; print(int(math.log2($f)))")
        "$BIN" crop --input "$T" --window "$at,128,128" --down "$f" --output "$OUT/flood/$name.$f.low.tif" >/dev/null
        "$BIN" amplify --dictionary "$OUT/heldout.grad" --input "$OUT/flood/$name.$f.low.tif" \
            --levels "$levels" --output "$OUT/flood/$name.$f.out.tif" >/dev/null
        "$BIN" eval --truth "$OUT/flood/$name.truth.tif" --input "$OUT/flood/$name.$f.low.tif" \
            --output "$OUT/flood/$name.$f.out.tif" >"$OUT/flood/$name.$f.json"
    done
done
names=()
for entry in "${CROPS[@]}"; do read -r name _ <<<"$entry"; names+=("$name"); done
python3 - "$OUT/flood" "${names[@]}" <<'PY' | tee "$OUT/flood.md"
import json, sys
out, names = sys.argv[1], sys.argv[2:]
print("| scale factor | " + " | ".join(names) + " | mean | truth mean |")
print("|---" * (len(names) + 3) + "|")
for f in (8, 16, 32):
    r = [json.load(open(f"{out}/{n}.{f}.json")) for n in names]
    v = [x["amplified"]["flood_extent_pct"] for x in r]
    t = [x["truth"]["flood_extent_pct"] for x in r]
    print(f"| {f} | " + " | ".join(f"{a:.1f} %" for a in v)
          + f" | {sum(v)/len(v):.1f} % | {sum(t)/len(t):.1f} % |")
PY
