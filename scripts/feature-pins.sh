#!/usr/bin/env bash
# Which shared dependencies the Python extension's build (crates/railgrip-py) compiles with other
# features than the workspace's test build: each such crate, and everything above it (polars,
# burn), is compiled twice when scripts/python-tests.sh runs after `cargo test` (8–10 minutes
# of CI on 2 cores). Prints the differences (name version: test-build features | extension
# features) and fails on any but the railgrip library's own (the tests turn on its `fuzzing`
# feature; it is compiled twice either way). The pins live in crates/railgrip-py/Cargo.toml
# (features the test build's dev-dependencies turn on) and the root Cargo.toml's
# dev-dependencies (features the extension's own dependencies turn on). Run by .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."
features() {
    cargo tree --prefix none -f '{p}|{f}' "$@" 2>/dev/null | sed 's/ (\*)$//' | sort -u
}
python3 - <(features -e normal,build -p railgrip-py) \
    <(features -e normal,build,dev --workspace --exclude railgrip-py) <<'PY'
import sys
def load(p):
    out = {}
    for line in open(p):
        pkg, _, feats = line.rstrip("\n").partition("|")
        name = " ".join(pkg.split()[:2])
        out.setdefault(name, set()).update(f for f in feats.split(",") if f)
    return out
ext, test = load(sys.argv[1]), load(sys.argv[2])
bad = 0
for name in sorted(ext):
    if name in test and ext[name] != test[name]:
        print(f"{name}: {','.join(sorted(test[name]))} | {','.join(sorted(ext[name]))}")
        bad += not name.startswith("railgrip ")
if bad:
    print(f"{bad} shared dependencies differ in features between the test build and the Python "
          "extension's: pin them (see the comments in crates/railgrip-py/Cargo.toml)")
    sys.exit(1)
PY
