#!/usr/bin/env bash
# The top-speed measurement: simulates the 12 scenes of pipelines/scenes/top_speed (80/120/160/
# 200 km/h × three ambient temperatures, the adhesion level falling steeper at the top) once per
# noise seed, runs `railgrip run` on each seed's campaign and scores the campaign's models per
# speed band in the curve and replay views (docs/simulator.md#scoring-against-the-truth).
#
#   scripts/top-speed.sh [OUT_DIR] [SEEDS]      default: target/top-speed "1 2 3"
#
# PIPELINE=file.toml runs the campaign with that pipeline (e.g. train.inputs with v_mps and
# ambient_temperature_c for the 4-input network).
# Prints the candidates' held-out scores and the chosen model (as `railgrip run` prints them,
# all of its output in OUT_DIR/seedN/run.txt) and one `railgrip score` report per seed and
# candidate model; the per-band tables of docs/training.md come from it. Needs a release build
# (cargo build --release).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/top-speed}"
seeds="${2:-1 2 3}"
bin="${RAILGRIP:-target/release/railgrip}"
[ -x "$bin" ] || { echo "no $bin: run cargo build --release first (or set RAILGRIP)" >&2; exit 2; }
scenes=(pipelines/scenes/top_speed/*.toml)
for seed in $seeds; do
    archive="$out/seed$seed/archive"
    mkdir -p "$archive"
    for s in "${scenes[@]}"; do
        "$bin" simulate "$s" --out "$archive" --seed "$seed" --format csv >/dev/null
    done
    # Exit 3 (a run failed, or the audit) still writes models; anything else stops here.
    rc=0
    "$bin" run "$archive" --out "$out/seed$seed/out" ${PIPELINE:+--pipeline "$PIPELINE"} > "$out/seed$seed/run.txt" || rc=$?
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 3 ]; then
        echo "seed $seed: railgrip run exited $rc (its output: $out/seed$seed/run.txt)" >&2
        exit 1
    fi
    [ "$rc" -eq 0 ] || echo "== seed $seed: railgrip run exited 3 (see $out/seed$seed/run.txt)"
    # The candidates' held-out scores and the choice, as `run` printed them.
    echo "== seed $seed: the model choice"
    grep -E '^(candidate|chosen) ' "$out/seed$seed/run.txt" || echo "no model choice (see $out/seed$seed/run.txt)"
    # mlp.2in.json only where the pipeline's network has other inputs than (Δv, dΔv/dt).
    for model in mlp.json mlp.polach.json mlp.2in.json mlp.3in.json mlp.4in.json mlp.residual.json; do
        if [ ! -f "$out/seed$seed/out/models/$model" ]; then
            [ "$model" = mlp.2in.json ] || echo "== seed $seed: no $model (see the run's notes)"
            continue
        fi
        echo "== seed $seed: $model"
        "$bin" score "$out/seed$seed/out/models/$model" "${scenes[@]}" --seeds "$seed" || true
    done
done
