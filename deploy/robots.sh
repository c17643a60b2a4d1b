#!/usr/bin/env bash
# Starts N robots of a team configuration as separate `certislam robot` processes (pose-graph
# sources: `certislam-robot`, the lean back-end-only executable beside it), each in its
# own network namespace joined by veth pairs on a bridge (a free 10.77.X.0/24, or
# CERTISLAM_SUBNET=A.B.C), talking tcp with CURVE keys made by `certislam keygen`; falls back to
# plain loopback where namespaces are not allowed (not root, no `ip netns`) or when
# CERTISLAM_NETNS=0. Waits for all and reports their exit codes.
# Usage: deploy/robots.sh N CONFIG [OUT_DIR]
#   CONFIG: a team configuration (source, solver, matcher); its "robots" (0..N-1) and
#   "network" parts are written here. Results: OUT_DIR/robot<k>.tum, OUT_DIR/robot<k>.log,
#   OUT_DIR/robot<k>.report.json (each robot's own), OUT_DIR/report.json (the team's, merged),
#   OUT_DIR/team.json (the configuration the robots ran).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
n="${1:?usage: deploy/robots.sh N CONFIG [OUT_DIR]}"
config="${2:?usage: deploy/robots.sh N CONFIG [OUT_DIR]}"
out="${3:-$root/out/robots}"
timeout_s="${CERTISLAM_TIMEOUT:-300}"
# shellcheck source=deploy/team.sh
source "$root/deploy/team.sh"
team_init "$n" || exit 1
mkdir -p "$out/keys"
trap team_net_down EXIT
team_net_up
team_keys "$out/keys"
team_config "$config" "$out/keys" "$out/team.json"

pids=()
for ((k = 0; k < n; k++)); do
    team_start "$k" "$out/robot$k.log" "$out/team.json" --json --timeout "$timeout_s" --out "$out"
    pids+=("$team_pid")
done
status=0
for ((k = 0; k < n; k++)); do
    code=0
    wait "${pids[$k]}" || code=$?
    case "$code" in
        0) echo "robot $k: certified ($out/robot$k.report.json)" ;;
        3) echo "robot $k: finished, not certified (see $out/robot$k.log)" ;;
        *) echo "robot $k: exit $code (see $out/robot$k.log)" ;;
    esac
    if [ "$code" != 0 ] && { [ "$status" = 0 ] || [ "$code" != 3 ]; }; then status=$code; fi
done
team_report "$out"
exit "$status"
