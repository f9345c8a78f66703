#!/usr/bin/env bash
# Builds the runtime image `teleop:local` WITHOUT a container registry: the binaries
# built on this host (Debian 12, the same glibc as the base image), stripped, with the
# ONNX Runtime and MuJoCo libraries, the hand model and the configs, on the base image that
# make-base-image.sh makes from Debian's packages. The registry way is
# deploy/docker/Dockerfile (multi-stage, FROM rust / debian:bookworm-slim).
#
#   deploy/docker/build-images.sh     # cargo build --release, base image, runtime image
#
# Environment: CARGO_TARGET_DIR (where cargo builds; default <repo>/target),
# TELEOP_IMAGE (default teleop:local), TELEOP_BASE_IMAGE (default teleop-base:bookworm),
# SKIP_CARGO_BUILD=1 (use the binaries already built).
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
IMAGE=${TELEOP_IMAGE:-teleop:local}
BASE=${TELEOP_BASE_IMAGE:-teleop-base:bookworm}
# The node table's binaries (shared/interfaces/src/nodes.rs) and the `teleop` tool
# (router, report, inspection), and the WAN link emulator. tests/compose.rs checks this
# list against the table.
BINARIES=(teleop wan_link remote_sim pr2_arm_controller shadow_hand_controller feedback_publisher
  local_sim wrist_tracker camera_arm hand_inference operator_display)

if [[ ${SKIP_CARGO_BUILD:-0} != 1 ]]; then
  (cd "$ROOT" && cargo build --release --workspace --bins --locked)
fi
TELEOP_BASE_IMAGE=$BASE bash "$ROOT/deploy/docker/make-base-image.sh"

CTX="$TARGET/docker-context"
rm -rf "$CTX"
mkdir -p "$CTX/bin" "$CTX/lib" "$CTX/local_site/models/hand"
for b in "${BINARIES[@]}"; do
  install -m 0755 "$TARGET/release/$b" "$CTX/bin/$b"
  strip "$CTX/bin/$b"
done
# ONNX Runtime: the library hand inference runs with on this host (the pinned PyPI
# wheel's; --ensure-runtime installs it into the project's environment if missing).
# It prints "<path> (via <where it was found>)".
ORT=$("$TARGET/release/hand_inference" --ensure-runtime | tail -1 | sed "s/ (via .*//")
[[ -f $ORT ]] || { echo "build-images: no ONNX Runtime library ($ORT)"; exit 1; }
cp "$ORT" "$CTX/lib/libonnxruntime.so"
for extra in "$(dirname "$ORT")"/libonnxruntime_providers_shared.so; do
  [[ -f $extra ]] && cp "$extra" "$CTX/lib/"
done
# MuJoCo: the library remote_sim links (the pinned `mujoco` wheel's, found or installed
# by the build), where the binaries' run path ($ORIGIN/../lib) finds it in the image.
MJ=$(ldd "$TARGET/release/remote_sim" | awk '/libmujoco/ {print $3}')
[[ -f $MJ ]] || { echo "build-images: remote_sim links no MuJoCo library (ldd: $MJ)"; exit 1; }
cp -L "$MJ" "$CTX/lib/"
# The model and its offline evaluation (the report judges the hand joint goal by it).
cp "$ROOT/local_site/models/hand/model.onnx" "$ROOT/local_site/models/hand/report.json" \
  "$CTX/local_site/models/hand/"
cp -r "$ROOT/deploy" "$CTX/deploy"
cp "$ROOT/deploy/docker/Dockerfile.runtime" "$CTX/Dockerfile"
docker build -q --build-arg "BASE=$BASE" -t "$IMAGE" "$CTX" >/dev/null
docker image inspect "$IMAGE" --format "build-images: {{.RepoTags}} {{.Size}} bytes"
