#!/usr/bin/env bash
# The held-out realism suite (issue #12): six 512² crops of the committed Tien Shan grid, from three
# windows kept out of the dictionary (high ranges, the Pamir-Alai, low hills and plains), each
# resampled to square cells as the dictionary's exemplar is (`crop --square`), box-down-sampled
# ×4 and amplified back by 2 levels, evaluated against the truth with the bicubic and bicubic +
# fBm baselines. Writes, under $OUT (default target/realism):
#   heldout.dict, per crop: truth/low/out GeoTIFFs, eval JSON and a hillshade picture
#   (truth | bicubic | bicubic + fBm | output), and table.md (per crop and mean).
#
# Usage: scripts/realism.sh [extra amplify arguments...]
#   OUT=dir           output directory (default target/realism)
#   DICT_ARGS="..."   extra `dictionary build` arguments (e.g. "--atoms 1024")
#   REUSE_DICT=1      keep an existing $OUT/heldout.dict
#   DICT=file         use this held-out dictionary instead of building one
#   BIN=path          terrasynth binary (default: cargo build --release, target/release/terrasynth)
set -euo pipefail
cd "$(dirname "$0")/.."

OUT=${OUT:-target/realism}
T=config/data/tienshan_west_gebco15s.tif
mkdir -p "$OUT"
if [[ -z "${BIN:-}" ]]; then
    cargo build --release --quiet
    BIN=target/release/terrasynth
fi

# Windows kept out of the dictionary (COL,ROW,WIDTH,HEIGHT) and the crops cut from them.
WINDOWS=(1600,600,1024,512 1280,1280,1024,512 256,0,1024,512)
CROPS=(
    "talas 1600,600,512,512"
    "kyrgyz 2112,600,512,512"
    "alai 1280,1280,512,512"
    "pamir 1792,1280,512,512"
    "karatau 256,0,512,512"
    "steppe 768,0,512,512"
)

if [[ -n "${DICT:-}" ]]; then
    cp "$DICT" "$OUT/heldout.dict"
elif [[ -z "${REUSE_DICT:-}" || ! -f "$OUT/heldout.dict" ]]; then
    ex=()
    for w in "${WINDOWS[@]}"; do ex+=(--exclude "$w"); done
    # shellcheck disable=SC2086
    "$BIN" dictionary build --default "${ex[@]}" ${DICT_ARGS:-} --output "$OUT/heldout.dict"
fi

for entry in "${CROPS[@]}"; do
    read -r name window <<<"$entry"
    "$BIN" crop --input "$T" --window "$window" --square --output "$OUT/$name.truth.tif" >/dev/null
    "$BIN" crop --input "$T" --window "$window" --square --down 4 --output "$OUT/$name.low.tif" >/dev/null
    "$BIN" amplify --dictionary "$OUT/heldout.dict" --input "$OUT/$name.low.tif" --levels 2 \
        --output "$OUT/$name.out.tif" "$@" >/dev/null
    "$BIN" eval --truth "$OUT/$name.truth.tif" --input "$OUT/$name.low.tif" \
        --output "$OUT/$name.out.tif" --picture "$OUT/$name.png" >"$OUT/$name.json"
    echo "$name done" >&2
done

names=()
for entry in "${CROPS[@]}"; do read -r name _ <<<"$entry"; names+=("$name"); done
python3 - "$OUT" "${names[@]}" <<'EOF' | tee "$OUT/table.md"
import json, sys
out, names = sys.argv[1], sys.argv[2:]
reports = {n: json.load(open(f"{out}/{n}.json")) for n in names}
rows = [
    ("band energy ratio", "band_energy_ratio", "{:.2f}"),
    ("flood extent error, points", "flood_extent_error_pct", "{:.2f}"),
    ("slope W1, °", "slope_wasserstein_deg", "{:.2f}"),
    ("log10 area W1", "log_area_wasserstein", "{:.3f}"),
    ("curvature W1, 1e-4/m", "curvature_wasserstein_per_m", "{:.3f}"),
    ("anisotropy / truth's", "anisotropy_vs_truth", "{:.2f}"),
    ("drainage density, km/km²", "drainage_density_km_per_km2", "{:.3f}"),
    ("RMSE, m", "rmse_m", "{:.1f}"),
    ("consistency, % relief", "consistency_pct", "{:.3f}"),
    ("detail correlation with the truth's (from bicubic)", "detail_correlation", "{:.3f}"),
    ("detail RMS / the truth's (from bicubic)", "detail_rms_ratio", "{:.3f}"),
]
scale = {"curvature_wasserstein_per_m": 1e4}
who = [("amplified", "ours"), ("bicubic", "bicubic"), ("bicubic_fbm", "bicubic+fBm")]

def val(n, w, k):
    return reports[n][w][k] * scale.get(k, 1.0)

print("| metric | candidate | " + " | ".join(names) + " | mean |")
print("| --- | --- | " + " | ".join("---:" for _ in names) + " | ---: |")
for label, key, fmt in rows:
    for w, wl in who:
        vals = [val(n, w, key) for n in names]
        cells = [fmt.format(v) for v in vals] + [fmt.format(sum(vals) / len(vals))]
        print(f"| {label} | {wl} | " + " | ".join(cells) + " |")
truth_dd = [reports[n]["truth"]["drainage_density_km_per_km2"] for n in names]
truth_fl = [reports[n]["truth"]["flood_extent_pct"] for n in names]
truth_an = [reports[n]["truth"]["axis_anisotropy"] for n in names]
for label, vals, fmt in [("drainage density, km/km²", truth_dd, "{:.3f}"),
                         ("flood extent, %", truth_fl, "{:.2f}"),
                         ("axis anisotropy", truth_an, "{:.2f}")]:
    cells = [fmt.format(v) for v in vals] + [fmt.format(sum(vals) / len(vals))]
    print(f"| {label} | truth | " + " | ".join(cells) + " |")
octaves = reports[names[0]]["band_octaves"]
for k, (lo, hi) in enumerate(octaves):
    for w, wl in who:
        vals = [reports[n][w]["band_octave_energy_ratios"][k] for n in names]
        cells = ["{:.2f}".format(v) for v in vals] + ["{:.2f}".format(sum(vals) / len(vals))]
        print(f"| band energy ratio, {lo:.3g}–{hi:.3g} cycles/cell | {wl} | " + " | ".join(cells) + " |")
for k, (lo, hi) in enumerate(reports[names[0]]["detail_octaves"]):
    vals = [reports[n]["amplified"]["detail_octave_correlations"][k] for n in names]
    cells = ["{:.3f}".format(v) for v in vals] + ["{:.3f}".format(sum(vals) / len(vals))]
    print(f"| detail correlation with the truth's, {lo:.3g}–{hi:.3g} cycles/cell | ours | " + " | ".join(cells) + " |")
# The truth's spectral slope: the band's first octave over the octave below it (which the input
# does not show), and that octave over the one below (which it does).
for label, num, den in [("first band octave / octave below", ("band_octave_energies", 0),
                         ("octave_below_band_energies", 1)),
                        ("octave below / the one below that", ("octave_below_band_energies", 1),
                         ("octave_below_band_energies", 0))]:
    vals = [reports[n]["truth"][num[0]][num[1]] / reports[n]["truth"][den[0]][den[1]] for n in names]
    cells = ["{:.2f}".format(v) for v in vals] + ["{:.2f}".format(sum(vals) / len(vals))]
    print(f"| energy ratio, {label} | truth | " + " | ".join(cells) + " |")
rmse_ratio = [reports[n]["amplified"]["rmse_m"] / reports[n]["bicubic"]["rmse_m"] for n in names]
cells = ["{:.2f}".format(v) for v in rmse_ratio] + ["{:.2f}".format(sum(rmse_ratio) / len(rmse_ratio))]
print("| RMSE / bicubic's | ours | " + " | ".join(cells) + " |")
EOF
