#!/usr/bin/env python3
"""Checks that the architecture's layers hold: no #include and no CMake link edge runs upward.

Usage: deploy/check_layers.py [BUILD_DIR]   (BUILD_DIR given: also checks the CMake target graph)
Layers, lowest first; a folder may use its own files and any folder listed in ALLOWED for it.
"""
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# folder -> folders whose headers it may include (besides its own).
SLAM_SUBSYSTEMS = ["slam/io", "slam/sim", "slam/frontend", "slam/backend", "slam/mapping", "slam/eval"]
ALLOWED = {
    "proto": [],
    "transport": ["proto"],
    "slam/core": [],
    **{s: ["slam/core"] for s in SLAM_SUBSYSTEMS},
    "slam/io/rosbag": ["slam/core", "slam/io"],
    "certify": ["slam/core", "slam/backend"],
    "certify/distributed": ["certify", "slam/core", "slam/backend"],
    "certify/pipeline": ["certify", "certify/distributed", "slam"],
    "actors": ["proto", "transport", "certify", "slam"],
    "bin": ["proto", "transport", "certify", "slam", "actors"],
}

# CMake target -> folder (for the link graph).
TARGETS = {
    "certislam_proto": "proto",
    "certislam_transport": "transport",
    "certislam_slam_core": "slam/core",
    "certislam_slam_io": "slam/io",
    "certislam_slam_io_base": "slam/io",
    "certislam_slam_sim": "slam/sim",
    "certislam_slam_frontend": "slam/frontend",
    "certislam_slam_backend": "slam/backend",
    "certislam_slam_mapping": "slam/mapping",
    "certislam_slam_eval": "slam/eval",
    "certislam_rosbag": "slam/io/rosbag",
    "certislam_certify": "certify",
    "certislam_certify_distributed": "certify/distributed",
    "certislam_pipeline": "certify/pipeline",
    "certislam_pipeline_rounds": "certify/pipeline",
    "certislam_actors": "actors",
    "certislam_actors_backend": "actors",
    "certislam": "bin",
    "certislam-robot": "bin",
    "certislam_robot_command": "bin",
    "certislam_team_config": "bin",
    "certislam_python": "bin",
}


def folder_of(path: str) -> str:
    """The deepest folder of ALLOWED that holds `path` ('' if none)."""
    best = ""
    for folder in ALLOWED:
        if path.startswith(folder + "/") and len(folder) > len(best):
            best = folder
    return best


def may_use(user: str, used: str) -> bool:
    if not used or used == user or used.startswith(user + "/") and used not in ALLOWED:
        return True
    return any(used == a or used.startswith(a + "/") for a in ALLOWED[user])


def check_includes() -> list:
    errors = []
    include = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
    for path in sorted(ROOT.glob("**/*")):
        rel = path.relative_to(ROOT).as_posix()
        if path.suffix not in (".h", ".cpp", ".cc") or rel.startswith(("build", "tests/")):
            continue
        user = folder_of(rel)
        if not user:
            continue
        for lineno, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            m = include.match(line)
            if not m or "/" not in m.group(1):
                continue
            used = folder_of(m.group(1))
            if used and not may_use(user, used):
                errors.append(f"{rel}:{lineno}: {user} includes {m.group(1)} ({used} is not below it)")
    return errors


def check_targets(build: Path) -> list:
    dot = build / "layers.dot"
    subprocess.run(["cmake", f"--graphviz={dot}", "."], cwd=build, check=True,
                   stdout=subprocess.DEVNULL)
    names, errors = {}, []
    for line in dot.read_text().splitlines():
        m = re.match(r'\s*"(node\d+)"\s*\[\s*label\s*=\s*"([^"]+)"', line)
        if m:
            names[m.group(1)] = m.group(2)
    for line in dot.read_text().splitlines():
        m = re.match(r'\s*"(node\d+)"\s*->\s*"(node\d+)"', line)
        if not m:
            continue
        a, b = names.get(m.group(1)), names.get(m.group(2))
        if a in TARGETS and b in TARGETS:
            user, used = TARGETS[a], TARGETS[b]
            if not may_use(user, used):
                errors.append(f"target {a} ({user}) links {b} ({used}): an upward edge")
    if not names:
        errors.append(f"{dot}: no targets found")
    return errors


def main() -> int:
    errors = check_includes()
    if len(sys.argv) > 1:
        errors += check_targets(Path(sys.argv[1]).resolve())
    for e in errors:
        print(e, file=sys.stderr)
    print(f"check_layers: {len(errors)} upward edge(s)")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
