#!/usr/bin/env bash
# The lever ablation of issue #12 on the held-out suite (scripts/realism.sh): each lever of
# `amplify --levers` alone on the pre-#12 amplifier (`base`), all of them (`default`, what the
# server runs), `default` with each of its last three levers taken back, and the rows measured on
# the one-atom amplifier served before them (`single`) with one lever changed. Writes target/realism/ablation/<name>/
# (one realism run each, sharing one held-out dictionary) and target/realism/ablation/table.md
# (means over the six crops; band energy also as its worst crop).
#
# Usage: scripts/ablation.sh   (BIN=path: terrasynth binary, default target/release/terrasynth)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=target/realism/ablation
BIN=${BIN:-target/release/terrasynth}
[[ -x "$BIN" ]] || cargo build --release --quiet --bin terrasynth
mkdir -p "$OUT"
RUNS=(
    "before base"
    "rough base,rough=0.58"
    "rough+gentle base,rough=0.58,gentle=0.8"
    "kaiser6x2 base,kernel=k6,passes=2"
    "breach6 base,breach=6,flat=6"
    "breach-steep base,breach=16,flat=4,steep=0.05"
    "breach-steep-volume base,breach=16,flat=4,steep=0.05,volume"
    "floor base,floor=3"
    "split base,split"
    "parent base,parent"
    "power3 base,power=3"
    "slopemod base,slopemod"
    "stripes base,stripes=3"
    "diverse base,diverse=8"
    "single single"
    "default default"
    "one-atom default,sparsity=1"
    "no-plains default,plains=0"
    "no-restore default,restore=0"
    "no-volume single,no-volume"
    "breach16 single,breach=16"
    "breach16+floor single,breach=16,floor=3"
    "dsmooth0.3 single,dsmooth=0.3"
    "dsmooth1 single,dsmooth=1"
    "dsmooth0.3+rough single,dsmooth=0.3,rough=0.62,gentle=0.85"
    "dsmooth0.5+rough single,dsmooth=0.5,rough=0.65,gentle=0.9"
    "prev single,breach=16,gentle=0,floor=3"
    "prev-diverse single,breach=16,gentle=0,floor=3,diverse=1"
    "prev+diverse4 single,breach=16,gentle=0,floor=3,diverse=4"
    "prev+within single,breach=16,gentle=0,floor=3,within=0.03"
    "prev-rough single,breach=16,gentle=0,floor=3,rough=0"
    "prev-kaiser single,breach=16,gentle=0,floor=3,kernel=cr,passes=4"
    "prev-breach single,breach=16,gentle=0,floor=3,breach=0"
    "prev-steep single,breach=16,gentle=0,floor=3,flat=16"
    "prev+breach6 single,breach=16,gentle=0,floor=3,breach=6,flat=6,steep=0"
    "prev-floor single,breach=16,gentle=0"
    "prev+power3 single,breach=16,gentle=0,floor=3,power=3"
    "prev+slopemod single,breach=16,gentle=0,floor=3,slopemod"
    "prev+octave single,breach=16,gentle=0,floor=3,octave=1"
    "prev+octave+split single,breach=16,gentle=0,floor=3,octave=1,split"
    "prev+stripes3 single,breach=16,gentle=0,floor=3,stripes=3"
    "prev+stripes1 single,breach=16,gentle=0,floor=3,stripes=1"
    "prev+nostripes single,breach=16,gentle=0,floor=3,stripes=0"
)
for run in "${RUNS[@]}"; do
    read -r name levers <<<"$run"
    dict=()
    [[ -f "$OUT/heldout.dict" ]] && dict=(DICT="$OUT/heldout.dict")
    env "${dict[@]}" OUT="$OUT/$name" BIN="$BIN" bash scripts/realism.sh --levers "$levers" >/dev/null
    [[ -f "$OUT/heldout.dict" ]] || cp "$OUT/$name/heldout.dict" "$OUT/heldout.dict"
    echo "$name ($levers) done" >&2
done
python3 - "$OUT" "${RUNS[@]}" <<'PY' | tee "$OUT/table.md"
import json, sys
out, runs = sys.argv[1], [r.split(" ", 1) for r in sys.argv[2:]]
crops = ["talas", "kyrgyz", "alai", "pamir", "karatau", "steppe"]
cols = [("band (worst)", None), ("band", "band_energy_ratio"), ("flood err", "flood_extent_error_pct"),
        ("slope W1 °", "slope_wasserstein_deg"), ("log-area W1", "log_area_wasserstein"),
        ("curv. W1 1e-4/m", "curvature_wasserstein_per_m"), ("aniso/truth", "anisotropy_vs_truth"),
        ("RMSE/bicubic", None), ("consist. %", "consistency_pct")]
print("| run | `--levers` | " + " | ".join(c for c, _ in cols) + " |")
print("| --- | --- | " + " | ".join("---:" for _ in cols) + " |")
for name, levers in runs:
    rep = [json.load(open(f"{out}/{name}/{c}.json")) for c in crops]
    amp = [r["amplified"] for r in rep]
    mean = lambda k: sum(a[k] for a in amp) / len(amp)
    cells = []
    for label, key in cols:
        if label == "band (worst)":
            worst = max((a["band_energy_ratio"] for a in amp), key=lambda b: abs(b - 1) if b >= 1 else abs(1 / b - 1))
            cells.append(f"{worst:.2f}")
        elif label == "RMSE/bicubic":
            cells.append("{:.2f}".format(sum(r["amplified"]["rmse_m"] / r["bicubic"]["rmse_m"] for r in rep) / len(rep)))
        elif key == "curvature_wasserstein_per_m":
            cells.append(f"{mean(key) * 1e4:.3f}")
        elif key == "log_area_wasserstein":
            cells.append(f"{mean(key):.3f}")
        else:
            cells.append(f"{mean(key):.2f}")
    print(f"| {name} | `{levers}` | " + " | ".join(cells) + " |")
PY
