#!/usr/bin/env bash
# Validate task-stack files with `ifc-spg check` (the checks the SPG applies to a stack it
# receives): exit 0 if all are valid, 2 (with the file, field, line and column of each
# error) if any is not. No DDS, no processes started.
#
#   scripts/check_stacks.sh [FILE ...]      default: every config/tasks/*.yaml and *.json
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

[[ "${1:-}" == -h ]] && { sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; exit 0; }
setup_env ifc-spg
files=("$@")
if (( ${#files[@]} == 0 )); then
  shopt -s nullglob
  files=("$IFC_SPG_ROOT"/config/tasks/*.yaml "$IFC_SPG_ROOT"/config/tasks/*.json)
  (( ${#files[@]} )) || die "no files given and none in $IFC_SPG_ROOT/config/tasks"
fi
rc=0
ifc-spg check "${files[@]}" || rc=$?
(( rc == 0 )) && say "${#files[@]} file(s) valid"
exit "$rc"
