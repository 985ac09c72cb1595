#!/usr/bin/env bash
# How `railgrip run` grows with the campaign: builds campaigns of N runs from the 12 scenes of
# pipelines/scenes/top_speed (80–200 km/h × three temperatures × rail condition ±5 %), scene k
# of the campaign being top-speed scene k mod 12 at noise seed 1 + k / 12 (so runs differ by
# speed, temperature, condition, demand and sensor noise), runs `railgrip run --force` on each
# and prints one row per campaign: runs, wall time per stage (timings.json; calibrate is 0 where
# the pipeline fits no calibration) and peak RSS
# (GNU time's maximum resident set size).
#
#   scripts/scaling.sh [OUT_DIR] [SIZES]      default: target/scaling "8 64 256"
#
# Needs a build (RAILGRIP=path, default target/release/railgrip) and /usr/bin/time.
# PIPELINE=file.toml runs the campaigns with that pipeline.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/scaling}"
sizes="${2:-8 64 256}"
bin="${RAILGRIP:-target/release/railgrip}"
[ -x "$bin" ] || { echo "no $bin: run cargo build --release first (or set RAILGRIP)" >&2; exit 2; }
[ -x /usr/bin/time ] || { echo "no /usr/bin/time (GNU time): apt-get install time" >&2; exit 2; }
scenes=(pipelines/scenes/top_speed/*.toml)
# Every run once, in a pool the campaigns link to.
largest=0
for n in $sizes; do [ "$n" -gt "$largest" ] && largest=$n; done
pool="$out/pool"
mkdir -p "$pool"
for ((k = 0; k < largest; k++)); do
    scene="${scenes[$((k % ${#scenes[@]}))]}"
    seed=$((1 + k / ${#scenes[@]}))
    name="$(basename "$scene" .toml)_s$seed"
    [ -f "$pool/$name.csv" ] && continue
    tmp="$out/tmp"
    rm -rf "$tmp" && mkdir -p "$tmp"
    "$bin" simulate "$scene" --out "$tmp" --seed "$seed" --format csv >/dev/null
    base="$(basename "$scene" .toml)"
    mv "$tmp/$base.csv" "$pool/$name.csv"
    mv "$tmp/$base.meta.toml" "$pool/$name.meta.toml"
    rm -rf "$tmp"
done
printf '%6s %10s %10s %10s %10s %10s %12s\n' runs calibrate_s estimate_s train_s report_s total_s peak_rss_MiB
for n in $sizes; do
    camp="$out/campaign$n"
    rm -rf "$camp" && mkdir -p "$camp/archive"
    # The first n runs in pool order (seed 1's twelve scenes first, then seed 2's, …).
    mapfile -t runs < <(for ((k = 0; k < n; k++)); do
        scene="${scenes[$((k % ${#scenes[@]}))]}"
        echo "$pool/$(basename "$scene" .toml)_s$((1 + k / ${#scenes[@]})).csv"
    done)
    for r in "${runs[@]}"; do
        ln -s "$(realpath "$r")" "$camp/archive/"
        ln -s "$(realpath "${r%.csv}.meta.toml")" "$camp/archive/"
    done
    /usr/bin/time -f '%M' -o "$camp/rss_kb" \
        "$bin" run "$camp/archive" --out "$camp/out" --force ${PIPELINE:+--pipeline "$PIPELINE"} >/dev/null 2>"$camp/stderr" \
        || { echo "campaign of $n runs failed: see $camp/stderr" >&2; continue; }
    python3 - "$camp/out/timings.json" "$camp/rss_kb" "$n" <<'EOF'
import json, sys
t = dict(json.load(open(sys.argv[1]))["stages"])
rss = int(open(sys.argv[2]).read().split()[-1]) / 1024
print(f"{int(sys.argv[3]):6d} {t.get('calibrate', 0.0):10.2f} {t['estimate']:10.2f} {t['train']:10.2f} {t['report']:10.2f} {t['total']:10.2f} {rss:12.0f}")
EOF
done
