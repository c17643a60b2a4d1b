#!/usr/bin/env bash
# clang-tidy (.clang-tidy) over certislam's own sources: transport, slam, certify, actors, bin.
# Usage: deploy/tidy.sh [--all | BASE]   (BUILD_DIR: the configured build with compile_commands)
#   --all  every source (long: each file parses its Eigen, PCL and protobuf headers again)
#   BASE   the sources changed since commit BASE and those that include a changed header or the
#          header of a changed schema directly; default: the commit in .ci/tidy-base, the last
#          one whose --all run was clean
# After a clean --all run, record HEAD as the new base: git rev-parse HEAD > .ci/tidy-base.
# Exits non-zero on any warning the config makes an error.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BUILD_DIR:-$root/build}"
cd "$root"
dirs='^(transport|slam|certify|actors|bin)/'

if [ "${1:-}" = "--all" ]; then
  mapfile -t files < <(git ls-files '*.cpp' | grep -E "$dirs")
else
  if [ -n "${1:-}" ] && ! git cat-file -e "$1^{commit}" 2>/dev/null; then
    echo "tidy.sh: '$1' is not a commit of this repository (usage: tidy.sh [--all | BASE])" >&2
    exit 2
  fi
  base="${1:-$(cat "$root/.ci/tidy-base")}"
  if ! git cat-file -e "$base^{commit}" 2>/dev/null; then
    echo "tidy.sh: WARNING: base commit '$base' is not in this clone (shallow?): nothing was" \
      "checked; fetch the history (git fetch --unshallow) or run deploy/tidy.sh --all" >&2
    exit 0
  fi
  if ! git diff --quiet "$base" -- .clang-tidy; then
    echo "tidy.sh: .clang-tidy changed since the base: a check it adds needs" \
      "deploy/tidy.sh --all" >&2
  fi
  # Against the working tree: the same as HEAD in a clean clone, and a developer's edits too.
  mapfile -t changed < <(git diff --name-only "$base" -- | grep -E "$dirs|^proto/" || true)
  declare -A pick=()
  for f in "${changed[@]}"; do
    [ -f "$f" ] || continue  # deleted since the base
    header=""
    case "$f" in
      *.cpp) pick["$f"]=1 ;;
      *.h) header="$f" ;;
      proto/*.proto) header="${f#proto/}"; header="${header%.proto}.pb.h" ;;
    esac
    if [ -n "$header" ]; then
      while IFS= read -r user; do pick["$user"]=1; done < <(
        git grep -l -F "#include \"$header\"" -- '*.cpp' | grep -E "$dirs" || true)
    fi
  done
  files=("${!pick[@]}")
  echo "tidy.sh: ${#files[@]} sources changed since ${base:0:12} or include what changed"
fi
if [ ${#files[@]} -eq 0 ]; then
  exit 0
fi
printf '%s\n' "${files[@]}" | sort |
  xargs -P "${JOBS:-2}" -n 4 clang-tidy -p "$build" --quiet \
    --extra-arg=-Wno-unknown-warning-option 2>/dev/null
