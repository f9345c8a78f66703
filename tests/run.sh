#!/usr/bin/env bash
# The project's test command (README): installs what the tests need (on a fresh machine
# too), then formatting, lints, and every test, including the interop tests against the
# independent Python implementation `rosbags`, the hand model test (ONNX Runtime's library
# from the PyPI `onnxruntime` wheel), the physics tests (MuJoCo's library from the PyPI
# `mujoco` wheel), the browser test (Debian's chromium) and the compose test.
# Every cargo test binary runs even when one fails (--no-fail-fast), and the compose test
# runs after a failed cargo test too; the script fails at the end if anything failed.
set -euo pipefail
cd "$(dirname "$0")/.."

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/teleop-target}"

# Debian packages: run as root, or through sudo where there is one.
as_root=()
if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null 2>&1; then as_root=(sudo); fi
apt_updated=0
apt_install() { # apt_install PACKAGE CHECK-COMMAND...
  local package="$1"; shift
  if "$@" >/dev/null 2>&1; then return 0; fi
  if [ "$apt_updated" -eq 0 ]; then
    "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null || true
    apt_updated=1
  fi
  if ! "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
      --no-install-recommends "$package" >/dev/null || ! "$@" >/dev/null 2>&1; then
    echo "error: the Debian package $package is missing and could not be installed with" \
         "apt-get; install it (apt-get install $package) and re-run" >&2
    exit 1
  fi
}
# The pictures' font: the tools and examples draw text with DejaVu Sans, read at run time.
apt_install fonts-dejavu-core test -f /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf
# The operator display's browser test drives headless Chromium.
apt_install chromium command -v chromium
# mujoco-rs's build script asks pkg-config for MuJoCo (.cargo/config.toml).
apt_install pkgconf command -v pkg-config
# pyzeros (the ros2_control stand-in's ROS 2 client) compiles its serializers with
# Cython on first use: a C compiler and the Python headers.
apt_install gcc command -v gcc
apt_install python3-dev test -f "$(python3 -c 'import sysconfig; print(sysconfig.get_paths()["include"])')/Python.h"

# Python environment for the interop tests, ONNX Runtime and MuJoCo (outside the clone,
# reused between runs; the hand-inference crate finds libonnxruntime.so there, the
# physics crate's build script libmujoco.so).
venv="${TELEOP_VENV:-$HOME/.cache/teleop-venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r tests/interop/requirements.txt
export TELEOP_PYTHON="$venv/bin/python"
export TELEOP_VENV="$venv"

# LeRobot, which loads the datasets of `teleop export lerobot` in their test
# (deploy/teleop/tests/lerobot.rs), in its own environment (large: torch); its video
# decoder, torchcodec, needs FFmpeg's libraries.
apt_install ffmpeg command -v ffmpeg
TELEOP_LEROBOT_PYTHON="$(bash tests/interop/lerobot-setup.sh)"
export TELEOP_LEROBOT_PYTHON

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy -D warnings"
cargo clippy --release --workspace --all-targets --locked -- -D warnings
echo "== cargo build (node binaries, for the launch test)"
cargo build --release --workspace --bins --locked
failed=()
echo "== cargo test"
cargo test --release --workspace --locked --no-fail-fast || failed+=("cargo test")
echo "== compose test (both sites as containers: deploy/compose/test.sh; TELEOP_SKIP_DOCKER=1 skips it where there is no Docker engine)"
SKIP_CARGO_BUILD=1 bash deploy/compose/test.sh || failed+=("compose test")
if [ "${#failed[@]}" -gt 0 ]; then
  echo "FAILED: ${failed[*]}" >&2
  exit 1
fi
