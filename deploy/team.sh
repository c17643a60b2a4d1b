# shellcheck shell=bash disable=SC2034  # team_* variables are read by the scripts that source this
# Shell functions shared by deploy/robots.sh and deploy/faults.sh (sourced, not run): a team of N
# `certislam robot` processes, each in its own network namespace joined by veth pairs on a bridge
# (a 10.77.X.0/24 no interface of the host uses yet, or CERTISLAM_SUBNET=A.B.C for A.B.C.0/24, so
# two campaigns on one host do not clash), talking tcp with CURVE keys made by `certislam keygen`;
# plain loopback where namespaces are not allowed (not root, no `ip netns`) or when
# CERTISLAM_NETNS=0.
# Call team_init N first, team_net_up after it, and team_net_down on exit (trap).

# team_init N: the team's size, the binary, the base port and whether namespaces are usable.
team_init() {
    team_n="$1"
    team_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    team_bin="${CERTISLAM:-${BUILD_DIR:-$team_root/build}/bin/certislam}"
    # Below Linux's ephemeral range (32768-60999): a client retrying a port that is not bound yet
    # could otherwise be handed that port as its own source (TCP self-connection) and take it.
    team_base_port="${CERTISLAM_BASE_PORT:-27000}"
    [ -x "$team_bin" ] || {
        echo "no certislam binary at $team_bin (build first)" >&2
        return 1
    }
    team_netns=0
    if [ "${CERTISLAM_NETNS:-1}" != 0 ] && [ "$(id -u)" = 0 ] && command -v ip >/dev/null &&
        ip netns add "cs-probe-$$" 2>/dev/null; then
        ip netns del "cs-probe-$$"
        team_netns=1
    fi
    team_tag="cs$$"
    if [ "$team_netns" = 1 ]; then team_pick_subnet || return 1; fi
}

# team_pick_subnet: team_subnet (A.B.C of A.B.C.0/24) from CERTISLAM_SUBNET, else the first
# 10.77.X with no address on the host, X starting from this shell's pid (campaigns started at
# once start apart).
team_pick_subnet() {
    if [ -n "${CERTISLAM_SUBNET:-}" ]; then
        [[ "$CERTISLAM_SUBNET" =~ ^[0-9]{1,3}\.[0-9]{1,3}\.[0-9]{1,3}$ ]] || {
            echo "CERTISLAM_SUBNET=$CERTISLAM_SUBNET: want A.B.C (the team uses A.B.C.0/24)" >&2
            return 1
        }
        team_subnet="$CERTISLAM_SUBNET"
        return 0
    fi
    local used i x
    used="$(ip -o -4 addr show 2>/dev/null)"
    for ((i = 0; i < 250; i++)); do
        x=$((($$ + i) % 250 + 1))
        if ! grep -q " 10\.77\.$x\." <<<"$used"; then
            team_subnet="10.77.$x"
            return 0
        fi
    done
    echo "team: every 10.77.X.0/24 is in use on this host (set CERTISLAM_SUBNET)" >&2
    return 1
}

# team_host K: the address robot K binds and its peers connect to.
team_host() { if [ "$team_netns" = 1 ]; then echo "$team_subnet.$((10 + $1))"; else echo 127.0.0.1; fi; }

# team_outside_host: an address outside every robot (the bridge, or loopback), for intruders.
team_outside_host() { if [ "$team_netns" = 1 ]; then echo "$team_subnet.1"; else echo 127.0.0.1; fi; }

# team_port K: robot K's base port (its edges are on base + 1 .. base + 7).
team_port() { echo $((team_base_port + 10 * $1)); }

# team_net_up: the bridge and one namespace per robot (nothing on loopback).
team_net_up() {
    if [ "$team_netns" != 1 ]; then
        echo "team: $team_n robots on loopback (network namespaces not available)"
        return 0
    fi
    ip link add "${team_tag}br" type bridge
    ip addr add "$team_subnet.1/24" dev "${team_tag}br"
    ip link set "${team_tag}br" up
    local k ns
    for ((k = 0; k < team_n; k++)); do
        ns="$team_tag-r$k"
        ip netns add "$ns"
        ip link add "${team_tag}v$k" type veth peer name eth0 netns "$ns"
        ip link set "${team_tag}v$k" master "${team_tag}br" up
        ip -n "$ns" addr add "$(team_host "$k")/24" dev eth0
        ip -n "$ns" link set eth0 up
        ip -n "$ns" link set lo up
    done
    echo "team: $team_n robots in network namespaces $team_tag-r0.. on bridge ${team_tag}br" \
        "($team_subnet.0/24)"
}

# team_net_down: removes what team_net_up made.
team_net_down() {
    [ "$team_netns" = 1 ] || return 0
    local k
    for ((k = 0; k < team_n; k++)); do
        ip netns del "$team_tag-r$k" 2>/dev/null || true
        ip link del "${team_tag}v$k" 2>/dev/null || true  # outlives the namespace while in use
    done
    ip link del "${team_tag}br" 2>/dev/null || true
}

# team_link K up|down: robot K's link to the bridge (a network partition when down).
team_link() { ip link set "${team_tag}v$1" "$2"; }

# team_keys DIR: a CURVE key pair per robot, DIR/robot<k>.pub and .key.
team_keys() {
    mkdir -p "$1"
    local k
    for ((k = 0; k < team_n; k++)); do
        "$team_bin" keygen --force --out "$1/robot$k" >/dev/null
    done
}

# team_config CONFIG KEY_DIR OUT_JSON: CONFIG with its "robots" (0..N-1) and "network" parts
# (addresses, ports, the keys of team_keys) written as OUT_JSON.
team_config() {
    local network="" k
    for ((k = 0; k < team_n; k++)); do
        [ "$k" = 0 ] || network+=","
        network+="\"$k\": {\"host\": \"$(team_host "$k")\", "
        network+="\"base_port\": $(team_port "$k"), "
        network+="\"public_key\": \"$2/robot$k.pub\", \"secret_key\": \"$2/robot$k.key\"}"
    done
    python3 - "$1" "$3" "{$network}" <<'PY'
import json, sys
team = json.load(open(sys.argv[1]))
team["network"] = json.loads(sys.argv[3])
team["robots"] = list(range(len(team["network"])))  # N robots, whatever CONFIG listed
json.dump(team, open(sys.argv[2], "w"), indent=2)
PY
}

# team_start K LOG CONFIG ARGS...: `certislam robot CONFIG ARGS --id K` in robot K's namespace, in
# the background, output to LOG; its pid in team_pid. A pose-graph team's robots run the lean
# `certislam-robot` beside the binary instead (same options; no PCL or OpenVDB loaded).
team_start() {
    local k="$1" log="$2"
    shift 2
    local run=("$team_bin" robot "$@" --id "$k")
    local lean
    lean="$(dirname "$team_bin")/certislam-robot"
    if [ -x "$lean" ] && python3 -c 'import json, sys
sys.exit(json.load(open(sys.argv[1])).get("source", {}).get("kind") != "pose_graph")' "$1" \
        2>/dev/null; then
        run=("$lean" "$@" --id "$k")
    fi
    if [ "$team_netns" = 1 ]; then run=(ip netns exec "$team_tag-r$k" "${run[@]}"); fi
    "${run[@]}" >"$log" 2>&1 &
    team_pid=$!
}

# team_report OUT: OUT/report.json, the team's report merged from OUT/robot<k>.report.json.
team_report() {
    python3 - "$1" "$team_n" <<'PY'
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
    # A keyframe robot lists its robots; a pose-graph robot (certislam-robot) names itself.
    "robots": [robot for r in reports
               for robot in (r["robots"] if isinstance(r.get("robots"), list)
                             else [r["robot"]] if "robot" in r else [])],
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
print(f"team report {os.path.join(out, 'report.json')}: {team['verdict']}")
PY
}
