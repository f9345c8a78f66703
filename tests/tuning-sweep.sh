#!/usr/bin/env bash
# The arms' gains compared in the closed loop (docs/local-site.md, "Tuning the arms"):
# `teleop launch --task pick_and_place` once per row, both arms alike unless noted.
# Needs the binaries: cargo build --release --workspace --bins. Prints a Markdown table.
set -u
cd "$(dirname "$0")/.."
out=${OUT:-/tmp/teleop-tuning-sweep}; mkdir -p "$out"
B=${CARGO_TARGET_DIR:-$HOME/.cache/teleop-target}/release
row() { # name w_cam d1 k w_pr2
  local name=$1 wc=$2 d1=$3 k=$4 wp=$5 d=$out/cfg-$1
  rm -rf $d; cp -r deploy/defaults $d
  for f in $d/camera_arm.toml $d/pr2_arm_controller.toml; do
    sed -i "s/^d1 = .*/d1 = $d1/; s/^feedback_gain_per_s = .*/feedback_gain_per_s = $k/" $f
  done
  sed -i "s/^regularization_weight = .*/regularization_weight = $wc/" $d/camera_arm.toml
  sed -i "s/^regularization_weight = .*/regularization_weight = $wp/" $d/pr2_arm_controller.toml
  $B/teleop launch --quiet --task pick_and_place --config-dir $d --report-dir $out/r-$name > $out/$name.log 2>&1
  python3 - "$name" "$wc" "$wp" "$d1" "$k" "$out" <<'PY'
import json,sys
n,wc,wp,d1,k,_=sys.argv[1:]
r=json.load(open(f'{sys.argv[6]}/r-{n}/report.json'))
c=r['camera_position_error_m'];p=r['pr2_position_error_m']
print(f"| {wc} / {wp} | {d1} | {k} | {c['mean']*100:.2f} | {c['max']*100:.1f} | {r['camera_best_fit_delay_ms']:.0f} | {p['mean']*1000:.1f} | {p['max']*1000:.1f} | {r['pr2_best_fit_delay_ms']:.0f} | {r['fraction_hand_fully_in_view']*100:.1f} |")
PY
}
echo "| regularization camera / PR2 | d1 | k (/s) | camera mean (cm) | camera max (cm) | camera delay (ms) | PR2 mean (mm) | PR2 max (mm) | PR2 delay (ms) | hand in view (%) |"
echo "|---|---|---|---|---|---|---|---|---|---|"
row thesis 0.5 0.7 3.0 0.5
row d1 0.5 1.0 3.0 0.5
row d1k10 0.5 1.0 10.0 0.5
row w02thesislaw 0.2 0.7 3.0 0.2
row d1w02 0.2 1.0 3.0 0.2
row defaults 0.2 1.0 10.0 0.3
row allw02 0.2 1.0 10.0 0.2
row pr2w04 0.2 1.0 10.0 0.4
