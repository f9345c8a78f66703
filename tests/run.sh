#!/usr/bin/env bash
# The project's test command (README): formatting, lints, and every test, including the
# interop tests against the independent Python implementation `rosbags`, and the hand
# model test, whose ONNX Runtime library comes from the PyPI `onnxruntime` wheel.
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/teleop-target}"

# Python environment for the interop tests and ONNX Runtime (outside the clone, reused
# between runs; the hand-inference crate finds libonnxruntime.so there).
venv="${TELEOP_VENV:-$HOME/.cache/teleop-venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r tests/interop/requirements.txt
export TELEOP_PYTHON="$venv/bin/python"
export TELEOP_VENV="$venv"

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy -D warnings"
cargo clippy --release --workspace --all-targets --locked -- -D warnings
echo "== cargo build (node binaries, for the launch test)"
cargo build --release --workspace --bins --locked
echo "== cargo test"
cargo test --release --workspace --locked
echo "== compose test (both sites as containers: deploy/compose/test.sh; TELEOP_SKIP_DOCKER=1 skips it where there is no Docker engine)"
SKIP_CARGO_BUILD=1 bash deploy/compose/test.sh
