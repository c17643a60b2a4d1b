#!/usr/bin/env bash
# Runs `certislam solve` on every g2o file with a reference optimum f* (data/g2o/README.md), with
# --robots 1 and --robots 5, and prints a Markdown table: cost, relative gap to f*, the
# certificate's verdict and proven bound beside the true gap cost - f*, time, and the SE-Sync
# anchors of issue 3 with the ratio.
# Usage: deploy/solve_all.sh [timeout_s per run (default 600)] [files...]
#   env: CERTISLAM (the binary; default build/bin/certislam), DATA (default ../shared/data/g2o),
#        ROBOTS (default "1 5"), OUT (JSON lines, default out/solve_all.jsonl),
#        METHOD (rbcd or lm, default rbcd: lm is the local-search baseline, judged by the certificate)
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${CERTISLAM:-$root/build/bin/certislam}"
data="${DATA:-$root/../shared/data/g2o}"
timeout_s="${1:-600}"
shift || true
robots_list="${ROBOTS:-1 5}"
method="${METHOD:-rbcd}"
out="${OUT:-$root/out/solve_all.jsonl}"
mkdir -p "$(dirname "$out")"
: > "$out"

# file f* SE-Sync-seconds (SE-Sync's solve + certify on the build machine kind; - if none)
read -r -d '' table <<'LIST'
tinyGrid3D.g2o 18.5193868731 -
smallGrid3D.g2o 1025.39802075 -
sphere2500.g2o 1687.0056783 0.74
torus3D.g2o 24227.0415461 1.49
parking-garage.g2o 1.2624854718 0.57
cubicle.g2o 717.134043271 1.90
CSAIL.g2o 31.7037159922 -
intel.g2o 52.3482275928 -
manhattan.g2o 6431.39138953 -
city10000.g2o 638.624621872 1.31
MIT.g2o 61.1541160916 -
input_INTEL_g2o.g2o 393.652540983 -
kitti_00.g2o 125.693514547 -
kitti_06.g2o 35.3252352854 -
kitti_07.g2o 23.9338449866 -
kitti_08.g2o 0 -
kitti_09.g2o 61.3099539282 -
variants/dpgo/CSAIL.g2o 31.4703317764 -
variants/dpgo/kitti_00.g2o 125.680707744 -
LIST

echo "| file | robots | method | cost | f* | rel. gap | verdict | lambda_min | proven bound | true gap | iterations | seconds | CPU s | SE-Sync s | ratio (wall) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
while read -r file fstar sesync; do
    if [ $# -gt 0 ] && ! printf '%s\n' "$@" | grep -qx "$file"; then continue; fi
    for robots in $robots_list; do
        json="$(timeout "$timeout_s" nice "$bin" solve "$data/$file" --robots "$robots" --method "$method" \
                --json --quiet 2>/dev/null)"
        rc=$?
        if { [ $rc -ne 0 ] && [ $rc -ne 3 ]; } || [ -z "$json" ]; then  # 3: not certified
            reason="exit $rc"; [ $rc -eq 124 ] && reason="timeout ${timeout_s} s"
            echo "| $file | $robots | $method | - | $fstar | - | - | - | - | - | - | $reason | - | $sesync | - |"
            continue
        fi
        printf '%s\n' "$json" | python3 -c 'import json,sys; print(json.dumps(json.load(sys.stdin)))' >> "$out"
        printf '%s\n' "$json" | python3 -c '
import json, sys
j = json.load(sys.stdin)
file, robots, fstar, sesync, method = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4], sys.argv[5]
cost = j["cost"]
gap = (cost - fstar) / fstar if fstar > 0 else cost
ratio = "%.1fx" % (j["seconds"] / float(sesync)) if sesync != "-" and method == "rbcd" else "-"
bound = j.get("suboptimality_bound")
bound = "-" if bound is None else "%.2e" % bound
lam = j.get("lambda_min")
lam = "-" if lam is None else "%.2e" % lam
verdict = j["verdict"] if j["certified"] else "**%s**" % j["verdict"]
print("| %s | %s | %s | %.10g | %.10g | %+.2e | %s | %s | %s | %.2e | %d | %.2f | %.2f | %s | %s |" % (
    file, robots, method, cost, fstar, gap, verdict, lam, bound, cost - fstar, j["iterations"],
    j["seconds"], j["cpu_seconds"], sesync, ratio))
' "$file" "$robots" "$fstar" "$sesync" "$method"
    done
done <<< "$table"
