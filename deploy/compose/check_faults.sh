#!/usr/bin/env bash
# Fault tests against a running compose system (a step of deploy/compose/test.sh; by
# hand against any running stack): each container in turn is killed (SIGKILL: a crash,
# a pulled plug) during a clutched motion and started again 2.5 s later. Listeners on
# both site LANs record every node's status and the robots' joint states; for each
# container check_faults.py checks:
#
#   * every other container kept running;
#   * the robots its commands drive stopped while it was gone (a controller's robot
#     brakes in the hardware safety layer; a commander's robot is stopped by its
#     controller's watchdogs);
#   * it reconnected: its status (for a router: its site's stream across the WAN, the
#     wrist poses or the PR2 joint states) reached the other site again within 1 s of
#     the container running again.
#
#   check_faults.sh [SERVICE...]     (default: every node container and both routers)
#
# Needs: COMPOSE_PROJECT_NAME, TELEOP_IMAGE, TELEOP_CERTS, TELEOP_REPORT_DIR.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=checks-common.sh
source "$HERE/checks-common.sh"
OUT=$TELEOP_REPORT_DIR/faults
mkdir -p "$OUT"
SERVICES=("$@")
if [[ ${#SERVICES[@]} == 0 ]]; then
  SERVICES=(pc1-wrist-tracker pc1-camera-arm pc1-hand-inference pc3-local-sim pc2-arm pc2-hand
    pc2-feedback robot-sim local-router remote-router)
fi
ALL=(local-router wan-link remote-router robot-sim pc2-arm pc2-hand pc2-feedback
  pc1-wrist-tracker pc1-camera-arm pc1-hand-inference pc3-local-sim)

# Every node runs, and the link is clear (an earlier step may have left either).
compose start pc1-wrist-tracker pc1-hand-inference >/dev/null 2>&1 || true
link reset >/dev/null
failed=()
for s in "${SERVICES[@]}"; do
  tag=$s
  # A kill can only be judged while the PR2 moves: if it has not moved 14 s into the
  # task (the arm waited for a fresh clutch press once, right after the WAN sweep: a CI
  # run here, 2026-12-06), the task starts over, at most three times in all, the tries
  # counted in the log; after the third the kill comes anyway and the check says why.
  # The container by id (the docker client, not Compose v1's second of CPU), killed and
  # started with the engine's own commands: they take milliseconds where Compose v1
  # takes about a second, so the times below are sharp. A restart keeps the id.
  id=$(service_id "$s")
  for try in 1 2 3; do
    rm -f "$OUT/$tag"-*.jsonl
    ids=$(listen remote "$tag-r" 32 /teleop/status /teleop/hw/pr2_arm/state /teleop/hw/shadow_hand/state /teleop/wrist_pose
      listen local "$tag-l" 32 /teleop/status /teleop/hw/ur5/state /teleop/pr2/joint_states)
    sleep 1.5
    # The task from its start: the operator presses the clutch 2 s in.
    compose restart -t 5 pc3-local-sim >/dev/null 2>&1
    # The kill comes while the PR2 moves (some joint faster than 0.05 rad/s over the
    # robot LAN listener's newest 0.1 s window, by position: the velocity a sample
    # reports carries contact chatter on MuJoCo, check_faults.py), at most 14 s in.
    if python3 "$HERE/check_faults.py" --wait-moving "$OUT/$tag-r-pr2_arm-state.jsonl" 14 0.05
    then
      break
    fi
    echo "faults: the PR2 did not move within 14 s of the task's start (try $try of 3)"
    if [[ $try == 3 ]]; then
      echo "faults: killing anyway"
      break
    fi
    # shellcheck disable=SC2086
    docker rm -f $ids >/dev/null 2>&1 || true
  done
  t_kill=$(date +%s.%N)
  docker kill "$id" >/dev/null
  t_killed=$(date +%s.%N)
  sleep 2.5
  # The running containers by compose's labels with the docker client (docker-compose
  # v1's `ps` once left out a router whose streams went on: a run here, 2026-12-06).
  mapfile -t running < <(docker ps --filter "label=com.docker.compose.project=$COMPOSE_PROJECT_NAME" \
    --filter status=running --format '{{.Label "com.docker.compose.service"}}' 2>/dev/null || true)
  others_down=()
  for o in "${ALL[@]}"; do
    [[ $o == "$s" ]] && continue
    printf '%s\n' "${running[@]}" | grep -qx "$o" && continue
    # Not in the list: asked of the engine for that container itself (`docker ps` left
    # out pc1-hand-inference once while its node's statuses went on at 1 Hz: a CI run
    # here, 2026-12-06). There is no restart policy: a container that died stays down.
    oid=$(docker ps -aq --filter "label=com.docker.compose.project=$COMPOSE_PROJECT_NAME" \
      --filter "label=com.docker.compose.service=$o" | head -1)
    [[ -n $oid && "$(docker inspect -f '{{.State.Running}}' "$oid" 2>/dev/null)" == true ]] \
      || others_down+=("$o")
  done
  t_start=$(date +%s.%N)
  docker start "$id" >/dev/null
  t_running=$(date +%s.%N)
  # shellcheck disable=SC2086
  docker wait $ids >/dev/null 2>&1 || true
  echo "faults: $s killed during a clutched motion, started again 2.5 s later"
  if ! python3 "$HERE/check_faults.py" "$OUT" "$tag" "$s" "$t_kill" "$t_killed" "$t_start" "$t_running" \
      "${others_down[*]:-}"; then
    failed+=("$s")
    compose logs --no-color --tail 15 "$s" || true
  fi
  # The next container's turn starts from a whole system.
  sleep 2
done
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "faults: FAILED for ${failed[*]}"
  exit 1
fi
echo "faults: passed (${#SERVICES[@]} containers killed and restarted in turn)"
