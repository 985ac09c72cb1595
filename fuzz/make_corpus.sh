#!/usr/bin/env bash
# Writes the seed corpora of the fuzz targets (fuzz/corpus/<target>/) from the bundled
# pipelines, scenes, golden models and two short simulated runs (0.4 s, one CSV with its
# sidecar, one multi-rate MCAP). Run from the repository root after `cargo build --release`.
set -euo pipefail
cd "$(dirname "$0")/.."
out=fuzz/corpus
rm -rf "$out"
mkdir -p "$out"/{csv,mcap,sidecar,pipeline,scene,model,mcap_message}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for s in soap_120kmh_p20 soap_120kmh_multirate_0c; do
    # The bundled scene cut to 0.4 s of braking (small inputs fuzz fast).
    sed -e 's|^\[run\]|[run]\nmax_duration_s = 0.4|' \
        -e 's|"\.\./uic_z1\.toml"|"'"$PWD"'/pipelines/uic_z1.toml"|' \
        "pipelines/scenes/$s.toml" > "$tmp/$s.toml"
    ./target/release/railgrip simulate "$tmp/$s.toml" --out "$tmp/sim" > /dev/null
done
cp "$tmp/sim/soap_120kmh_p20.csv" "$out/csv/"
cp "$tmp/sim/soap_120kmh_p20.mcap" "$tmp/sim/soap_120kmh_multirate_0c.mcap" "$out/mcap/"
cp "$tmp/sim/soap_120kmh_p20.meta.toml" "$out/sidecar/"
cp fixtures/archive/soap_120kmh_m20.meta.toml "$out/sidecar/"
cp pipelines/uic_z1.toml "$out/pipeline/"
cp pipelines/scenes/soap_120kmh_p20.toml pipelines/scenes/soap_120kmh_multirate_0c.toml \
    pipelines/scenes/foreign/lr_120kmh_p10.toml pipelines/scenes/foreign/table_120kmh_p10.toml \
    "$out/scene/"
cp models/golden/synthetic_mlp.json models/golden/synthetic_mlp_4inputs.json \
    models/golden/synthetic_polach.json "$out/model/"
# mcap_message: [0 protobuf | 1 CDR][schema length, u16 LE][schema][payload] per message of the
# corner-case files (needs python3 with `pip install mcap`).
python3 - "$out/mcap_message" <<'PY'
import struct, sys
from mcap.reader import make_reader
for pick, f in ((0, "small.protobuf.mcap"), (1, "small.ros2.mcap")):
    with open(f"tests/data/mcap/{f}", "rb") as fh:
        for k, (schema, _, msg) in enumerate(make_reader(fh).iter_messages()):
            with open(f"{sys.argv[1]}/{f.split('.')[1]}_{k}", "wb") as out:
                out.write(bytes([pick]) + struct.pack("<H", len(schema.data)) + schema.data + msg.data)
PY
du -sh "$out"/*
