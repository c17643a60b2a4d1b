#!/usr/bin/env bash
# Fuzzes every untrusted decoder with libFuzzer (clang, ASan + UBSan), each for a bounded time: the
# envelope decoder, the message bodies the actors accept (actors/convert.h: solver, certifier,
# mapper, loop matcher and descriptor bodies), the durable log reader, the g2o reader, the PCD
# reader, a peer's submap bytes (slam/mapping/tsdf_serialize.h's checked voxel format).
# Usage: deploy/fuzz.sh [SECONDS]   (default 40 per target; FUZZ_BUILD_DIR overrides build-fuzz/;
# FUZZ_TARGETS="bodies g2o" picks targets)
# Builds only the fuzzers in their own clang build folder (the bodies and the durable log link a
# small library of the decoders, not the actors), writes seed corpora of real encoded messages,
# logs and files, fuzzes for SECONDS each and exits non-zero when a fuzzer finds a crash, a leak,
# an allocation beyond its limit or undefined behaviour (the input is kept in
# FUZZ_BUILD_DIR/artifacts/).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${FUZZ_BUILD_DIR:-$root/build-fuzz}"
seconds="${1:-40}"
targets="${FUZZ_TARGETS:-envelope bodies durable_log g2o pcd submap}"

"$root/deploy/install-deps.sh"

sanitizers="-fsanitize=address,undefined -fno-sanitize-recover=undefined"
mkdir -p "$build"
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_C_FLAGS="-fsanitize=fuzzer-no-link $sanitizers" \
    -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link $sanitizers" \
    -DCMAKE_EXE_LINKER_FLAGS="$sanitizers" \
    -DCERTISLAM_FUZZ=ON -DCERTISLAM_BUILD_TESTS=OFF -DCERTISLAM_WERROR=ON \
    >"$build/configure.log" 2>&1 || {
    cat "$build/configure.log" >&2
    exit 1
  }
fi
binaries=()
for target in $targets; do binaries+=("fuzz_$target"); done
cmake --build "$build" -j "${JOBS:-2}" --target "${binaries[@]}" fuzz_envelope_seeds fuzz_bodies_seeds \
  $(case " $targets " in *" submap "*) echo fuzz_submap_seeds ;; esac)

# Seeds: real encoded envelopes; one real message per body and wire form, and real durable logs;
# a small real g2o file; small PCD files of each DATA kind.
rm -rf "$build"/seeds-*
"$build/tests/fuzz/fuzz_envelope_seeds" "$build/seeds-envelope" >/dev/null
"$build/tests/fuzz/fuzz_bodies_seeds" "$build/seeds-bodies" "$build/seeds-durable_log" >/dev/null
case " $targets " in *" submap "*) "$build/tests/fuzz/fuzz_submap_seeds" "$build/seeds-submap" >/dev/null ;; esac
data="${CERTISLAM_DATA_DIR:-$root/../shared/data}"
mkdir -p "$build/seeds-g2o" "$build/seeds-pcd" "$build/artifacts"
cp "$data/g2o/tinyGrid3D.g2o" "$build/seeds-g2o/" 2>/dev/null || true
printf 'FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n' \
  >"$build/seeds-pcd/ascii.pcd"
printf 'FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary\n0123456789ab' \
  >"$build/seeds-pcd/binary.pcd"

for target in $targets; do
  max_len=8192
  case "$target" in bodies | durable_log) max_len=65536 ;; submap) max_len=262144 ;; esac
  echo "fuzz: $target for ${seconds} s (corpus $build/corpus-$target, crashes in $build/artifacts)"
  mkdir -p "$build/corpus-$target"
  # New inputs go to the first corpus folder; the seeds are read as well.
  "$build/tests/fuzz/fuzz_$target" "$build/corpus-$target" "$build/seeds-$target" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -detect_leaks=1 -max_len="$max_len" \
    -artifact_prefix="$build/artifacts/$target-" -print_final_stats=1
done
