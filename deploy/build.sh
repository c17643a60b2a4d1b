#!/usr/bin/env bash
# Installs missing Debian packages, then configures and builds certislam (Release) in build/.
# Usage: deploy/build.sh [extra cmake args...]   (BUILD_DIR overrides the build folder)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BUILD_DIR:-$root/build}"

"$root/deploy/install-deps.sh"
mkdir -p "$build"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release "$@" >"$build/configure.log" 2>&1 || {
  cat "$build/configure.log" >&2
  exit 1
}
cmake --build "$build" -j "${JOBS:-2}"
