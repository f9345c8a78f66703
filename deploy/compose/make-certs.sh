#!/usr/bin/env bash
# The certificates of the compose deployment (docker-compose.yml's `certs` service
# runs this in the image; run it yourself with TELEOP=path/to/teleop): a certificate
# authority and, for each identity, a certificate whose common name is the identity the
# routers' access control knows, with the names and addresses it is reached at.
# Identities already in DIR are kept, so `up` after `up` changes nothing.
#
#   make-certs.sh DIR        (TELEOP_CERT_DAYS: validity, default 30)
set -euo pipefail
OUT=${1:?usage: make-certs.sh DIR}
TELEOP=${TELEOP:-teleop}
exec "$TELEOP" certs --out "$OUT" --keep-existing --days "${TELEOP_CERT_DAYS:-30}" \
  local-router=172.30.1.2 \
  remote-router=172.30.2.2,172.30.9.2,remote-site.wan \
  remote_sim pr2_arm_controller shadow_hand_controller feedback_publisher \
  local_sim wrist_tracker camera_arm hand_inference operator_display \
  teleop-observer
