#!/usr/bin/env bash
# Every test of softrod from a fresh clone: installs the package with its test extra
# (this builds the Rust extension), then runs the Rust tests, the Python tests and the
# format/lint checks. Needs Python >= 3.10 with pip, and Rust (https://rustup.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v cargo >/dev/null || { echo "error: cargo not found; install Rust (https://rustup.rs)" >&2; exit 1; }
PY=${PYTHON:-python3}
echo "== installing softrod with its test extra (builds the Rust core)"
"$PY" -m pip install --quiet --disable-pip-version-check -e ".[test]"
echo "== format and lint"
cargo fmt --all --check
"$PY" -m ruff check python tests benchmarks
echo "== Rust tests"
cargo test -p softrod-core --quiet
echo "== Python tests"
"$PY" -m pytest -q
