#!/usr/bin/env bash
# Where a campaign's samples lie in speed, and how the wheel-slide protection cycles there:
# simulates scenes (campaign noise seed SEED, as `railgrip simulate --seed` takes it), estimates each run (`railgrip estimate --csv`) and prints
# per scene family and speed band, for the training axle (2): the valid samples (what a
# campaign model is trained on), those with slip Δv > 0.2 m/s, the share of the band's time
# sliding, and the WSP cycles (slip excursions above 0.5 m/s: how many start in the band, their
# mean length and peak slip).
#
#   scripts/speed-balance.sh [OUT_DIR] [SEED]     default: target/speed-balance 1
#
# Families: the bundled Polach scenes (pipelines/scenes/*.toml but the multirate one), the foreign-law scenes
# (pipelines/scenes/foreign/: loss_recovery `lr_*` and table `table_*`) and the top-speed
# family (pipelines/scenes/top_speed/). Needs bash 4, a release build and python3 with numpy.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/speed-balance}"
seed="${2:-1}"
bin="${RAILGRIP:-target/release/railgrip}"
[ -x "$bin" ] || { echo "no $bin: run cargo build --release first (or set RAILGRIP)" >&2; exit 2; }
declare -A families=(
    [polach]="pipelines/scenes/*.toml"
    [loss_recovery]="pipelines/scenes/foreign/lr_*.toml"
    [table]="pipelines/scenes/foreign/table_*.toml"
    [top_speed]="pipelines/scenes/top_speed/*.toml"
)
for fam in polach loss_recovery table top_speed; do
    mkdir -p "$out/$fam/logs" "$out/$fam/est"
    for s in ${families[$fam]}; do
        # CSV has one time base; the multirate scene is the bundled 120 km/h scene again.
        [[ $s == *multirate* ]] && continue
        "$bin" simulate "$s" --out "$out/$fam/logs" --seed "$seed" --format csv >/dev/null
    done
    for log in "$out/$fam/logs"/*.csv; do
        # Exit 3: estimated, but some input was lost at ingest (still counted).
        rc=0
        "$bin" estimate "$log" --out "$out/$fam/est" --csv >/dev/null || rc=$?
        [ "$rc" -eq 0 ] || [ "$rc" -eq 3 ] || { echo "estimate $log exited $rc" >&2; exit 1; }
    done
done
python3 - "$out" <<'EOF'
import glob, sys
import numpy as np

BANDS = [0, 40, 80, 120, 145, 170, 210]  # km/h, as `railgrip score`'s replay view
AXLE = 2
print("family | band km/h | valid samples (share) | with slip > 0.2 m/s | time sliding | WSP cycles | mean length s | mean peak slip m/s")
for fam in ["polach", "loss_recovery", "table", "top_speed"]:
    rows = {b: [0, 0, 0.0, 0.0, 0, [], []] for b in range(len(BANDS) - 1)}
    total_valid = 0
    for f in sorted(glob.glob(f"{sys.argv[1]}/{fam}/est/*.estimates.csv")):
        d = np.genfromtxt(f, delimiter=",", names=True, converters={"valid": lambda x: x.strip() in (b"true", "true")})
        d = d[d["axle"] == AXLE]
        t, v, dv = d["time_s"], d["v_mps"] * 3.6, d["dv_mps"]
        valid = d["valid"].astype(bool)
        dt = np.median(np.diff(t))
        band = np.digitize(v, BANDS) - 1
        total_valid += valid.sum()
        # Slip excursions above 0.5 m/s: start, end, peak.
        on = dv > 0.5
        edges = np.flatnonzero(np.diff(on.astype(int)))
        starts = [i + 1 for i in edges if not on[i]]
        for s in starts:
            e = s
            while e < len(on) and on[e]:
                e += 1
            b = band[s]
            if 0 <= b < len(BANDS) - 1:
                rows[b][4] += 1
                rows[b][5].append((e - s) * dt)
                rows[b][6].append(dv[s:e].max())
        for b in rows:
            m = band == b
            rows[b][0] += (valid & m).sum()
            rows[b][1] += (valid & m & (dv > 0.2)).sum()
            rows[b][2] += (m & (dv > 0.5)).sum() * dt
            rows[b][3] += m.sum() * dt
    for b, (nv, ns, slide, time, cycles, lengths, peaks) in rows.items():
        if time == 0:
            continue
        print(
            f"{fam} | {BANDS[b]}–{BANDS[b + 1]} | {nv} ({nv / max(total_valid, 1):.0%}) | {ns} | "
            f"{slide / time:.0%} of {time:.0f} s | {cycles} | "
            f"{np.mean(lengths) if lengths else float('nan'):.2f} | {np.mean(peaks) if peaks else float('nan'):.2f}"
        )
EOF
