#!/usr/bin/env bash
# The robots' own back end on the benchmark graphs: for each file, `certislam solve --robots 1`
# (in process) and then `solve --robots N --distributed --transport T` in the same run, and a
# Markdown table: verdict, cost against the in-process one, team iterations beside dpgo's,
# the team's finish after rounds that did not converge (status, trust-region steps, CG
# iterations), certificate rounds and Lanczos steps, bytes between robots (solver, certifier,
# kbit per team iteration: a round or a CG iteration of the finish), wall time and its ratio to
# --robots 1, the largest robot's peak RSS.
# Usage: deploy/solve_distributed.sh [timeout_s per run (default 600)] [files...]
#   env: CERTISLAM (the binary; default build/bin/certislam), DATA (default ../shared/data/g2o),
#        ROBOTS (default 5), TRANSPORT (inproc, ipc or tcp; default tcp),
#        OVERLAP (the rounds' overlapping depth, solve --overlap; default the solver's),
#        OUT (JSON lines, default out/solve_distributed.jsonl)
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${CERTISLAM:-$root/build/bin/certislam}"
data="${DATA:-$root/../shared/data/g2o}"
timeout_s="${1:-600}"
shift || true
robots="${ROBOTS:-5}"
transport="${TRANSPORT:-tcp}"
out="${OUT:-$root/out/solve_distributed.jsonl}"
overlap=()
if [ -n "${OVERLAP:-}" ]; then overlap=(--overlap "$OVERLAP"); fi
mkdir -p "$(dirname "$out")"
: > "$out"

# file, dpgo's team iterations where published (issue 15: sphere2500 240, torus3D 421)
read -r -d '' table <<'LIST'
smallGrid3D.g2o -
sphere2500.g2o 240
torus3D.g2o 421
parking-garage.g2o -
cubicle.g2o -
city10000.g2o -
intel.g2o -
kitti_00.g2o -
multirobot/tunnels -
LIST

echo "| file | robots | transport | overlap | verdict | cost vs --robots 1 | team iterations | dpgo | finish: status, TR steps / CG | certificate rounds | Lanczos steps | solver MB | certifier MB | kbit / iteration | seconds | wall s | --robots 1 s | ratio (wall) | peak RSS / robot MB |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
while read -r file dpgo; do
    if [ $# -gt 0 ] && ! printf '%s\n' "$@" | grep -qx "$file"; then continue; fi
    one="$(timeout "$timeout_s" "$bin" solve "$data/$file" --robots 1 --json --quiet 2>/dev/null)"
    team="$(timeout $((timeout_s + 60)) "$bin" solve "$data/$file" --robots "$robots" --distributed \
            --transport "$transport" --timeout "$timeout_s" "${overlap[@]}" --json 2>&1)"
    rc=$?
    if ! printf '%s' "$team" | python3 -c 'import json,sys; json.load(sys.stdin)' 2>/dev/null; then
        echo "| $file | $robots | $transport | ${OVERLAP:-} | exit $rc: $(printf '%s' "$team" | tail -1 | cut -c1-120) |"
        continue
    fi
    printf '%s\n' "$team" | python3 -c 'import json,sys; print(json.dumps(json.load(sys.stdin)))' >> "$out"
    printf '%s\n' "$team" | python3 -c '
import json, sys
t = json.load(sys.stdin)
file, dpgo, one_text = sys.argv[1], sys.argv[2], sys.argv[3]
one = json.loads(one_text) if one_text.strip() else None
b = t["bytes_between_robots"]
f = t.get("finish", {})
cg = f.get("cg_iterations", 0)
it = max(t["iterations"] + cg, 1)
finish = "%s, %d / %d" % (f["status"], f["steps"], cg) if f.get("status") else "-"
rel = "%.1e" % (abs(t["cost"] - one["cost"]) / one["cost"]) if one else "-"
wall = t.get("wall_seconds", t["seconds"])
ratio = "%.1fx" % (wall / one["seconds"]) if one and one["seconds"] > 0 else "-"
verdict = t["verdict"] if t["certified"] else "**%s**" % t["verdict"]
print("| %s | %d | %s | %s | %s | %s | %d | %s | %s | %d | %d | %.1f | %.1f | %.0f | %.1f | %.1f | %s | %s | %.0f |" % (
    file, t["robots"], t["transport"], t.get("overlap", "-"), verdict, rel, t["iterations"], dpgo, finish,
    t["certificate_rounds"], t["lanczos_steps"], b["by_actor"].get("solver", 0) / 1e6,
    b["by_actor"].get("certifier", 0) / 1e6, b["total"] * 8 / 1e3 / it, t["seconds"], wall,
    "%.2f" % one["seconds"] if one else "-", ratio, t["peak_rss_mb"]))
' "$file" "$dpgo" "$one"
done <<< "$table"
