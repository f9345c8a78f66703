#!/usr/bin/env bash
# The project's test command (README): formatting, lints, and every test, including the
# interop tests against the independent Python implementation `rosbags`.
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/teleop-target}"

# Python environment for the interop tests (outside the clone, reused between runs).
venv="${TELEOP_VENV:-$HOME/.cache/teleop-venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r tests/interop/requirements.txt
export TELEOP_PYTHON="$venv/bin/python"

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy -D warnings"
cargo clippy --release --workspace --all-targets --locked -- -D warnings
echo "== cargo build (node binaries, for the launch test)"
cargo build --release --workspace --bins --locked
echo "== cargo test"
cargo test --release --workspace --locked
