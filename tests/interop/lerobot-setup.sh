#!/usr/bin/env bash
# Makes the Python environment in which the `lerobot` package (PyPI) checks the datasets
# of `teleop export lerobot` (tests/interop/check_lerobot.py): $TELEOP_LEROBOT_VENV,
# default $HOME/.cache/teleop-lerobot-venv. Prints the environment's python.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="${TELEOP_LEROBOT_VENV:-$HOME/.cache/teleop-lerobot-venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
pip=("$venv/bin/python" -m pip --quiet --disable-pip-version-check)
"${pip[@]}" install -r "$here/lerobot-requirements.txt" >&2
"${pip[@]}" install --no-deps lerobot==0.4.4 >&2
# Fails here, not in the test, if the loader does not import.
(cd /tmp && "$venv/bin/python" -c 'from lerobot.datasets.lerobot_dataset import LeRobotDataset' >&2)
echo "$venv/bin/python"
