#!/usr/bin/env bash
# Do two railgrip binaries write the same outputs? Runs `run` (bundled archive), `train` (three
# bundled logs), `simulate` (every bundled scene and two foreign ones, CSV and MCAP) and a small
# `study` with each, then compares every file: byte for byte, except that the repository path
# each binary was built in may differ (the default archive's path is compiled in), timings.json
# and the logs' timings are left out, and study.csv / cells/*.json are compared without their
# timing columns. For a refactoring: build the commit before and after, then
#
#   scripts/same-outputs.sh OLD_BIN OLD_REPO NEW_BIN NEW_REPO [WORK_DIR]
#
# Exit code 0 when every compared file is the same. The study plan names its models by
# `train.model`; a binary from before the study's model axis (which took `family`) refuses it:
# compare those with the copy of this script from their own commit.
set -euo pipefail
old_bin=$1 old_repo=$2 new_bin=$3 new_repo=$4
work=${5:-$(mktemp -d)}
here=$(cd "$(dirname "$0")/.." && pwd)
plan="$work/plan.toml"
mkdir -p "$work"
cat > "$plan" <<'PLAN'
[study]
max_cells = 20
max_minutes = 10
eval_points = 256

[[grid]]
label = "Polach"
train.model = ["polach_pooled", "polach_kt"]

[[grid]]
label = "LM"
train.inputs = [["dv_mps", "ddv_mps2"], ["dv_mps", "ddv_mps2", "v_mps", "ambient_temperature_c"]]
train.layers = [[5], [10]]
PLAN
for side in old new; do
    if [ $side = old ]; then bin=$old_bin; else bin=$new_bin; fi
    d="$work/$side"; rm -rf "$d"; mkdir -p "$d"; cd "$d"
    "$bin" run --out run --jobs 2 > run.log 2>&1
    "$bin" train "$here"/fixtures/archive/soap_120kmh_p20.csv "$here"/fixtures/archive/soap_160kmh_0c.mcap \
        "$here"/fixtures/archive/soap_120kmh_m20.csv --out train > train.log 2>&1
    for s in "$here"/pipelines/scenes/*.toml "$here"/pipelines/scenes/foreign/lr_120kmh_p10.toml \
             "$here"/pipelines/scenes/foreign/table_160kmh_p10.toml; do
        "$bin" simulate "$s" --out sim --format both > /dev/null
    done
    "$bin" study --plan "$plan" --out study --jobs 2 > study.log 2>&1
done
cd "$work"
python3 - "$old_repo" "$new_repo" <<'PY'
import csv, json, os, sys
old_repo, new_repo = sys.argv[1], sys.argv[2]
timing_cols = {"train_s", "estimated_train_s", "single_ns", "batch_ns", "plain_libm_ns",
               "pareto_train", "pareto_eval", "recommended"}
def text(side, path, repo):
    b = open(os.path.join(side, path), "rb").read()
    return b.replace(repo.encode(), b"ROOT")
def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items()
                if not any(t in k for t in ("_s", "_ns", "time", "created"))}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x
files = sorted(os.path.relpath(os.path.join(r, f), "old")
               for r, _, fs in os.walk("old") for f in fs)
bad = 0
for f in files:
    if f.endswith(".log") or f.endswith("timings.json"):
        continue
    if not os.path.exists(os.path.join("new", f)):
        print("missing in new:", f); bad += 1; continue
    if f.endswith("study.csv"):
        o = list(csv.DictReader(open(os.path.join("old", f))))
        n = list(csv.DictReader(open(os.path.join("new", f))))
        same = len(o) == len(n) and all(a[k] == b[k] for a, b in zip(o, n) for k in a if k not in timing_cols)
    elif "/cells/" in f and not f.endswith(".model.json") or f.endswith("study.json"):
        same = strip(json.loads(text("old", f, old_repo))) == strip(json.loads(text("new", f, new_repo)))
    elif f.endswith("study.html"):
        continue  # holds the timings; its numbers come from study.json
    else:
        same = text("old", f, old_repo) == text("new", f, new_repo)
    if not same:
        print("differs:", f); bad += 1
print(f"{len(files)} files compared, {bad} differ")
sys.exit(1 if bad else 0)
PY
