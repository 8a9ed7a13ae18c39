#!/usr/bin/env bash
# Every test of softrod from a fresh clone: installs the package with its test and docs extras
# (this builds the Rust extension) and runs the Python tests (the docs' examples, the API
# reference build and the stub check included) and ruff; beside them, cargo fmt, clippy and the
# Rust tests. Exits non-zero when anything failed. Needs Python >= 3.10 with pip, and Rust
# (https://rustup.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v cargo >/dev/null || { echo "error: cargo not found; install Rust (https://rustup.rs)" >&2; exit 1; }
PY=${PYTHON:-python3}
# Both the extension and the Rust tests are built in the `checked` profile (Cargo.toml: the
# release build with debug assertions and overflow checks), so the core compiles once: the
# Rust tests select softrod-py too, which gives the shared dependencies the same features as
# the extension's build. The Rust side (format, clippy, the Rust tests) runs in the background
# beside the Python side (install, ruff, pytest): the compiles are mostly single-threaded, so
# on two cores the sides overlap. Cargo locks each profile's directory: clippy runs beside the
# install, the Rust tests wait for the core the install compiles (or compile it first, and the
# install finds it built). The Rust side's output is printed when the Python tests end.
export MATURIN_PEP517_ARGS="--profile checked"
rust_log=$(mktemp "${TMPDIR:-/tmp}/softrod-rust-side.XXXXXX")
echo "== Rust side (cargo fmt --check, clippy, cargo test) started in the background; its output follows the Python tests"
(
    set -e
    echo "== format and lint (Rust)"
    cargo fmt --all --check
    cargo clippy --quiet -p softrod-core -p softrod-py --all-targets -- -D warnings
    echo "== Rust tests"
    cargo test --profile checked -p softrod-core -p softrod-py --quiet
) >"$rust_log" 2>&1 &
rust_pid=$!
# Stopped or failed early (Ctrl-C, a failed install): do not leave the Rust side running, and
# show what it printed so far (the log is removed once it has been printed at the end).
stop_rust_side() {
    kill "$rust_pid" 2>/dev/null || true
    if [ -f "$rust_log" ]; then
        echo "== Rust side stopped early; its output so far:"
        cat "$rust_log"
        rm -f "$rust_log"
    fi
}
trap stop_rust_side EXIT
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
echo "== installing softrod with its test and docs extras (builds the Rust core, checked profile)"
"$PY" -m pip install --quiet --disable-pip-version-check -e ".[test,docs]"
echo "== format and lint (Python)"
"$PY" -m ruff format --check python tests benchmarks examples
"$PY" -m ruff check python tests benchmarks examples
echo "== Python tests"
python_rc=0
"$PY" -m pytest -q --hypothesis-profile=reproducible || python_rc=$?
rust_rc=0
wait "$rust_pid" || rust_rc=$?
cat "$rust_log"
rm -f "$rust_log"
if [ "$python_rc" != 0 ] || [ "$rust_rc" != 0 ]; then
    echo "error: the Python side exited with $python_rc, the Rust side with $rust_rc (0 = passed)" >&2
    exit 1
fi
echo "== all passed: Rust side and Python side"
