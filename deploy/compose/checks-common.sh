# Sourced by the compose check scripts (check_security.sh, check_faults.sh, sweep.sh)
# and by test.sh, after they set HERE: checks the environment test.sh exports, and
# defines IMAGE, `compose`, `listen` and `link`.
: "${COMPOSE_PROJECT_NAME:?}" "${TELEOP_CERTS:?}" "${TELEOP_REPORT_DIR:?}"
IMAGE=${TELEOP_IMAGE:-teleop:local}
if docker compose version >/dev/null 2>&1; then COMPOSE=(docker compose); else COMPOSE=(docker-compose); fi
compose() { "${COMPOSE[@]}" -f "$HERE/docker-compose.yml" "$@"; }
# A service's running container, found by compose's labels with the docker client:
# docker-compose v1 (Python) takes about a second of CPU to start, and on a 2-core
# machine that stall, right before a timed cut, stopped the arm before the cut came.
service_id() { docker ps -q --filter "label=com.docker.compose.project=$COMPOSE_PROJECT_NAME" \
  --filter "label=com.docker.compose.service=$1" | head -1; }
# The WAN link emulator's control port (wan_link ctl): set, partition, reset, show.
link() { docker exec -i "$(service_id wan-link)" wan_link ctl --control 127.0.0.1:7500 "$@"; }

# A listener on a site LAN as the observer identity: `teleop topic echo` of each topic
# given, as JSON lines, into $OUT/<tag>-<topic-dir>-<topic-name>.jsonl (OUT set by
# the caller), for $3 seconds.
listen() { # site tag seconds topic...
  local site=$1 tag=$2 secs=$3
  shift 3
  local net router
  if [[ $site == local ]]; then net=local_lan router=172.30.1.2; else net=remote_lan router=172.30.2.2; fi
  local cmds=""
  for t in "$@"; do
    cmds+="teleop \$Z topic echo $t --format json --duration-s $secs >/out/$tag-$(basename "$(dirname "$t")")-$(basename "$t").jsonl 2>/dev/null & "
  done
  docker run -d --rm --label "com.docker.compose.project=$COMPOSE_PROJECT_NAME" \
    --network "${COMPOSE_PROJECT_NAME}_$net" -v "$OUT:/out" -v "$TELEOP_CERTS:/certs:ro" "$IMAGE" \
    sh -c "set -f; Z='--mode client --connect tls/$router:7447 --no-multicast-scouting --tls-ca /certs/ca.pem --tls-cert /certs/teleop-observer.pem --tls-key /certs/teleop-observer.key --hardware-interface *'; $cmds wait"
}

