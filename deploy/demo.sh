#!/usr/bin/env bash
# Quick start, command 1: set up, build, and run the built-in simulated mission.
# Usage: deploy/demo.sh [certislam demo options...]   (results in out/demo by default)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/deploy/build.sh" -DCERTISLAM_BUILD_TESTS=OFF
build="${BUILD_DIR:-$root/build}"
if [ $# -eq 0 ]; then set -- --out "$root/out/demo"; fi
exec "$build/bin/certislam" demo "$@"
