#!/usr/bin/env bash
# How much the network's initialisation moves the top-speed scores: retrains the estimates of
# each seed's top-speed campaign (scripts/top-speed.sh, run first into the same OUT_DIR) with
# `train.seed` set to each of TRAIN_SEEDS, and once with four starts averaged (`starts = 4`,
# `ensemble = 4`), through `railgrip train`, scores the residual network with `railgrip score`
# and prints one row per training: the lowest and highest hysteresis ratio over the runs, each
# initial speed's ratio with its runs' pairs pooled, and the curve RMSE per speed band
# (80 / 120 / 160 / 200 km/h), nominal cell centres (docs/training.md, "Top speeds: the models
# per speed band").
#
#   scripts/top-speed.sh OUT_DIR "1 2 3"
#   scripts/init-spread.sh [OUT_DIR] [SEEDS] [TRAIN_SEEDS]   default: target/top-speed "1 2 3" "1 2 3 4"
#
# Needs a release build (RAILGRIP=path, default target/release/railgrip).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/top-speed}"
seeds="${2:-1 2 3}"
train_seeds="${3:-1 2 3 4}"
bin="${RAILGRIP:-target/release/railgrip}"
[ -x "$bin" ] || { echo "no $bin: run cargo build --release first (or set RAILGRIP)" >&2; exit 2; }
base=pipelines/uic_z1.toml
for key in '^seed = 1 ' '^starts = 1 ' '^ensemble = 1 '; do
    grep -q "$key" "$base" || { echo "$base: no line matching '$key' to edit" >&2; exit 2; }
done
scenes=(pipelines/scenes/top_speed/*.toml)
printf '%-5s %-18s %7s %7s   %-27s %s\n' seed training lowest highest "pooled 80 / 120 / 160 / 200" "curve RMSE 80 / 120 / 160 / 200 km/h"
for seed in $seeds; do
    runs="$out/seed$seed/out/runs"
    [ -d "$runs" ] || { echo "no $runs: run scripts/top-speed.sh $out \"$seed\" first" >&2; exit 2; }
    work="$out/seed$seed/init-spread"
    rm -rf "$work" && mkdir -p "$work/tables"
    for r in "$runs"/*/; do
        cp "$r/estimates.parquet" "$work/tables/$(basename "$r").estimates.parquet"
    done
    for t in $train_seeds ensemble4; do
        if [ "$t" = ensemble4 ]; then
            sed -e 's/^starts = 1 /starts = 4 /' -e 's/^ensemble = 1 /ensemble = 4 /' "$base" > "$work/p_$t.toml"
            label="4 starts averaged"
        else
            sed -e "s/^seed = 1 /seed = $t /" "$base" > "$work/p_$t.toml"
            label="train.seed = $t"
        fi
        "$bin" train "$work"/tables/*.estimates.parquet --out "$work/m_$t" --pipeline "$work/p_$t.toml" --quiet \
            > "$work/train_$t.log" 2>&1 || { echo "seed $seed, $label: railgrip train failed, see $work/train_$t.log" >&2; exit 1; }
        "$bin" score "$work/m_$t/mlp.residual.json" "${scenes[@]}" --seeds "$seed" > "$work/score_$t.txt"
        # The curve view's table: one row per speed band, ending in its hysteresis ratios
        # "pooled, run mean (lowest … highest)".
        awk -v s="$seed" -v l="$label" '
            /^Curve view: the model/ { c = 1; next }
            c && /^(80|120|160|200) / {
                # A band without a ratio (no true difference of 0.002) ends in "–".
                if ($NF == "–") { print "seed " s ", " l ": no hysteresis ratio at " $1 " km/h" > "/dev/stderr"; bad = 1; n++; next }
                low = $(NF-2); high = $NF; pooled = $(NF-4)
                gsub(/[(),]/, "", low); gsub(/[(),]/, "", high); gsub(/[(),]/, "", pooled)
                if (lo == "" || low + 0 < lo + 0) lo = low
                if (hi == "" || high + 0 > hi + 0) hi = high
                r = r (r == "" ? "" : " / ") $4
                p = p (p == "" ? "" : " / ") pooled
                n++
            }
            c && n == 4 { c = 0 }
            END { if (n != 4 || bad) { if (n != 4) print "seed " s ", " l ": no curve view in the score" > "/dev/stderr"; exit 1 }
                  printf "%-5s %-18s %7s %7s   %-27s %s\n", s, l, lo, hi, p, r }' "$work/score_$t.txt"
    done
done
