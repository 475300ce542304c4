#!/usr/bin/env bash
# Publish task-stack files to a running spg_node and return once it has them: validates
# every file (exit 2 with the field, line and column of the first error), waits for the
# SPG's subscription, publishes (a timed sequence with FILE@SECONDS), waits until the
# subscriber acknowledged the last stack, then exits. The SPG replies on spg/status.
#
#   scripts/publish_stack.sh [-r ROBOT] [-t TIMEOUT] FILE[@SECONDS] ...
#
#   -r  also validate against this robot's model (lbr_iiwa14, lbr4, icub_upper_body, ...)
#   -t  give up after this many seconds without a subscriber (default 30; exit 1)
# Environment: CYCLONEDDS_URI (default: the loopback config in config/), ROS_DOMAIN_ID
# (must match the SPG's; default: random, which only makes sense for a dry run).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

robot_args=() timeout=30
while getopts 'r:t:h' opt; do
  case "$opt" in
    r) robot_args=(--robot "$OPTARG") ;;
    t) timeout="$OPTARG" ;;
    h) sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option; see -h" ;;
  esac
done
shift $((OPTIND - 1))
(( $# )) || die "give at least one task-stack file; see -h"
setup_env task_publisher
[[ -n "${ROS_DOMAIN_ID:-}" ]] || die "ROS_DOMAIN_ID is not set"
exec task_publisher "$@" "${robot_args[@]}" --once --timeout "$timeout"
