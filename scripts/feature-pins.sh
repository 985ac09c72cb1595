#!/usr/bin/env bash
# Which shared dependencies the Python extension's build (crates/railgrip-py) compiles with other
# features than the workspace's test build: each such crate, and everything above it (polars,
# burn), is compiled twice when scripts/python-tests.sh runs after `cargo test` (8–10 minutes
# of CI on 2 cores). Prints the differences (name version: test-build features | extension
# features) and fails on any but the railgrip library's own (the tests turn on its `fuzzing`
# feature; it is compiled twice either way). The pins live in crates/railgrip-py/Cargo.toml
# (features the test build's dev-dependencies turn on) and the root Cargo.toml's
# dev-dependencies (features the extension's own dependencies turn on). Run by .ci/run. It
# does not notice a pin that no crate needs any more (after a dependency's update): check the
# pins against `cargo tree -i <crate> -p railgrip-py` then.
set -euo pipefail
cd "$(dirname "$0")/.."
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# Each package once per feature set it is built with (a crate built for build scripts and for
# the target may have two).
features() {
    cargo tree --prefix none -f '{p}|{f}' "$@" > "$tmp/raw" \
        || { echo "feature-pins: cargo tree $* failed" >&2; exit 1; }
    sed 's/ (\*)$//' "$tmp/raw" | sort -u
}
features -e normal,build -p railgrip-py > "$tmp/ext"
features -e normal,build,dev --workspace --exclude railgrip-py > "$tmp/test"
python3 - "$tmp/ext" "$tmp/test" <<'PY'
import sys
def load(p):
    out = {}
    for line in open(p):
        pkg, sep, feats = line.rstrip("\n").partition("|")
        if not sep:
            continue
        name = " ".join(pkg.split()[:2])
        out.setdefault(name, set()).add(tuple(sorted(f for f in feats.split(",") if f)))
    if len(out) < 50:
        sys.exit(f"feature-pins: only {len(out)} packages in {p}: cargo tree's output changed?")
    return out
ext, test = load(sys.argv[1]), load(sys.argv[2])
show = lambda sets: " / ".join(",".join(f) or "-" for f in sorted(sets))
bad = 0
for name in sorted(ext):
    if name in test and ext[name] != test[name]:
        print(f"{name}: {show(test[name])} | {show(ext[name])}")
        bad += not name.startswith("railgrip ")
if bad:
    print(f"{bad} shared dependencies differ in features between the test build and the Python "
          "extension's: pin them (see the comments in crates/railgrip-py/Cargo.toml)")
    sys.exit(1)
PY
