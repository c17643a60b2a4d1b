#!/usr/bin/env bash
# Quick start, command 2: set up, build with warnings as errors, check formatting and
# clang-tidy (what changed since its last full run: deploy/tidy.sh), run the whole test suite,
# then fuzz the untrusted decoders for a bounded time each.
# Each step prints the seconds spent so far (CI has 90 minutes on 2 cores).
# Env: FUZZ_SECONDS (default 20 per target; 0 skips), TIDY (default 1; 0 skips), BUILD_DIR.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BUILD_DIR:-$root/build}"
cd "$root"
step() { echo "== $1 (at ${SECONDS} s)"; }

"$root/deploy/install-deps.sh"

step "format check"
mapfile -t sources < <(git ls-files '*.h' '*.cpp' '*.cc' | grep -E '^(proto|transport|slam|certify|actors|bin|tests)/')
if [ ${#sources[@]} -gt 0 ]; then
  clang-format --dry-run --Werror "${sources[@]}"
fi

step "layers (no include and no link edge runs upward)"
python3 "$root/deploy/check_layers.py"

step "sizes (no source file over 500 lines, no function over 80)"
python3 "$root/deploy/check_sizes.py"

step "build"
"$root/deploy/build.sh" -DCERTISLAM_WERROR=ON -DCERTISLAM_BUILD_TESTS=ON

if [ "${TIDY:-1}" != "0" ]; then
  step "clang-tidy (the sources changed since .ci/tidy-base: deploy/tidy.sh)"
  BUILD_DIR="$build" "$root/deploy/tidy.sh"
fi

step "layers of the built targets' link edges"
python3 "$root/deploy/check_layers.py" "$build"

step "tests"
(cd "$build" && ctest --output-on-failure -j "${JOBS:-2}" --timeout 900)

if [ "${FUZZ_SECONDS:-20}" != "0" ] && [ -x "$root/deploy/fuzz.sh" ]; then
  step "fuzz"
  "$root/deploy/fuzz.sh" "${FUZZ_SECONDS:-20}"
fi
step "all checks passed"
