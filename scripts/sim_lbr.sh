#!/usr/bin/env bash
# Simulated KUKA LBR end to end, without launch files: start the SPG (spg_node) and the
# MuJoCo bridge (sim_bridge, FRI joint impedance) as separate processes over loopback DDS,
# publish task stacks (task_publisher), run for a span of simulated time, stop everything
# this script started, and print the nodes' summaries. Exit 0 only if both nodes ran to
# the end. Copy it into your CI.
#
#   scripts/sim_lbr.sh [-m lockstep|realtime] [-d SECONDS] [-s SCENE] [-r ROBOT] [-o DIR]
#                      [STACK_FILE[@SECONDS] ...]
#
#   -m  bridge mode: lockstep (deterministic, waits for every command; default) or realtime
#   -d  simulated duration in [s] (default 5)
#   -s  scene: free (default), table, obstacle, drawer_horizontal, ...
#   -r  robot: lbr_iiwa14 (default) or lbr4; the SPG reads config/<robot>.yaml
#   -o  directory for the logs (default: a new temporary directory)
# Stack files are validated first (task_publisher --robot); FILE@T publishes FILE T seconds
# (wall clock) after the first. Environment: CYCLONEDDS_URI (default: the loopback config in
# config/), ROS_DOMAIN_ID (default: random in 1..101).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

mode=lockstep duration=5 scene=free robot=lbr_iiwa14 out=''
while getopts 'm:d:s:r:o:h' opt; do
  case "$opt" in
    m) mode="$OPTARG" ;;
    d) duration="$OPTARG" ;;
    s) scene="$OPTARG" ;;
    r) robot="$OPTARG" ;;
    o) out="$OPTARG" ;;
    h) sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option; see -h" ;;
  esac
done
shift $((OPTIND - 1))
stacks=("$@")
[[ "$mode" == lockstep || "$mode" == realtime ]] || die "-m must be lockstep or realtime, got '$mode'"
[[ "$duration" =~ ^[0-9]+([.][0-9]+)?$ ]] || die "-d must be a number of seconds, got '$duration'"
[[ "$robot" == lbr_iiwa14 || "$robot" == lbr4 ]] || die "-r must be lbr_iiwa14 or lbr4, got '$robot'"
params="$IFC_SPG_ROOT/config/$robot.yaml"
[[ -f "$params" ]] || die "no parameter file $params"

setup_env sim_bridge spg_node task_publisher
out="${out:-$(mktemp -d "${TMPDIR:-/tmp}/sim_lbr.XXXXXX")}"
mkdir -p "$out"
trap stop_started EXIT
trap 'exit 130' INT TERM
say "logs in $out (ROS_DOMAIN_ID=$ROS_DOMAIN_ID)"

start "$out/spg_node.log" spg_node --ros-args --params-file "$params"
spg_pid="$STARTED_PID"
wait_for_line "$out/spg_node.log" 'waiting for joint_states' 60 "$spg_pid"

if (( ${#stacks[@]} )); then
  start "$out/task_publisher.log" task_publisher --robot "$robot" "${stacks[@]}"
  wait_for_line "$out/spg_node.log" 'task stack .* accepted' 60 "$STARTED_PID"
fi

printf -v duration_s '%.6f' "$duration"   # a ROS double parameter needs the decimal point
printf -v whole_s '%.0f' "$duration"
if [[ "$mode" == realtime ]]; then limit=$(( whole_s + 60 )); else limit=$(( 60 + 20 * whole_s )); fi
start "$out/sim_bridge.log" sim_bridge --ros-args -p "robot:=$robot" -p "scene:=$scene" \
  -p "mode:=$mode" -p "duration:=$duration_s"
bridge_pid="$STARTED_PID"
deadline=$(( $(date +%s) + limit ))
while kill -0 "$bridge_pid" 2>/dev/null; do
  if (( $(date +%s) > deadline )); then
    die "sim_bridge did not finish $duration s of simulated time within $limit s (see $out)"
  fi
  kill -0 "$spg_pid" 2>/dev/null || die "spg_node exited during the run (see $out/spg_node.log)"
  sleep 0.2
done
rc=0
wait "$bridge_pid" || rc=$?
(( rc == 0 )) || { tail -n 20 "$out/sim_bridge.log" >&2; die "sim_bridge failed with exit code $rc"; }
kill -0 "$spg_pid" 2>/dev/null || die "spg_node exited during the run (see $out/spg_node.log)"
stop_started
grep -hE 'spg_node: [0-9]+ ticks|realtime pacing' "$out/spg_node.log" "$out/sim_bridge.log" || true
echo "logs: $out"
