#!/usr/bin/env bash
# Compact terrains on held-out real terrain: PSNR against storage for sparsity 1, 2, 4 and 8 with
# a constrained (k-medoids: real patches) and a K-SVD dictionary, beside plain baselines at the
# same storage (box down-sampling + bicubic, deflate of the quantised grid) and the inverse
# procedural modelling figures (Perlin-only and ridged-only atoms). Writes target/compact/
# table.md and the JSON of every run. A measurement, not a test: not in CI.
#
# The crops (512², from the committed Tien Shan grid) are kept out of every dictionary with
# --exclude. Dictionaries: 256 atoms of 16² cells, stride 8; K-SVD: 10 rounds, learned with the
# sparsity it is used with. Takes about 15 minutes on the 2-core development machine.
#
# Usage: scripts/compact.sh [--no-build]
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=target/compact
mkdir -p "$OUT"
[[ "${1:-}" == "--no-build" ]] || cargo build --release --quiet
B=${TERRASYNTH_BIN:-target/release/terrasynth}
T=config/data/tienshan_west_gebco15s.tif
CROPS=("1600,600" "900,1300")
EXCLUDE=()
for c in "${CROPS[@]}"; do EXCLUDE+=(--exclude "$c,512,512"); done
for c in "${CROPS[@]}"; do
    n=${c/,/_}
    [[ -f "$OUT/crop_$n.tif" ]] || "$B" crop --input "$T" --window "$c,512,512" --output "$OUT/crop_$n.tif" >/dev/null
done
[[ -f "$OUT/medoids.dict" ]] || "$B" dictionary build --default "${EXCLUDE[@]}" --output "$OUT/medoids.dict"
for s in 1 2 4 8; do
    [[ -f "$OUT/ksvd$s.dict" ]] || "$B" dictionary build --default "${EXCLUDE[@]}" \
        --learning ksvd:10 --sparsity "$s" --output "$OUT/ksvd$s.dict"
done
run() { # name crop args...
    local name=$1 crop=$2; shift 2
    "$B" compress --input "$OUT/crop_$crop.tif" --coef-quantum 32 --output "$OUT/$name.sct" "$@" \
        >"$OUT/$name.json"
}
for c in "${CROPS[@]}"; do
    n=${c/,/_}
    for s in 1 2 4 8; do
        run "medoids_s${s}_$n" "$n" --dictionary "$OUT/medoids.dict" --sparsity "$s"
        run "ksvd_s${s}_$n" "$n" --dictionary "$OUT/ksvd$s.dict" --sparsity "$s"
    done
    for k in perlin ridged; do
        run "${k}_s1_$n" "$n" --analytic "$k" --analytic-atoms 256 --sparsity 1
        run "${k}_s4_$n" "$n" --analytic "$k" --analytic-atoms 256 --sparsity 4
    done
done
python3 - "$OUT" "${CROPS[@]}" <<'PY'
import json, sys, os
out, crops = sys.argv[1], [c.replace(",", "_") for c in sys.argv[2:]]
def load(name):
    return json.load(open(os.path.join(out, name + ".json")))
lines = ["| crop | atoms | s | PSNR dB | storage, shared dictionary | storage with the atoms | bicubic at ≥ that storage | deflate at that storage |",
         "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
for c in crops:
    for kind in ["medoids", "ksvd"]:
        for s in [1, 2, 4, 8]:
            d = load(f"{kind}_s{s}_{c}")
            b = d["baselines"]
            bic = "—" if b["bicubic_psnr_db"] is None else f"{b['bicubic_psnr_db']:.1f} dB ({100*b['bicubic_storage_ratio']:.2f} %, ×{b['bicubic_factor']})"
            lines.append(f"| {c.replace('_', ',')} | {'constrained (k-medoids)' if kind == 'medoids' else 'K-SVD'} | {s} | {d['psnr_db']:.2f} | {100*d['storage_ratio_shared_dictionary']:.2f} % | {100*d['storage_ratio']:.2f} % | {bic} | {b['deflate_psnr_db']:.1f} dB |")
lines.append("")
lines.append("| crop | analytic atoms only | s | PSNR dB | storage, shared dictionary |")
lines.append("| --- | --- | ---: | ---: | ---: |")
for c in crops:
    for k in ["perlin", "ridged"]:
        for s in [1, 4]:
            d = load(f"{k}_s{s}_{c}")
            lines.append(f"| {c.replace('_', ',')} | {k} | {s} | {d['psnr_db']:.2f} | {100*d['storage_ratio_shared_dictionary']:.2f} % |")
open(os.path.join(out, "table.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
