#!/usr/bin/env bash
# A fault campaign over the deploy/robots.sh team (deploy/team.sh: namespaces, keys, config):
# for each team size, a fault-free reference run, then one run per fault: kill -9 and restart of
# the anchor and of a non-anchor robot, SIGSTOP for 20 s, a 30 s network partition (veth down),
# a stale log (another mission's log in --log-dir: refused, then moved aside), an intruder with
# an unlisted key, garbage and oversized frames on every port, a connection flood. Prints one
# JSON table (fault, robots, healed, certified, max difference to the fault-free run in metres,
# wall time) and exits 1 when a fault did not heal to the same certified result within 1e-6 m.
# Without network namespaces the partition is reported as skipped (never as healed).
# Usage: deploy/faults.sh [OUT_DIR]
#   FAULTS_ROBOTS   team sizes (default "2 4")
#   FAULTS_ONLY     run only these faults (names as in the table; default all)
#   FAULTS_KEYFRAMES  keyframes per robot of the simulated mission (default 40; with 30 the
#                     robots see no inter-robot loop)
#   FAULTS_FLOOD    idle connections held per flooded port (default 2000)
#   FAULTS_STOP_S, FAULTS_PARTITION_S  fault lengths (default 20 and 30)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/out/faults}"
tools="$root/deploy/faults_tools.py"
keyframes="${FAULTS_KEYFRAMES:-40}"
stop_s="${FAULTS_STOP_S:-20}"
partition_s="${FAULTS_PARTITION_S:-30}"
flood_per_port="${FAULTS_FLOOD:-2000}"
faults="${FAULTS_ONLY:-kill9_anchor kill9_robot sigstop partition stale_log intruder garbage flood}"
timeout_s=$((120 + stop_s + partition_s))
# shellcheck source=deploy/team.sh
source "$root/deploy/team.sh"
rm -rf "$out"
mkdir -p "$out"
rows="$out/rows.jsonl"
: >"$rows"

# The mission: a short simulated one (deploy/configs/sim2_team.json, fewer keyframes).
python3 - "$root/deploy/configs/sim2_team.json" "$out/mission.json" "$keyframes" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
m["source"]["max_keyframes"] = int(sys.argv[3])
json.dump(m, open(sys.argv[2], "w"), indent=2)
PY

now() { date +%s.%N; }
elapsed() { python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$1" "$(now)"; }

# start_robot K DIR [CONFIG]: robot K of the team, results and durable logs in DIR.
start_robot() {
    team_start "$1" "$2/robot$1.log.$(date +%s%N)" "${3:-$team_json}" --json \
        --timeout "$timeout_s" --out "$2" --log-dir "$2/logs"
    pids[$1]=$team_pid
}

# start_team DIR: every robot; their pids in pids[k].
start_team() {
    local k
    for ((k = 0; k < team_n; k++)); do start_robot "$k" "$1"; done
}

# wait_team: waits for every robot; their exit codes, comma-separated, in codes.
wait_team() {
    local k code list=""
    for ((k = 0; k < team_n; k++)); do
        code=0
        wait "${pids[$k]}" || code=$?
        list+=",$code"
    done
    codes="${list#,}"
}

# ports K: robot K's edges as HOST:PORT.
ports() {
    local p
    for ((p = 1; p <= 7; p++)); do echo "$(team_host "$1"):$(($(team_port "$1") + p))"; done
}

# mid_mission K: returns once robot K has logged half the keyframes it logged in the fault-free
# run (its durable keyframe log at half that size), so a fault lands mid-mission whatever the load.
mid_mission() {
    local log="$dir/logs/robot$1.keyframes.log" half k
    half=$(($(stat -c %s "$reference/logs/robot$1.keyframes.log" 2>/dev/null || echo 0) / 2))
    for ((k = 0; k < 600; k++)); do
        [ "$(stat -c %s "$log" 2>/dev/null || echo 0)" -lt "$half" ] || return 0
        sleep 0.1
    done
    note="failed: robot $1 never reached mid-mission"
    return 1
}

# signal SIG K: sends SIG to robot K; a robot already gone fails the fault (never a silent pass).
signal() {
    kill "-$1" "${pids[$2]}" 2>/dev/null || note="failed: robot $2 had exited before SIG$1"
}

fault_kill9() { # K: kill -9 mid-mission, restarted 1 s later from its durable log
    start_team "$dir"
    mid_mission "$1" || true
    signal KILL "$1"
    wait "${pids[$1]}" 2>/dev/null || true
    sleep 1
    start_robot "$1" "$dir"
    wait_team
}
fault_kill9_anchor() { fault_kill9 0; }
fault_kill9_robot() { fault_kill9 $((team_n - 1)); }

fault_sigstop() { # robot 1 stopped for stop_s, then continued
    start_team "$dir"
    mid_mission 1 || true
    signal STOP 1
    sleep "$stop_s"
    signal CONT 1
    wait_team
}

fault_partition() { # robot 1's link down for partition_s
    if [ "$team_netns" != 1 ]; then
        note="skipped: no network namespaces (not root, no ip netns, or CERTISLAM_NETNS=0)"
        return
    fi
    start_team "$dir"
    mid_mission 1
    team_link 1 down
    sleep "$partition_s"
    team_link 1 up
    wait_team
}

fault_stale_log() { # robot 1 finds another mission's log: refused, then moved aside
    local k=1 other="$dir/other"
    # Another mission: the same team with another simulator seed; robot 1 alone, for 3 s.
    python3 - "$team_json" "$other.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
m["source"]["seed"] += 1
json.dump(m, open(sys.argv[2], "w"), indent=2)
PY
    team_start "$k" "$dir/other.log" "$other.json" --timeout 3 --out "$other" --log-dir "$dir/logs"
    wait "$team_pid" || true
    local stale_size
    stale_size=$(stat -c %s "$dir/logs/robot$k.keyframes.log" 2>/dev/null || echo 0)
    start_robot "$k" "$dir"
    local code=0
    wait "${pids[$k]}" || code=$?
    if [ "$stale_size" = 0 ] || [ "$code" != 1 ] ||
        ! grep -qs "written by another mission" "$dir"/robot$k.log.*; then
        note="failed: the stale log ($stale_size B) was not refused (exit $code)"
    else
        note="stale log of $stale_size B refused (exit 1), then moved aside"
    fi
    python3 - "$team_json" "$dir/move_aside.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
m["log_stale"] = "move_aside"
json.dump(m, open(sys.argv[2], "w"), indent=2)
PY
    local r
    for ((r = 0; r < team_n; r++)); do
        if [ "$r" = "$k" ]; then start_robot "$r" "$dir" "$dir/move_aside.json"; else
            start_robot "$r" "$dir"; fi
    done
    wait_team
    ls "$dir/logs/robot$k.keyframes.log.stale-"* >/dev/null 2>&1 ||
        note="failed: the stale log was not moved aside"
}

fault_intruder() { # a robot 1 with a key not on the allow-list, outside every namespace
    "$team_bin" keygen --force --out "$dir/intruder" >/dev/null
    python3 - "$team_json" "$dir/intruder.json" "$dir/intruder" "$(team_outside_host)" \
        "$(($(team_port "$team_n") + 100))" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
m["network"]["1"].update(host=sys.argv[4], base_port=int(sys.argv[5]),
                         public_key=sys.argv[3] + ".pub", secret_key=sys.argv[3] + ".key")
json.dump(m, open(sys.argv[2], "w"), indent=2)
PY
    start_team "$dir"
    "$team_bin" robot "$dir/intruder.json" --id 1 --timeout "$timeout_s" --out "$dir/intruder" \
        >"$dir/intruder.log" 2>&1 &
    local intruder=$!
    wait_team
    kill "$intruder" 2>/dev/null || true
    wait "$intruder" 2>/dev/null || true
    # The allow-list lets nothing through: the intruder never sees a peer's descriptor.
    local seen
    seen=$(grep -o '[0-9]* inter-robot loop ends' "$dir/intruder.log" | tail -n 1 | cut -d' ' -f1)
    if [ -z "$seen" ]; then
        note="failed: the intruder did not run (see $dir/intruder.log)"
    elif [ "$seen" != 0 ]; then
        note="failed: the intruder matched $seen inter-robot loop ends"
    else
        note="intruder saw no peer message"
    fi
}

fault_garbage() { # malformed greetings, random bytes and 2^62-byte frames on every port
    local targets=() k
    for ((k = 0; k < team_n; k++)); do mapfile -t -O "${#targets[@]}" targets < <(ports "$k"); done
    start_team "$dir"
    mid_mission 0 || true  # the robots have bound their ports
    python3 "$tools" garbage 8 "${targets[@]}" >"$dir/garbage.json" &
    local sender=$!
    wait_team
    wait "$sender" || true
    if grep -q '"garbage_connections": 0[,}]' "$dir/garbage.json" || [ ! -s "$dir/garbage.json" ]; then
        note="failed: no garbage reached a robot ($(cat "$dir/garbage.json"))"
    elif [ -z "$note" ]; then
        note="$(cat "$dir/garbage.json")"
    fi
}

# listen_drops K: connection attempts robot K's kernel dropped from full accept queues so far
# (TcpExt ListenDrops of its namespace; empty on loopback, where the counter is the host's).
listen_drops() {
    [ "$team_netns" = 1 ] || return 0
    ip netns exec "$team_tag-r$1" nstat -asz TcpExtListenDrops | awk '/ListenDrops/ {print $2}'
}

fault_flood() { # idle unauthenticated connections held on the anchor's ports through the mission
    local targets drops
    drops=$(listen_drops 0)
    mapfile -t targets < <(ports 0 | head -n 2)
    python3 "$tools" flood "$timeout_s" "$flood_per_port" "${targets[@]}" >"$dir/flood.json" &
    local flooder=$! code=0
    sleep 2
    start_team "$dir"
    wait_team
    kill -TERM "$flooder" 2>/dev/null || true
    wait "$flooder" || code=$?
    if [ "$code" != 0 ] || [ ! -s "$dir/flood.json" ] ||
        grep -q '"flood_opened": 0[,}]' "$dir/flood.json"; then
        note="failed: the flood did not run (exit $code)"
    else
        note="$(cat "$dir/flood.json")"
        [ -z "$drops" ] || note+=" listen_drops $(($(listen_drops 0) - drops))"
    fi
}

# run_case NAME: one run (reference or fault) of the team in $out/n<N>/NAME.
run_case() {
    dir="$out/n$team_n/$1"
    note=""
    codes=""
    mkdir -p "$dir/logs"
    local start wall
    start=$(now)
    "fault_$1"
    wall=$(elapsed "$start")
    python3 "$tools" row "$1" "$team_n" "$dir" "$reference" "$wall" "$codes" "$note" >>"$rows"
    tail -n 1 "$rows"
    # Not healed: each robot's last status lines and report, so CI's output says where it stuck.
    if ! tail -n 1 "$rows" | grep -q '"healed": true'; then
        local f
        for f in "$dir"/robot*.log.*; do
            [ -s "$f" ] && { echo "--- $f"; grep -a "robots certified" "$f" | tail -n 2; }
        done >&2
        for f in "$dir"/robot*.report.json; do
            [ -s "$f" ] && python3 -c 'import json, sys
r = json.load(open(sys.argv[1])); r.pop("mesh", None)
print("---", sys.argv[1], json.dumps(r))' "$f"
        done >&2
    fi
}

fault_reference() { start_team "$dir"; wait_team; }

# On exit (also when interrupted): no robot of the campaign left running, no namespace left.
cleanup() {
    local p
    for p in $(jobs -p); do kill -9 "$p" 2>/dev/null || true; done  # this shell's own children
    team_net_down
}
pids=()
for n in ${FAULTS_ROBOTS:-2 4}; do
    team_init "$n"
    trap cleanup EXIT
    team_net_up
    team_keys "$out/n$n/keys"
    team_json="$out/n$n/team.json"
    team_config "$out/mission.json" "$out/n$n/keys" "$team_json"
    reference="$out/n$n/reference"
    run_case reference
    if ! tail -n 1 "$rows" | grep -q '"healed": true'; then
        echo "faults: the fault-free run of $n robots did not certify (see $reference)" >&2
    else
        for fault in $faults; do run_case "$fault"; done
    fi
    team_net_down
done
python3 "$tools" table "$rows"
