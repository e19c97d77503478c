#!/usr/bin/env bash
# The tests, from a fresh clone: the Rust suite, then the Python front's (pytest) against the
# command line built by it. Python packages (maturin, numpy, pytest) come from PyPI into a
# virtual environment under target/ (nothing installed outside this checkout).
set -euo pipefail
cd "$(dirname "$0")"
# builds target/release/hystbench too, the command line the Python tests compare with
cargo test --release
target_dir="${CARGO_TARGET_DIR:-$PWD/target}"
venv="$target_dir/python-venv"
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r python/requirements-test.txt
VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH" maturin develop --release --quiet -m python/Cargo.toml
HYSTBENCH_BIN="$target_dir/release/hystbench" "$venv/bin/python" -m pytest -q python/tests
