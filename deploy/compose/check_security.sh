#!/usr/bin/env bash
# Security between the sites, tried against the running compose system (the last step
# of deploy/compose/test.sh, which exports what this needs). The operator site's
# commanders (wrist tracker, hand inference) are stopped first, so that nothing but the
# attempts below could reach the robot site's controllers:
#
#   1. no connection: a certificate of another authority; no TLS at all;
#   2. valid certificates, no permission: an unknown identity on the operator's LAN
#      and on the WAN (straight at the robot site's router), the observer identity
#      publishing, a robot-site identity at the operator's router; each holds clutch
#      and enable and sends wrist poses for 2 s. Checked: the PR2 arm controller
#      received none of it (its counters), the arm did not move;
#   3. the operator site's own identity (a compromised or broken operator node) sends
#      across the WAN malformed bytes, samples stamped 5 s in the future, a replayed
#      (older) sequence number, NaN poses: each is refused and counted at the robot
#      site, by kind; the arm did not move;
#   4. identity claims: while the real wrist tracker runs, hand inference's identity
#      announces `wrist_tracker` and sends wrist poses (before the commanders stop);
#      the feedback publisher's identity, on the robot's LAN, announces
#      `pr2_arm_controller` and sends arm commands; strangers and nodes query the
#      routers' admin space (`@/**`). Checked at the robot site: one node of each name
#      in the graph, no sample of the claimed publishers (their GIDs) while the real
#      controller's commands are heard, the arm did not move; no admin-space reply but
#      to the observer.
#
# Needs: COMPOSE_PROJECT_NAME, TELEOP_IMAGE, TELEOP_CERTS, TELEOP_REPORT_DIR, COMPOSE_FILE_PATH.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=checks-common.sh
source "$HERE/checks-common.sh"
OUT=$TELEOP_REPORT_DIR/security
mkdir -p "$OUT"

# `teleop` in a throwaway container on network $1, with identity files from $2 (a
# directory mounted at /id) for identity $3, against router endpoint $4; the rest is
# the teleop command.
as() {
  local net=$1 dir=$2 who=$3 endpoint=$4
  shift 4
  local tls=()
  if [[ $who != none ]]; then
    tls=(--tls-ca /certs/ca.pem --tls-cert "/id/$who.pem" --tls-key "/id/$who.key")
  fi
  docker run --rm --network "${COMPOSE_PROJECT_NAME}_$net" -v "$TELEOP_CERTS:/certs:ro" \
    -v "$dir:/id:ro" "$IMAGE" teleop --mode client --connect "$endpoint" \
    --no-multicast-scouting "${tls[@]}" "$@"
}
LOCAL=tls/172.30.1.2:7447
REMOTE=tls/172.30.2.2:7447
REMOTE_WAN=tls/172.30.9.2:7447
# On the robot site's LAN, where hardware topics may travel.
observe() { as remote_lan "$TELEOP_CERTS" teleop-observer "$REMOTE" --hardware-interface '*' "$@"; }

# The arm controller's newest counters and one arm encoder sample, to $1.json / .arm.
snapshot() {
  observe topic echo /teleop/status --format json --duration-s 2.6 >"$OUT/$1.status" 2>/dev/null || true
  observe topic echo /teleop/hw/pr2_arm/state --format json -n 1 --duration-s 3 >"$OUT/$1.arm" 2>/dev/null || true
}

# An identity the deployment does not know, signed by the deployment's authority.
docker run --rm -v "$TELEOP_CERTS:/certs" "$IMAGE" teleop certs --out /certs --keep-existing intruder >/dev/null

# 4a. While the real wrist tracker runs: hand inference's identity claims its name.
CLAIM_GID=c1a1c1a1c1a1c1a1c1a1c1a1c1a1c1a1
as local_lan "$TELEOP_CERTS" hand_inference "$LOCAL" topic pub /teleop/wrist_pose \
  '{header: {frame_id: ur5_base}, pose: {position: {x: 0.7, z: 0.3}, orientation: {w: 1.0}}}' \
  --stamp-now --rate-hz 50 --duration-s 4 --node wrist_tracker --gid "$CLAIM_GID" >/dev/null 2>&1 &
sleep 1.5
observe node list --wait-s 1.5 >"$OUT/claim-wrist.nodes" 2>/dev/null &
observe topic echo /teleop/wrist_pose --format json --duration-s 2 >"$OUT/claim-wrist.echo" 2>/dev/null &
wait
# The admin space: the routers answer their observer identity alone.
for who in "teleop-observer local_lan $LOCAL" "intruder local_lan $LOCAL" \
  "intruder wan_remote $REMOTE_WAN" "wrist_tracker local_lan $LOCAL" \
  "pr2_arm_controller remote_lan $REMOTE"; do
  read -r id net endpoint <<<"$who"
  as "$net" "$TELEOP_CERTS" "$id" "$endpoint" query '@/**' --timeout-s 2 \
    >"$OUT/admin-$id-$net.log" 2>&1 || true
done

echo "security: the operator site's commanders stopped; nothing else commands the robot"
compose stop -t 5 pc1-wrist-tracker pc1-hand-inference >/dev/null 2>&1
sleep 1.5
snapshot before

# Identities the deployment does not know: one signed by another authority.
ROGUE=$OUT/rogue-ca
docker run --rm -v "$OUT:/out" "$IMAGE" teleop certs --out /out/rogue-ca wrist_tracker >/dev/null

# 1. No connection without a certificate of the authority, nor without TLS.
refused=0
for attempt in "rogue $ROGUE wrist_tracker $LOCAL" "plain $TELEOP_CERTS none tcp/172.30.1.2:7447"; do
  read -r name dir who endpoint <<<"$attempt"
  if as local_lan "$dir" "$who" "$endpoint" node list --wait-s 1 >"$OUT/$name.log" 2>&1; then
    echo "security: a client with $name credentials connected to the operator site's router"
    cat "$OUT/$name.log"
    exit 1
  fi
  refused=$((refused + 1))
done
echo "security: $refused clients without a valid certificate could not connect ($(grep -h -o -m1 'Unable to connect[^!]*' "$OUT"/rogue.log "$OUT"/plain.log | head -1 || echo refused))"

# 2. Valid certificates without permission try to drive the arm.
drive() { # network dir identity endpoint node-name
  local net=$1 dir=$2 who=$3 endpoint=$4 node=$5
  as "$net" "$dir" "$who" "$endpoint" topic pub /teleop/operator_input \
    '{enable: true, clutch: true, motion_scale: 1.0}' --stamp-now --rate-hz 50 \
    --duration-s 2 --node "$node" >/dev/null 2>&1 &
  as "$net" "$dir" "$who" "$endpoint" topic pub /teleop/wrist_pose \
    '{header: {frame_id: ur5_base}, pose: {position: {x: 0.5, z: 0.3}, orientation: {w: 1.0}}}' \
    --stamp-now --rate-hz 50 --duration-s 2 --node "$node" >/dev/null 2>&1 &
  wait
}
drive local_lan "$TELEOP_CERTS" intruder "$LOCAL" wrist_tracker
drive wan_remote "$TELEOP_CERTS" intruder "$REMOTE_WAN" wrist_tracker
drive local_lan "$TELEOP_CERTS" teleop-observer "$LOCAL" teleop_cli_1
drive local_lan "$TELEOP_CERTS" pr2_arm_controller "$LOCAL" pr2_arm_controller
snapshot unauthorised

# 3. The operator's own identity, across the WAN: bad samples, each kind refused. One
# forged publisher GID throughout, so the arm's one-commander lock is never in the way.
GID=7e1e0b0a7e1e0b0a7e1e0b0a7e1e0b0a
inject() { as local_lan "$TELEOP_CERTS" wrist_tracker "$LOCAL" topic pub /teleop/wrist_pose \
  --node wrist_tracker --gid "$GID" --rate-hz 10 --wait-s 1 "$@" >/dev/null 2>&1; }
POSE='{header: {frame_id: ur5_base}, pose: {position: {x: 0.5, z: 0.3}, orientation: {w: 1.0}}}'
inject --raw-hex deadbeef01020304 -n 5 --first-sequence 1
inject "$POSE" --stamp-offset-ms 5000 -n 5 --first-sequence 10
inject "$POSE" -n 1 --first-sequence 100
inject "$POSE" -n 3 --first-sequence 50
inject '{header: {frame_id: ur5_base}, pose: {position: {x: .nan, z: 0.3}, orientation: {w: 1.0}}}' \
  -n 5 --first-sequence 200
snapshot injected

# 4b. The feedback publisher's identity, on the robot's LAN, claims the arm controller's
# name and sends 0.5 rad/s to every arm joint.
ARM_CLAIM_GID=c1a1b2b2c1a1b2b2c1a1b2b2c1a1b2b2
as remote_lan "$TELEOP_CERTS" feedback_publisher "$REMOTE" --hardware-interface '*' topic pub \
  /teleop/hw/pr2_arm/command \
  '{name: [r_shoulder_pan_joint, r_shoulder_lift_joint, r_upper_arm_roll_joint, r_elbow_flex_joint, r_forearm_roll_joint, rh_WRJ2, rh_WRJ1], velocity: [0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]}' \
  --stamp-now --rate-hz 100 --duration-s 4 --node pr2_arm_controller --gid "$ARM_CLAIM_GID" >/dev/null 2>&1 &
sleep 1.5
observe node list --wait-s 1.5 >"$OUT/claim-arm.nodes" 2>/dev/null &
observe topic echo /teleop/hw/pr2_arm/command --format json --duration-s 2 >"$OUT/claim-arm.echo" 2>/dev/null &
wait
snapshot claimed

python3 "$HERE/check_security.py" "$OUT" "$CLAIM_GID" "$ARM_CLAIM_GID"
