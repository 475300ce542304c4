# Shared helpers for the launch-free scripts (sourced, not run): the environment (the repo's
# .venv on PATH, loopback Cyclone DDS, a ROS domain) and start/stop of background processes
# by PID. Every script that starts processes calls `stop_started` from its EXIT trap, which
# stops exactly the PIDs it started (TERM, then KILL after a grace period) and nothing else.

IFC_SPG_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
STARTED_PIDS=()

die() { echo "$(basename "$0"): $*" >&2; exit 1; }
say() { echo "$(basename "$0"): $*" >&2; }

# setup_env: the .venv's console scripts first on PATH; loopback DDS unless the caller set
# CYCLONEDDS_URI (built-in backend) or ROS_AUTOMATIC_DISCOVERY_RANGE and
# FASTDDS_DEFAULT_PROFILES_FILE (rclpy / Fast DDS: config/fastdds_loopback.xml); a
# random ROS_DOMAIN_ID in [1, 101] unless set (so parallel runs on one machine do not talk to
# each other). The backend is rclpy where it imports, else the built-in one
# (IFC_SPG_ROS_BACKEND=cyclonedds forces it).
setup_env() {
  if [[ -d "$IFC_SPG_ROOT/.venv/bin" ]]; then
    export PATH="$IFC_SPG_ROOT/.venv/bin:$PATH"
  fi
  export CYCLONEDDS_URI="${CYCLONEDDS_URI:-file://$IFC_SPG_ROOT/config/cyclonedds_loopback.xml}"
  export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
  # Fast DDS: ports on 127.0.0.1, announcements every second (the file says what it does)
  export FASTDDS_DEFAULT_PROFILES_FILE="${FASTDDS_DEFAULT_PROFILES_FILE:-$IFC_SPG_ROOT/config/fastdds_loopback.xml}"
  export FASTRTPS_DEFAULT_PROFILES_FILE="${FASTRTPS_DEFAULT_PROFILES_FILE:-$FASTDDS_DEFAULT_PROFILES_FILE}"
  export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( RANDOM % 101 + 1 ))}"
  local exe
  for exe in "$@"; do
    command -v "$exe" >/dev/null 2>&1 \
      || die "'$exe' not found on PATH; run ./run setup (or pip install -e .) first"
  done
}

# start LOGFILE CMD...: run CMD in the background with output to LOGFILE; sets STARTED_PID.
start() {
  local log="$1"
  shift
  "$@" >"$log" 2>&1 &
  STARTED_PID="$!"
  STARTED_PIDS+=("$STARTED_PID")
  say "started $1 (PID $STARTED_PID), log $log"
}

# stop PID: TERM, wait up to 5 s, then KILL; only for PIDs this script started.
stop() {
  local pid="$1" i
  kill -0 "$pid" 2>/dev/null || { wait "$pid" 2>/dev/null || true; return 0; }
  kill -TERM "$pid" 2>/dev/null || true
  for i in $(seq 50); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  if kill -0 "$pid" 2>/dev/null; then
    say "PID $pid did not stop on TERM; killing it"
    kill -KILL "$pid" 2>/dev/null || true
  fi
  wait "$pid" 2>/dev/null || true
}

# stop_started: stop every process this script started, newest first.
stop_started() {
  local i
  for (( i=${#STARTED_PIDS[@]}-1; i>=0; i-- )); do
    stop "${STARTED_PIDS[$i]}"
    say "stopped PID ${STARTED_PIDS[$i]}"
  done
  STARTED_PIDS=()
}

# wait_for_line FILE PATTERN TIMEOUT PID: wait until FILE contains PATTERN (grep -E); fail
# if PID exits first or TIMEOUT [s] passes.
wait_for_line() {
  local file="$1" pattern="$2" timeout="$3" pid="$4" deadline
  deadline=$(( $(date +%s) + timeout ))
  until grep -qE "$pattern" "$file" 2>/dev/null; do
    kill -0 "$pid" 2>/dev/null || { cat "$file" >&2; die "process $pid exited early"; }
    (( $(date +%s) < deadline )) || { cat "$file" >&2; die "timed out waiting for '$pattern'"; }
    sleep 0.1
  done
}
