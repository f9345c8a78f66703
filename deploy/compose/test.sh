#!/usr/bin/env bash
# The compose system end to end: builds the images (offline, deploy/docker/
# build-images.sh), brings both sites up as containers, records the end-of-run report
# of the simulator's scripted task (pick_and_place) at the operator's site, checks its
# figures against the local-site goals and that every container was still running,
# and tears everything down, also when a step fails; then checks that `down` left no
# container, network or volume behind.
#
#   deploy/compose/test.sh [--no-build] [--skip-without-docker] [--sweep=reduced|full|caps|none]
#                          [--no-faults]
#
# --sweep: the WAN-condition sweep at the end (deploy/compose/sweep.sh): the reduced
# set by default (6 conditions, about 4 minutes), the full one (12, about 8 minutes:
# the figures of docs/network.md), the bandwidth caps alone (4), or none.
# --no-faults: leave out the kill-and-restart of the containers (check_faults.sh,
# about 5 minutes).
#
# Without a Docker engine and Compose it says so and fails, unless
# --skip-without-docker (or TELEOP_SKIP_DOCKER=1) is given.
set -euo pipefail

HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
BUILD=1
SKIP=${TELEOP_SKIP_DOCKER:-0}
SWEEP=${TELEOP_SWEEP:-reduced}
FAULTS=1
for a in "$@"; do
  case $a in
    --no-build) BUILD=0 ;;
    --no-faults) FAULTS=0 ;;
    --sweep=*) SWEEP=${a#--sweep=} ;;
    --skip-without-docker) SKIP=1 ;;
    *) echo "compose test: unknown option $a"; exit 2 ;;
  esac
done

if docker compose version >/dev/null 2>&1; then
  COMPOSE=(docker compose)
elif command -v docker-compose >/dev/null 2>&1; then
  COMPOSE=(docker-compose)
else
  COMPOSE=()
fi
if ! docker info >/dev/null 2>&1 || [[ ${#COMPOSE[@]} == 0 ]]; then
  echo "compose test: no Docker engine with Compose on this machine (docker info / docker compose / docker-compose)"
  if [[ $SKIP == 1 ]]; then
    echo "compose test: SKIPPED (--skip-without-docker)"
    exit 0
  fi
  exit 1
fi

# The stack's networks have fixed subnets (the configs name them). A network left by
# an earlier compose test that was killed before its teardown is removed when nothing
# uses it; any other network on one of those subnets (another stack still up) is named,
# with how to stop it, and the test stops here instead of failing inside `up`.
SUBNETS=(172.30.1.0/24 172.30.2.0/24 172.30.8.0/24 172.30.9.0/24)
while read -r net; do
  [[ -z $net ]] && continue
  subnets=$(docker network inspect -f '{{range .IPAM.Config}}{{.Subnet}} {{end}}' "$net" 2>/dev/null || true)
  for s in "${SUBNETS[@]}"; do
    [[ " $subnets " == *" $s "* ]] || continue
    users=$(docker network inspect -f '{{len .Containers}}' "$net" 2>/dev/null || echo 1)
    project=$(docker network inspect -f '{{index .Labels "com.docker.compose.project"}}' "$net" 2>/dev/null || true)
    if [[ $net == teleoptest* && $users == 0 ]]; then
      echo "compose test: removing network $net, left unused by an earlier run ($s)"
      docker network rm "$net" >/dev/null
    else
      echo "compose test: network $net (compose project '${project:-none}', $users container(s)) already uses $s, which this stack needs"
      echo "compose test: stop it first, e.g. docker-compose -p ${project:-<project>} -f deploy/compose/docker-compose.yml down -v"
      exit 1
    fi
  done
done < <(docker network ls --format '{{.Name}}')

# The test measures latencies and tracking errors on this machine's cores: the system's
# programs running outside the stack (a `teleop launch` left running, say) slow every
# container down, and a wrist pose delayed past its 100 ms deadline stops the PR2 for the
# rest of the task. Named here.
others=$(pgrep -a -f '(^|/)(teleop launch|remote_sim|local_sim|pr2_arm_controller|shadow_hand_controller|feedback_publisher|wrist_tracker|camera_arm|hand_inference|operator_display)( |$)' |
  grep -v -e containerd-shim -e "^$$ " || true)
if [[ -n $others ]]; then
  echo "compose test: WARNING: the system's programs are running on this machine outside the stack; the figures will be slower:"
  echo "$others" | head -5
fi

export COMPOSE_PROJECT_NAME=teleoptest$$
export TELEOP_REPORT_DIR TELEOP_CERTS
TELEOP_REPORT_DIR=$(mktemp -d /tmp/teleop-compose-report.XXXXXX)
# The deployment's certificates: made by the compose file's one-shot `certs` service.
TELEOP_CERTS=$TELEOP_REPORT_DIR/certs
# IMAGE, `compose`, `listen` and `link`, as the check scripts have them.
# shellcheck source=checks-common.sh
source "$HERE/checks-common.sh"
teardown() {
  compose --profile report down -v --remove-orphans --timeout 15 >/dev/null 2>&1 || true
}
trap teardown EXIT
echo "compose test: project $COMPOSE_PROJECT_NAME, report in $TELEOP_REPORT_DIR"

if [[ $BUILD == 1 ]]; then
  bash "$ROOT/deploy/docker/build-images.sh"
fi

# The build and the tests before this leave gigabytes of dirty pages; their writeback
# during the task can stall the containers' log writes, and a node blocked on its log
# delays a wrist pose past its deadline (suspected: a CI run with no other load still
# stopped the PR2 on a 119 ms pose). Flushed first.
sync
NODES=(local-router wan-link remote-router robot-sim pc2-arm pc2-hand pc2-feedback
  pc1-wrist-tracker pc1-camera-arm pc1-hand-inference)
compose up -d "${NODES[@]}"
# The recorder first, so it sees the task from its start; then the simulator.
compose run --rm report >"$TELEOP_REPORT_DIR/report.log" 2>&1 &
REPORT=$!
for _ in $(seq 300); do
  grep -q "recording" "$TELEOP_REPORT_DIR/report.log" 2>/dev/null && break
  sleep 0.1
done
compose up -d pc3-local-sim
status=0
wait $REPORT || status=$?
cat "$TELEOP_REPORT_DIR/report.log"
if [[ $status != 0 ]]; then
  echo "compose test: the report failed ($status); the last lines of every container:"
  compose logs --no-color --tail 20
  exit 1
fi
# Every node container still running at the end of the task.
mapfile -t running < <(compose ps --services --filter status=running 2>/dev/null || true)
for s in "${NODES[@]}" pc3-local-sim; do
  if ! printf '%s\n' "${running[@]}" | grep -qx "$s"; then
    echo "compose test: $s is not running at the end of the task"
    compose logs --no-color --tail 30 "$s"
    exit 1
  fi
done
if ! python3 "$HERE/check_report.py" "$TELEOP_REPORT_DIR/report.json" |
  tee "$TELEOP_REPORT_DIR/check.txt"; then
  # Once (CI, 2026-12-04) nothing of the robot site reached the operator's LAN during
  # the task (0 feedback samples in 19 s); the routers' and the WAN's own words then.
  echo "compose test: the report misses its goals; the last lines of the WAN's containers:"
  compose logs --no-color --tail 40 local-router wan-link remote-router pc2-feedback
  # The goals missed again last: CI keeps only the tail of what a run printed.
  echo "compose test: the goals missed:"
  grep -E '^  (BAD|the PR2)' "$TELEOP_REPORT_DIR/check.txt" || true
  exit 1
fi

# Hardware topics stay on their site: a listener on the robot's LAN hears the PR2's
# encoders, one on the operator's LAN (through its router, across the wan) does not,
# though it hears the PR2's joint states that the feedback publisher sends across.
# Probes run as the deployment's observer identity (may watch, never publish).
OBSERVER=(--tls-ca /certs/ca.pem --tls-cert /certs/teleop-observer.pem
  --tls-key /certs/teleop-observer.key)
samples() { # network router-address topic
  docker run --rm --network "${COMPOSE_PROJECT_NAME}_$1" -v "$TELEOP_CERTS:/certs:ro" "$IMAGE" \
    teleop --mode client --connect "tls/$2:7447" --no-multicast-scouting "${OBSERVER[@]}" \
    --hardware-interface '*' topic echo "$3" --format json -n 20 --duration-s 4 2>/dev/null |
    grep -c '"position"' || true
}
hw_robot=$(samples remote_lan 172.30.2.2 /teleop/hw/pr2_arm/state)
hw_operator=$(samples local_lan 172.30.1.2 /teleop/hw/pr2_arm/state)
feedback_operator=$(samples local_lan 172.30.1.2 /teleop/pr2/joint_states)
echo "compose test: PR2 encoder samples heard on remote_lan: $hw_robot, on local_lan: $hw_operator; PR2 feedback samples on local_lan: $feedback_operator"
if [[ $hw_robot -lt 1 || $hw_operator -ne 0 || $feedback_operator -lt 1 ]]; then
  echo "compose test: hardware topics must be heard on the robot's LAN only, feedback at the operator's site"
  exit 1
fi

# Every byte between the sites went through the link emulator, both ways; a partition
# cuts the operator's site off the robot's feedback, and it comes back after.
shown=$(link show)
echo "compose test: wan-link: $shown"
up=$(sed -n 's/.* up_bytes=\([0-9]*\).*/\1/p' <<<"$shown")
down=$(sed -n 's/.* down_bytes=\([0-9]*\).*/\1/p' <<<"$shown")
if [[ ${up:-0} -lt 100000 || ${down:-0} -lt 100000 ]]; then
  echo "compose test: too little traffic through the link emulator (up $up, down $down bytes)"
  exit 1
fi
link partition on >/dev/null
cut_off=$(samples local_lan 172.30.1.2 /teleop/pr2/joint_states)
link partition off >/dev/null
back=$(samples local_lan 172.30.1.2 /teleop/pr2/joint_states)
echo "compose test: PR2 feedback samples at the operator's site during a partition: $cut_off, after it: $back"
if [[ $cut_off -ne 0 || $back -lt 1 ]]; then
  echo "compose test: a partition must cut the feedback off, and the link must come back"
  exit 1
fi

# A 2 s cut of the commands during a clutched motion: the task starts over (the
# simulator restarted: clutch pressed 2 s in), a listener on the robot's LAN records
# the wrist poses and the nodes' statuses, the cut comes 7 s in and lasts 2 s;
# check_partition.py checks the arm stopped in time and stayed stopped without a fresh
# clutch press. The listener runs 24 s: the simulator's restart has taken up to 4 s
# here, and the check needs the poses coming back after the cut. Two cuts: a WAN partition (what the link held is released late and
# must be refused), and the commanding wrist tracker's container paused (a frozen
# process, not a dead one).
cut_test() { # name cut-command restore-command [--released-late]
  local name=$1 cut=$2 restore=$3 flag=${4:-}
  docker run -d --rm --label "com.docker.compose.project=$COMPOSE_PROJECT_NAME" \
    --network "${COMPOSE_PROJECT_NAME}_remote_lan" -v "$TELEOP_REPORT_DIR:/out" \
    -v "$TELEOP_CERTS:/certs:ro" "$IMAGE" sh -c "
      z='--mode client --connect tls/172.30.2.2:7447 --no-multicast-scouting ${OBSERVER[*]}'
      teleop \$z topic echo /teleop/wrist_pose --format json --duration-s 24 >/out/$name-wrist.jsonl &
      teleop \$z topic echo /teleop/status --format json --duration-s 24 >/out/$name-status.jsonl
      wait" >"$TELEOP_REPORT_DIR/probe.id"
  sleep 1.5
  compose restart -t 5 pc3-local-sim
  sleep 7
  local t_on t_off
  t_on=$(date +%s.%N)
  eval "$cut" >/dev/null
  sleep 2
  eval "$restore" >/dev/null
  t_off=$(date +%s.%N)
  docker wait "$(cat "$TELEOP_REPORT_DIR/probe.id")" >/dev/null 2>&1 || true
  echo "compose test: a 2 s $name during a clutched motion"
  python3 "$HERE/check_partition.py" "$TELEOP_REPORT_DIR/$name-wrist.jsonl" \
    "$TELEOP_REPORT_DIR/$name-status.jsonl" "$t_on" "$t_off" $flag
}
# A cut can only be judged if the arm was following when it came; if the arm had
# stopped on its own just before (check_partition.py exits 2 and shows why), the cut
# runs again, at most three times in all, and the tries are counted in the log.
cut_test_judged() {
  local try rc
  for try in 1 2 3; do
    rc=0
    cut_test "$@" || rc=$?
    if [[ $rc -ne 2 ]]; then
      return "$rc"
    fi
    echo "compose test: the $1 cut could not be judged (try $try of 3)"
  done
  return 1
}
cut_test_judged partition "link partition on" "link partition off" --released-late
# The pause by the container's id with the engine's own command: Compose v1 spends about
# a second of CPU before it pauses, and on 2 cores that stalled the wrist poses right
# before the freeze, so the arm had stopped already and the cut could not be judged
# (CI failed three tries so). The engine's freezer can refuse a process busy in the
# file system ("unable to freeze"): the pause is tried again for up to a second.
freeze() { # container-id
  local try
  for try in $(seq 20); do
    docker pause "$1" >/dev/null 2>&1 && return 0
    sleep 0.05
  done
  echo "compose test: docker pause $1 failed 20 times" >&2
  return 1
}
tracker=$(service_id pc1-wrist-tracker)
cut_test_judged pause "freeze $tracker" "docker unpause $tracker"

# WAN conditions (delay, jitter, loss, bandwidth caps) through the link emulator, the
# task once per condition: latencies, rates and the PR2 error, and the checks of the
# robot site's deadlines, order and stop/hold policy (deploy/compose/sweep.sh).
if [[ $SWEEP != none ]]; then
  bash "$HERE/sweep.sh" "$SWEEP"
  echo "compose test: sweep table and plots in $TELEOP_REPORT_DIR/sweep (sweep.md, sweep.png)"
fi

# Each container killed during a clutched motion and started again 2.5 s later: the
# others keep running, its robots stop while it is gone (the hand's controller gone:
# the hand and the arm), it is heard again within 1 s (check_faults.sh, every node
# container and both routers; about 6 minutes). TELEOP_FAULT_SERVICES (space-
# separated) picks others.
if [[ $FAULTS == 1 ]]; then
  # shellcheck disable=SC2086
  bash "$HERE/check_faults.sh" ${TELEOP_FAULT_SERVICES:-}
fi

# Security between the sites: who cannot connect, who cannot command, what the robot
# site refuses from the operator's own identity (check_security.sh).
bash "$HERE/check_security.sh"

teardown
trap - EXIT
left=$(docker ps -aq --filter "label=com.docker.compose.project=$COMPOSE_PROJECT_NAME"
  docker network ls -q --filter "label=com.docker.compose.project=$COMPOSE_PROJECT_NAME"
  docker volume ls -q --filter "label=com.docker.compose.project=$COMPOSE_PROJECT_NAME")
if [[ -n $left ]]; then
  echo "compose test: down left these behind: $left"
  exit 1
fi
echo "compose test: passed (down left no container, network or volume behind)"
