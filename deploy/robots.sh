#!/usr/bin/env bash
# Starts N robots of a team configuration as separate `certislam robot` processes, each in its
# own network namespace joined by veth pairs on a bridge (10.77.0.0/24), talking tcp with CURVE
# keys made by `certislam keygen`; falls back to plain loopback where namespaces are not allowed
# (not root, no `ip netns`) or when CERTISLAM_NETNS=0. Waits for all and reports their exit codes.
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
bin="${CERTISLAM:-${BUILD_DIR:-$root/build}/bin/certislam}"
# Below Linux's ephemeral range (32768-60999): a client retrying a port that is not bound yet
# could otherwise be handed that port as its own source (TCP self-connection) and take it.
base_port="${CERTISLAM_BASE_PORT:-27000}"
timeout_s="${CERTISLAM_TIMEOUT:-300}"
[ -x "$bin" ] || { echo "robots.sh: no certislam binary at $bin (build first)" >&2; exit 1; }
mkdir -p "$out/keys"

use_netns=0
if [ "${CERTISLAM_NETNS:-1}" != 0 ] && [ "$(id -u)" = 0 ] && command -v ip >/dev/null &&
    ip netns add "cs-probe-$$" 2>/dev/null; then
    ip netns del "cs-probe-$$"
    use_netns=1
fi
tag="cs$$"
cleanup() {
    if [ "$use_netns" = 1 ]; then
        for ((k = 0; k < n; k++)); do ip netns del "$tag-r$k" 2>/dev/null || true; done
        ip link del "${tag}br" 2>/dev/null || true
    fi
}
trap cleanup EXIT

host_of() { if [ "$use_netns" = 1 ]; then echo "10.77.0.$((10 + $1))"; else echo 127.0.0.1; fi; }

if [ "$use_netns" = 1 ]; then
    ip link add "${tag}br" type bridge
    ip addr add 10.77.0.1/24 dev "${tag}br"
    ip link set "${tag}br" up
    for ((k = 0; k < n; k++)); do
        ns="$tag-r$k"
        ip netns add "$ns"
        ip link add "${tag}v$k" type veth peer name eth0 netns "$ns"
        ip link set "${tag}v$k" master "${tag}br" up
        ip -n "$ns" addr add "$(host_of "$k")/24" dev eth0
        ip -n "$ns" link set eth0 up
        ip -n "$ns" link set lo up
    done
    echo "robots.sh: $n robots in network namespaces $tag-r0.. on bridge ${tag}br"
else
    echo "robots.sh: $n robots on loopback (network namespaces not available)"
fi

# The team configuration with its network part: addresses and key files.
network=""
for ((k = 0; k < n; k++)); do
    "$bin" keygen --force --out "$out/keys/robot$k" >/dev/null
    network+="$([ "$k" -gt 0 ] && echo ,)\"$k\": {\"host\": \"$(host_of "$k")\", "
    network+="\"base_port\": $((base_port + 10 * k)), "
    network+="\"public_key\": \"$out/keys/robot$k.pub\", \"secret_key\": \"$out/keys/robot$k.key\"}"
done
python3 - "$config" "$out/team.json" "{$network}" <<'PY'
import json, sys
team = json.load(open(sys.argv[1]))
team["network"] = json.loads(sys.argv[3])
team["robots"] = list(range(len(team["network"])))  # N robots, whatever CONFIG listed
json.dump(team, open(sys.argv[2], "w"), indent=2)
PY

pids=()
for ((k = 0; k < n; k++)); do
    run=("$bin" robot "$out/team.json" --id "$k" --json --timeout "$timeout_s" --out "$out")
    if [ "$use_netns" = 1 ]; then run=(ip netns exec "$tag-r$k" "${run[@]}"); fi
    "${run[@]}" >"$out/robot$k.log" 2>&1 &
    pids+=($!)
done
status=0
for ((k = 0; k < n; k++)); do
    code=0
    wait "${pids[$k]}" || code=$?
    case "$code" in
        0) echo "robot $k: certified ($out/robot$k.tum)" ;;
        3) echo "robot $k: finished, not certified (see $out/robot$k.log)" ;;
        *) echo "robot $k: exit $code (see $out/robot$k.log)" ;;
    esac
    if [ "$code" != 0 ] && { [ "$status" = 0 ] || [ "$code" != 3 ]; }; then status=$code; fi
done
# The team report: every robot's own report, and what holds for the team.
python3 - "$out" "$n" <<'PY'
import json, os, sys
out, n = sys.argv[1], int(sys.argv[2])
reports = []
for k in range(n):
    path = os.path.join(out, f"robot{k}.report.json")
    if os.path.exists(path):
        reports.append(json.load(open(path)))
verdicts = sorted({r.get("verdict", "none") for r in reports})
team = {
    "schema_version": 1,
    "robots": [robot for r in reports for robot in r.get("robots", [])],
    "reports": len(reports),
    "certified": len(reports) == n and all(r.get("certified") for r in reports),
    "verdict": verdicts[0] if len(verdicts) == 1 and len(reports) == n else "inconclusive",
    # The anchor's certificate (every robot reports the one the anchor sent): objective, and the
    # bound only when it was proven (null otherwise).
    "objective": reports[0].get("objective") if reports else None,
    "lower_bound": reports[0].get("lower_bound") if reports else None,
    "relative_suboptimality_bound":
        reports[0].get("relative_suboptimality_bound") if reports else None,
    "bytes_sent": sum(r.get("bytes_sent", 0) for r in reports),
    "seconds": max((r.get("seconds", 0.0) for r in reports), default=0.0),
}
json.dump(team, open(os.path.join(out, "report.json"), "w"), indent=2)
print(f"robots.sh: team report {os.path.join(out, 'report.json')}: {team['verdict']}")
PY
exit "$status"
