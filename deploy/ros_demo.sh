#!/usr/bin/env bash
# Two robots live over ROS 1: a real roscore, LIO-SAM-style bags of the built-in simulator's
# mission played with `rosbag play --clock`, one `certislam_node` per robot (tcp + CURVE between
# them), and a subscriber recording their paths and status. Prints one JSON line (per robot: path
# length received, ATE against the simulator's truth, last verdict, dropped keyframes; wall time)
# and exits 0 when both robots' paths arrived and their last verdict is certified.
# Usage: deploy/ros_demo.sh [OUT_DIR]
#   env: BUILD_DIR (build), RATE (rosbag play rate, 2), KEYFRAMES (per robot, 150),
#        TIMEOUT (recorder's limit, seconds, 240), COMPARE (1: also `certislam run` the same
#        team on the same bags and report the largest position difference of the paths; 0: skip),
#        SCREENSHOT (a .png path: also run rviz with deploy/ros/certislam.rviz on a virtual X
#        display (Xvfb) and save its window at the end of the bags; needs xvfb, rviz, x11-apps,
#        netpbm)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BUILD_DIR:-$root/build}"
out="${1:-$root/out/ros_demo}"
rate="${RATE:-2}"
keyframes="${KEYFRAMES:-150}"
timeout_s="${TIMEOUT:-240}"
start_s=$(date +%s.%N)

# ROS 1 from Debian, installed when missing.
ros_packages=(ros-core-dev libroscpp-dev libtf2-ros-dev libnav-msgs-dev libsensor-msgs-dev
              libvisualization-msgs-dev python3-rosmaster python3-rostopic python3-rosbag
              python3-rospy librosbag-dev)
missing=()
for p in "${ros_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "ros_demo: installing ${missing[*]}" >&2
    sudo=""; [ "$(id -u)" -ne 0 ] && sudo=sudo
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

node="$build/bin/ros/certislam_node"
bags="$build/bin/ros/certislam_ros_bags"
certislam="$build/bin/certislam"
for b in "$node" "$bags" "$certislam"; do
    [ -x "$b" ] || { echo "ros_demo: no $b (cmake --build $build --target certislam_node" \
                          "certislam_ros_bags certislam)" >&2; exit 1; }
done

rm -rf "$out" && mkdir -p "$out/keys"
# Ports of this run (several runs may share the machine): the master and the team's edges.
master_port=$((12000 + $$ % 2000))
base0=$((20000 + ($$ % 300) * 20))
for k in 0 1; do "$certislam" keygen --out "$out/keys/robot$k" >/dev/null; done
cat >"$out/team.json" <<JSON
{
  "robots": [0, 1],
  "source": {"kind": "simulator", "seed": 1, "max_keyframes": $keyframes},
  "solver": {"rank": 5, "rel_grad_tol": 1e-9},
  "matcher": {"query_stride": 3, "max_sc_distance": 0.2},
  "mapping": {"voxel_m": 0.4, "team_map": "anchor"},
  "network": {
    "0": {"host": "127.0.0.1", "base_port": $base0,
          "public_key": "keys/robot0.pub", "secret_key": "keys/robot0.key"},
    "1": {"host": "127.0.0.1", "base_port": $((base0 + 10)),
          "public_key": "keys/robot1.pub", "secret_key": "keys/robot1.key"}
  },
  "ros": {
    "cloud_topic": "/robot{robot}/lio_sam/mapping/cloud_registered_raw",
    "odometry_topic": "/robot{robot}/lio_sam/mapping/odometry",
    "select_keyframes": false,
    "end_after_silence_s": 10.0,
    "mesh_period_s": 5.0
  }
}
JSON
"$bags" "$out/team.json" --out "$out" >"$out/bags.json"

pids=()
cleanup() {
    for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill "${pids[$i]}" 2>/dev/null || true; done
    for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

export ROS_MASTER_URI="http://127.0.0.1:$master_port" ROS_HOSTNAME=127.0.0.1
export ROS_LOG_DIR="$out/ros_log"
roscore -p "$master_port" >"$out/roscore.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do rosparam list >/dev/null 2>&1 && break; sleep 0.2; done
rosparam set /use_sim_time true

for k in 0 1; do
    "$node" "$out/team.json" --id "$k" --out "$out" >"$out/node$k.json" 2>"$out/node$k.log" &
    pids+=($!)
done
if [ -n "${SCREENSHOT:-}" ]; then
    display=":$((90 + $$ % 100))"
    Xvfb "$display" -screen 0 1400x900x24 >"$out/xvfb.log" 2>&1 &
    pids+=($!)
    sleep 1
    DISPLAY="$display" rviz -d "$root/deploy/ros/certislam.rviz" >"$out/rviz.log" 2>&1 &
    pids+=($!)
fi
/usr/bin/python3 "$root/deploy/ros/record.py" --robots 0 1 --truth "$out" \
    --ready "$out/recorder.ready" --timeout "$timeout_s" >"$out/record.json" 2>"$out/record.log" &
recorder=$!
pids+=("$recorder")
for _ in $(seq 100); do [ -e "$out/recorder.ready" ] && break; sleep 0.2; done
sleep 2  # the nodes' and recorder's subscriptions connect
rosbag play --clock -q -r "$rate" "$out/robot0.bag" "$out/robot1.bag" >"$out/play.log" 2>&1
if [ -n "${SCREENSHOT:-}" ]; then
    sleep 8  # the last paths and a mesh period reach rviz
    xwd -root -display "$display" | xwdtopnm 2>/dev/null | pnmtopng >"$SCREENSHOT"
fi
status=0
wait "$recorder" || status=$?
cleanup
pids=()
end_s=$(date +%s.%N)
# The same team in one process on the same keyframes (`certislam run` reading the two bags the
# nodes were played), to compare with.
if [ "${COMPARE:-1}" != 0 ]; then
    /usr/bin/python3 - "$out" <<'PY'
import json, sys
out = sys.argv[1]
team = json.load(open(f"{out}/team.json"))
ros = team.pop("ros")
team.pop("network")
team["source"] = {"kind": "rosbag", "paths": {k: f"robot{k}.bag" for k in ("0", "1")},
                  "cloud_topic": ros["cloud_topic"], "odometry_topic": ros["odometry_topic"]}
json.dump(team, open(f"{out}/run_team.json", "w"), indent=2)
PY
    "$certislam" run "$out/run_team.json" --out "$out/run" --json --progress 0 \
        >"$out/run.json" 2>"$out/run.log" || true
fi
/usr/bin/python3 - "$out" "$start_s" "$end_s" "$rate" <<'PY'
import json, math, os, sys
out, start, end, rate = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])

def tum(path):
    with open(path) as f:
        return [[float(x) for x in l.split()] for l in f if l.strip() and not l.startswith("#")]

def compare(rec):
    # Largest position difference between each node's last path and `certislam run`'s.
    if not os.path.exists(f"{out}/run.json"):
        return None
    try:
        run = json.load(open(f"{out}/run.json"))
    except ValueError:
        return {"error": f"certislam run failed; see {out}/run.log"}
    res = {"inter_robot_loops_run": run.get("inter_robot_loops"), "verdict_run": run.get("verdict")}
    for k in ("0", "1"):
        a, b = f"{out}/robot{k}.tum", f"{out}/run/robot{k}.tum"
        if os.path.exists(a) and os.path.exists(b):
            # Poses matched by stamp; poses only one side holds are counted, not hidden.
            pa = {round(p[0], 6): p[1:4] for p in tum(a)}
            pb = {round(p[0], 6): p[1:4] for p in tum(b)}
            common = pa.keys() & pb.keys()
            res[f"robot{k}_max_diff_m"] = max((math.dist(pa[t], pb[t]) for t in common),
                                              default=None)
            res[f"robot{k}_poses_matched"] = len(common)
            res[f"robot{k}_poses_unmatched"] = len(pa.keys() ^ pb.keys())
    return res
try:
    rec = json.load(open(f"{out}/record.json"))
except Exception as e:
    rec = {"ok": False, "error": f"no recorder output ({e}); see {out}/record.log"}
rec["rate"] = rate
rec["wall_time_s"] = round(end - start, 2)
rec["bags"] = json.load(open(f"{out}/bags.json"))
for k, robot in rec.get("robots", {}).items():
    # Keyframes the bag played that the node never took in (ROS queues or ingest drops).
    played = rec["bags"].get(k, {}).get("keyframes")
    got = (robot.get("keyframes") or {}).get("selected")
    if played is not None and got is not None:
        robot["keyframes_lost"] = played - got
rec["vs_certislam_run"] = compare(rec)
print(json.dumps(rec))
PY
exit "$status"
