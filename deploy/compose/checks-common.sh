# Sourced by the compose check scripts (check_security.sh, check_faults.sh) after they
# set HERE: checks the environment test.sh exports, and defines IMAGE and `compose`.
: "${COMPOSE_PROJECT_NAME:?}" "${TELEOP_CERTS:?}" "${TELEOP_REPORT_DIR:?}"
IMAGE=${TELEOP_IMAGE:-teleop:local}
if docker compose version >/dev/null 2>&1; then COMPOSE=(docker compose); else COMPOSE=(docker-compose); fi
compose() { "${COMPOSE[@]}" -f "$HERE/docker-compose.yml" "$@"; }
