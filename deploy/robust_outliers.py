#!/usr/bin/env python3
"""Robust mode against injected outliers: adds K random loop closures (seeded; random pose pair at
least 2 apart, uniform translation in [-20, 20] m, uniform random rotation, the information of
the file's first edge) to each g2o file, runs `certislam solve --robust --json` on it, and
prints a Markdown table: outliers rejected, genuine edges rejected, cost beside the clean
file's optimum, verdict, seconds. The injected edges are the last K of the file, so the JSON's
`rejected_edges` tells them apart.

Usage: deploy/robust_outliers.py [files...]   (default: tinyGrid3D sphere2500 torus3D
       parking-garage from ../shared/data/g2o)
  env: CERTISLAM (binary, default build/bin/certislam), K (outliers, default 20), SEED (default 7),
       OUT (folder for the corrupted files, default out/robust)
"""
import json
import math
import os
import random
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("CERTISLAM", os.path.join(ROOT, "build/bin/certislam"))
DATA = os.path.join(ROOT, "..", "shared", "data", "g2o")
K = int(os.environ.get("K", "20"))
SEED = int(os.environ.get("SEED", "7"))
OUT = os.environ.get("OUT", os.path.join(ROOT, "out", "robust"))


def corrupt(path, rng):
    lines = open(path).read().splitlines()
    n = sum(1 for l in lines if l.startswith("VERTEX"))
    edges = [l for l in lines if l.startswith("EDGE")]
    template = edges[0].split()
    for _ in range(K):
        i = rng.randrange(n)
        j = rng.randrange(n)
        while abs(i - j) < 2:
            j = rng.randrange(n)
        q = [rng.gauss(0.0, 1.0) for _ in range(4)]
        norm = math.sqrt(sum(x * x for x in q))
        fields = list(template)
        fields[1:3] = [str(i), str(j)]
        fields[3:6] = ["%.4f" % rng.uniform(-20.0, 20.0) for _ in range(3)]
        fields[6:10] = ["%.9f" % (x / norm) for x in q]
        lines.append(" ".join(fields))
    os.makedirs(OUT, exist_ok=True)
    out = os.path.join(OUT, os.path.basename(path).replace(".g2o", "_out%d.g2o" % K))
    open(out, "w").write("\n".join(lines) + "\n")
    return out, len(edges)


def solve(path, robust):
    args = [BIN, "solve", path, "--json"] + (["--robust"] if robust else [])
    run = subprocess.run(args, capture_output=True, text=True)
    if run.returncode not in (0, 2, 3):
        sys.exit("%s failed (%d): %s" % (" ".join(args), run.returncode, run.stderr[-500:]))
    return json.loads(run.stdout)


def main():
    names = sys.argv[1:] or ["tinyGrid3D", "sphere2500", "torus3D", "parking-garage"]
    rng = random.Random(SEED)
    print("| file | outliers rejected | genuine rejected | reinstated | cost (clean f*) | verdict | seconds |")
    print("|---|---|---|---|---|---|---|")
    for name in names:
        path = name if name.endswith(".g2o") else os.path.join(DATA, name + ".g2o")
        clean = solve(path, False)
        corrupted, genuine = corrupt(path, rng)
        j = solve(corrupted, True)
        rejected = j["rejected_edges"]
        outliers = sum(1 for e in rejected if e >= genuine)
        print("| %s | %d / %d | %d / %d | %d | %.6g (%.6g) | %s | %.2f |" % (
            os.path.basename(path), outliers, K, len(rejected) - outliers, genuine,
            j["gnc_reinstated"], j["cost"], clean["cost"], j["verdict"], j["seconds"]))


if __name__ == "__main__":
    main()
