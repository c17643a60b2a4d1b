#!/usr/bin/env bash
# Installs the build into a temporary prefix, builds tests/package/consumer against it with
# find_package(certislam) and solves a g2o file with it. Usage: consumer_test.sh BUILD_DIR SRC_DIR G2O
set -euo pipefail
build="$1" src="$2" g2o="$3"
prefix="$(mktemp -d)"
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --prefix "$prefix/usr" >/dev/null
test -x "$prefix/usr/bin/certislam"
"$prefix/usr/bin/certislam" --version
test -x "$prefix/usr/bin/certislam-robot"  # the lean back-end-only robot, installed beside it
"$prefix/usr/bin/certislam-robot" --version
cmake -S "$src/tests/package/consumer" -B "$prefix/consumer" -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$prefix/usr" >/dev/null
cmake --build "$prefix/consumer" -j2 >/dev/null
"$prefix/consumer/consumer" "$g2o"
