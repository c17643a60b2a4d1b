#!/usr/bin/python3
"""Subscriber of deploy/ros_demo.sh: records each robot's published path and status until every
robot's status says done (certified, keyframes ended, quiet) or the timeout; prints one JSON object:
per robot the last path's length, its ATE (RMSE of positions, map frame, no alignment) against the
truth TUM file, the last verdict, dropped keyframes, and the delays from the first status counting
an inter-robot loop to the first path published after it and to the first path that loop moved
(a pose both paths hold changed by over 1 mm: the corrected path).

Usage: record.py --robots 0 1 --truth DIR --timeout S [--ready FILE]
"""
import argparse
import json
import math
import sys
import threading
import time

import rospy
from nav_msgs.msg import Path
from std_msgs.msg import String


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                v = [float(x) for x in line.split()]
                rows.append((v[0], v[1:4]))
    return rows


def ate(path_msg, truth):
    """RMSE of positions at matching stamps (within 1 ms); (rmse, matched)."""
    by_stamp = {round(t, 3): p for t, p in truth}
    se, n = 0.0, 0
    for ps in path_msg.poses:
        t = round(ps.header.stamp.to_sec(), 3)
        if t not in by_stamp:
            continue
        q = ps.pose.position
        p = by_stamp[t]
        se += (q.x - p[0]) ** 2 + (q.y - p[1]) ** 2 + (q.z - p[2]) ** 2
        n += 1
    return (math.sqrt(se / n) if n else None), n


def moved(before, after):
    """Largest position change of the poses both paths hold (same index), in metres."""
    if before is None:
        return math.inf
    change = 0.0
    for a, b in zip(before.poses, after.poses):
        p, q = a.pose.position, b.pose.position
        change = max(change, math.dist((p.x, p.y, p.z), (q.x, q.y, q.z)))
    return change


class Robot:
    def __init__(self, k):
        self.k = k
        self.path = None
        self.paths = 0
        self.status = None
        self.first_loop_wall = None
        self.first_path_after_loop_wall = None
        self.path_before_loop = None  # the last path published before the first loop
        self.first_corrected_wall = None  # first path after it that the loop moved (> 1 mm)
        self.lock = threading.Lock()

    def on_path(self, msg):
        with self.lock:
            self.path = msg
            self.paths += 1
            if self.first_loop_wall is None:
                self.path_before_loop = msg
                return
            now = time.monotonic()
            if self.first_path_after_loop_wall is None:
                self.first_path_after_loop_wall = now
            if self.first_corrected_wall is None and moved(self.path_before_loop, msg) > 1e-3:
                self.first_corrected_wall = now

    def on_status(self, msg):
        s = json.loads(msg.data)
        with self.lock:
            self.status = s
            if s.get("inter_robot_loops", 0) > 0 and self.first_loop_wall is None:
                self.first_loop_wall = time.monotonic()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", type=int, nargs="+", required=True)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--ready", help="touch this file once subscribed")
    args = ap.parse_args(rospy.myargv()[1:])
    rospy.init_node("certislam_demo_recorder", disable_signals=True)
    robots = {k: Robot(k) for k in args.robots}
    for k, r in robots.items():
        rospy.Subscriber(f"/certislam/robot{k}/path", Path, r.on_path, queue_size=10)
        rospy.Subscriber(f"/certislam/robot{k}/status", String, r.on_status, queue_size=100)
    if args.ready:
        open(args.ready, "w").close()
    start = time.monotonic()
    done = False
    while time.monotonic() - start < args.timeout and not rospy.is_shutdown():
        time.sleep(0.2)
        with_all = all(r.status and r.status.get("done") and r.path for r in robots.values())
        if with_all:
            done = True
            break
    time.sleep(1.0)  # the last path of a late step
    out = {"done": done, "robots": {}}
    ok = done
    for k, r in robots.items():
        with r.lock:
            entry = {"paths_received": r.paths,
                     "path_length": len(r.path.poses) if r.path else 0,
                     "verdict": r.status.get("verdict") if r.status else None,
                     "lambda_min": r.status.get("lambda_min") if r.status else None,
                     "inter_robot_loops": r.status.get("inter_robot_loops") if r.status else None,
                     "anchor": r.status.get("anchor") if r.status else None,
                     "keyframes": r.status.get("keyframes") if r.status else None}
            if r.path:
                rmse, n = ate(r.path, read_tum(f"{args.truth}/robot{k}.truth.tum"))
                entry["ate_rmse_m"] = rmse
                entry["ate_matched"] = n
            if r.first_loop_wall is not None and r.first_path_after_loop_wall is not None:
                entry["first_path_after_loop_s"] = r.first_path_after_loop_wall - r.first_loop_wall
            if r.first_loop_wall is not None and r.first_corrected_wall is not None:
                entry["first_corrected_path_after_loop_s"] = r.first_corrected_wall - r.first_loop_wall
        out["robots"][str(k)] = entry
        # A team, not two lone robots: each node must have accepted an inter-robot loop.
        ok = (ok and entry["path_length"] > 0 and entry["verdict"] == "certified"
              and (entry["inter_robot_loops"] or 0) > 0)
    out["ok"] = ok
    print(json.dumps(out), flush=True)
    rospy.signal_shutdown("done")
    return 0 if ok else 2


if __name__ == "__main__":
    sys.exit(main())
