#!/usr/bin/env bash
# Reproduces the shipped hand model and the comparison: datasets (~5 minutes), the
# baseline (60 minutes: the committed model), then TeachNet and Transteleop (15 and 30
# minutes) on the 2-core machine.
#   local_site/training/train_all.sh [DATA_DIR] [RUNS_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
data="${1:-$HOME/.cache/teleop-hand-data}"
runs="${2:-$HOME/.cache/teleop-hand-runs}"
py="${TELEOP_TRAIN_VENV:-$HOME/.cache/teleop-train-venv}/bin/python"
[[ -x "$py" ]] || "$here/setup.sh"
cargo build --release --manifest-path "$root/Cargo.toml" -p teleop-hand-dataset
gen="${CARGO_TARGET_DIR:-$root/target}/release/hand_dataset"
make_set() { [[ -f "$data/$1/manifest.json" ]] || "$gen" --out "$data/$1" --preset "$2" --count "$3" --seed "$4" --quiet; }
make_set train train 120000 1
make_set val test 2000 2
make_set test test 3000 3
for p in ood-views ood-far ood-shapes ood-roll; do make_set "$p" "$p" 1000 4; done
train() { "$py" "$here/train.py" --model "$1" --train "$data/train" --val "$data/val" --minutes "$2" --out "$runs/$1"; }
train baseline 60
train teachnet 15
train transteleop 30
