#!/usr/bin/env bash
# Creates the training environment ($HOME/.cache/teleop-train-venv) from PyPI with the
# pinned requirements. Training is not part of CI; the runtime does not need it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="${TELEOP_TRAIN_VENV:-$HOME/.cache/teleop-train-venv}"
if [[ ! -x "$venv/bin/python" ]]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet -r "$here/requirements.txt"
echo "training environment ready: $venv/bin/python"
