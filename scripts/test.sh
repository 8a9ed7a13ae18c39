#!/usr/bin/env bash
# Every test of softrod from a fresh clone: installs the package with its test and docs extras
# (this builds the Rust extension), then runs the Rust tests, the Python tests (the docs' examples,
# the API reference build and the stub check included) and the format/lint checks. Needs
# Python >= 3.10 with pip, and Rust (https://rustup.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v cargo >/dev/null || { echo "error: cargo not found; install Rust (https://rustup.rs)" >&2; exit 1; }
PY=${PYTHON:-python3}
# The viewer's browser test drives Debian's Chromium (never a downloaded browser). Install it
# when it is missing (~20 s, ~500 MB): as root with apt-get, else through sudo when that works
# without a password; otherwise say so, and that test is skipped with the reason.
if ! command -v chromium >/dev/null 2>&1; then
    if ! command -v apt-get >/dev/null 2>&1; then
        echo "note: Chromium is not installed and there is no apt-get: the browser test will be skipped"
    elif [ "$(id -u)" = 0 ] || { command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; }; then
        SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo -n"
        echo "== installing Debian's chromium for the browser test"
        $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null \
            || echo "note: apt-get could not install chromium: the browser test will be skipped"
    else
        echo "note: Chromium is not installed and this user can neither apt-get nor sudo: the browser test will be skipped (install Debian's chromium to run it)"
    fi
fi
echo "== installing softrod with its test and docs extras (builds the Rust core)"
"$PY" -m pip install --quiet --disable-pip-version-check -e ".[test,docs]"
echo "== format and lint"
cargo fmt --all --check
cargo clippy --quiet -p softrod-core -p softrod-py --all-targets -- -D warnings
"$PY" -m ruff format --check python tests benchmarks examples
"$PY" -m ruff check python tests benchmarks examples
echo "== Rust tests"
cargo test -p softrod-core --quiet
echo "== Python tests"
"$PY" -m pytest -q --hypothesis-profile=reproducible
