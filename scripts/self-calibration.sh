#!/usr/bin/env bash
# What the campaign's self-calibration costs and buys: simulates the 12 scenes of
# pipelines/scenes/mismatch (a vehicle the pipeline does not describe exactly: per-axle α off
# by 2 %, pad friction +5 % from 200 km/h to standstill, a radar 0.3 % high and 30 ms late,
# wheel loads fluctuating 1.5 % rms, the pivot force's share of the load transfer)
# once per noise seed, runs `railgrip run` on each seed's campaign twice — with the pipeline's
# α and radar (estimate.calibration = "pipeline") and with the campaign's calibration
# ("campaign") — and prints per seed and mode:
#   - the stage times (`calibrate` is the calibration's cost; per run: divide by 12);
#   - per axle, the estimates' μ RMSE and bias against the truth (valid samples, true Δv >
#     0.2 m/s), per speed band;
#   - `railgrip score` of the chosen model: the curve and replay views per speed band.
#
#   scripts/self-calibration.sh [OUT_DIR] [SEEDS]      default: target/self-calibration "1 2 3"
#
# Needs a release build (cargo build --release) and python3 with pyarrow.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/self-calibration}"
seeds="${2:-1 2 3}"
bin="${RAILGRIP:-target/release/railgrip}"
[ -x "$bin" ] || { echo "no $bin: run cargo build --release first (or set RAILGRIP)" >&2; exit 2; }
scenes=(pipelines/scenes/mismatch/*.toml)
mkdir -p "$out"
# The vehicle as its owner describes it (the pivot force's share of the load transfer, which the
# scenes' vehicle has), with the pipeline's α and radar, and calibrating itself.
base="$out/pipeline.toml"
pipe="$out/campaign.toml"
sed -e '/^\[vehicle\]/a pivot_force_load_transfer = true' \
    -e '/^\[estimate\]/a calibration = "pipeline"' pipelines/uic_z1.toml > "$base"
sed 's/^calibration = "pipeline"$/calibration = "campaign"/' "$base" > "$pipe"
for seed in $seeds; do
    archive="$out/seed$seed/archive"
    mkdir -p "$archive"
    for s in "${scenes[@]}"; do
        "$bin" simulate "$s" --out "$archive" --seed "$seed" --format csv >/dev/null
    done
    for mode in pipeline campaign; do
        dest="$out/seed$seed/$mode"
        args=(--pipeline "$base")
        [ "$mode" = campaign ] && args=(--pipeline "$pipe")
        "$bin" run "$archive" --out "$dest" --force "${args[@]}" > "$dest.log" 2>&1 || true
        echo "== seed $seed, estimate.calibration = \"$mode\""
        grep -E '^(time|chosen|note       campaign)' "$dest.log" || true
        python3 - "$archive" "$dest" <<'EOF'
import sys, pathlib
import pyarrow.parquet as pq
archive, dest = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
bands = [(0, 80), (80, 145), (145, 230)]
acc = {}
for run in sorted((dest / "runs").iterdir()):
    e = pq.read_table(run / "estimates.parquet").to_pydict()
    t = pq.read_table(archive / f"{run.name}.truth.parquet").to_pydict()
    truth = {(round(ts, 6), ax): (mu, dv) for ts, ax, mu, dv in zip(t["time_s"], t["axle"], t["mu"], t["dv_mps"])}
    for ts, ax, v, mu, ok in zip(e["time_s"], e["axle"], e["v_mps"], e["mu"], e["valid"]):
        tr = truth.get((round(ts, 6), ax))
        if not ok or tr is None or tr[1] <= 0.2:
            continue
        kmh = v * 3.6
        band = next((b for b in bands if b[0] <= kmh < b[1]), None)
        if band is None:
            continue
        d = mu - tr[0]
        s = acc.setdefault((ax, band), [0, 0.0, 0.0])
        s[0] += 1; s[1] += d; s[2] += d * d
print("axle  band km/h   samples   μ RMSE    μ bias")
for (ax, band), (n, s1, s2) in sorted(acc.items()):
    print(f"{ax:>4}  {band[0]:>3}–{band[1]:<4}  {n:>9}  {(s2 / n) ** 0.5:.5f}  {s1 / n:+.5f}")
EOF
        chosen=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get('chosen_model',''))" "$dest/campaign.json" 2>/dev/null || true)
        [ -n "$chosen" ] && "$bin" score "$dest/$chosen" "${scenes[@]}" --seeds "$seed" | sed -n '/^Curve view/,$p' || true
    done
done
