#!/usr/bin/env bash
# Builds the base image `teleop-base:bookworm` without a container registry: a minimal
# Debian 12 (bookworm) root filesystem made by debootstrap from Debian's package
# archive, imported with `docker import`. The root filesystem is cached as a tarball in
# ${TELEOP_DOCKER_CACHE:-$HOME/.cache/teleop-docker}, so a warm machine only imports it.
#
#   deploy/docker/make-base-image.sh            # build (or reuse) teleop-base:bookworm
#   deploy/docker/make-base-image.sh --force    # rebuild the root filesystem
#
# Needs root (debootstrap) and the debootstrap package (installed with apt-get if
# missing). Users with a registry do not need this: deploy/docker/Dockerfile starts
# from debian:bookworm-slim.
set -euo pipefail

IMAGE=${TELEOP_BASE_IMAGE:-teleop-base:bookworm}
CACHE=${TELEOP_DOCKER_CACHE:-$HOME/.cache/teleop-docker}
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
# libstdc++6 and libgcc-s1 (in minbase) for ONNX Runtime; iproute2 to look at a
# container's links; fonts-dejavu-core for the report's plot.
PACKAGES=iproute2,ca-certificates,fonts-dejavu-core
# The cache and the image are keyed by the package list: change it and both are remade.
KEY=$(echo "bookworm minbase $PACKAGES" | sha256sum | cut -c1-12)
TARBALL="$CACHE/bookworm-minbase-$KEY.tar"
FORCE=0
[[ ${1:-} == --force ]] && FORCE=1

if [[ $FORCE == 0 ]] &&
  [[ $(docker image inspect "$IMAGE" --format '{{index .Config.Labels "teleop.base"}}' 2>/dev/null) == "$KEY" ]]; then
  echo "make-base-image: $IMAGE exists ($KEY)"
  exit 0
fi
mkdir -p "$CACHE"
AS_ROOT=()
if [[ $(id -u) != 0 ]]; then
  command -v sudo >/dev/null || { echo "make-base-image: debootstrap needs root (or sudo)"; exit 1; }
  AS_ROOT=(sudo)
fi
if [[ $FORCE == 1 || ! -s $TARBALL ]]; then
  if ! command -v debootstrap >/dev/null; then
    echo "make-base-image: installing debootstrap"
    "${AS_ROOT[@]}" apt-get install -y debootstrap >/dev/null 2>&1 ||
      { "${AS_ROOT[@]}" apt-get update >/dev/null && "${AS_ROOT[@]}" apt-get install -y debootstrap >/dev/null; }
  fi
  ROOT=$(mktemp -d "$CACHE/rootfs.XXXXXX")
  trap '"${AS_ROOT[@]}" rm -rf "$ROOT"' EXIT
  echo "make-base-image: debootstrap bookworm (minbase) from $MIRROR"
  "${AS_ROOT[@]}" debootstrap --variant=minbase --include="$PACKAGES" bookworm "$ROOT" "$MIRROR" \
    >"$CACHE/debootstrap.log" 2>&1 ||
    { tail -20 "$CACHE/debootstrap.log"; echo "make-base-image: debootstrap failed"; exit 1; }
  # A smaller image: no package lists, caches or docs.
  "${AS_ROOT[@]}" rm -rf "$ROOT"/var/cache/apt/archives/*.deb "$ROOT"/var/lib/apt/lists/* \
    "$ROOT"/usr/share/doc/* "$ROOT"/usr/share/man/* "$ROOT"/usr/share/locale/*
  "${AS_ROOT[@]}" tar -C "$ROOT" -cf "$TARBALL.partial" .
  mv "$TARBALL.partial" "$TARBALL"
fi
echo "make-base-image: importing $TARBALL as $IMAGE"
docker import --change 'CMD ["/bin/bash"]' --change "LABEL teleop.base=$KEY" "$TARBALL" "$IMAGE" >/dev/null
docker image inspect "$IMAGE" --format 'make-base-image: {{.RepoTags}} {{.Size}} bytes'
