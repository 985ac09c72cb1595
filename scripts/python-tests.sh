#!/usr/bin/env bash
# The Python package's tests: builds the extension in the test build's profile (sharing the
# dependencies `cargo test` compiled), installs the wheel into this Python and runs pytest
# against the `railgrip` binary of the same build (with a local Ray and moto's S3 server for
# railgrip.ray). Used by .ci/run; run it after `cargo test`.
set -euo pipefail
cd "$(dirname "$0")/.."

pip_install() {
    python3 -m pip install --quiet "$@" || python3 -m pip install --quiet --break-system-packages "$@"
}
pip_install "maturin>=1.9.4,<2" "pytest>=7" "numpy>=1.21" "pandas>=1.3" "ray>=2.60,<3" "pyarrow>=12" \
    "moto[server]>=5.2,<5.3" "matplotlib>=3.5" "fmpy>=0.3.20"

target="${CARGO_TARGET_DIR:-$PWD/target}"
# The binary the tests compare with: the one `cargo test` built (a plain `cargo build` would
# compile the dependencies again without the test build's features).
[ -x "$target/debug/railgrip" ] || cargo build --quiet
rm -rf "$target/wheels"
python3 -m maturin build --quiet --profile dev -m crates/railgrip-py/Cargo.toml -o "$target/wheels"
pip_install --force-reinstall --no-deps "$target"/wheels/railgrip-*.whl
RAILGRIP_BIN="$target/debug/railgrip" python3 -m pytest -q crates/railgrip-py/tests
