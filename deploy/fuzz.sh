#!/usr/bin/env bash
# Fuzzes the untrusted decoders with libFuzzer (clang, ASan + UBSan), each for a bounded time: the
# envelope decoder, the message bodies the actors accept (actors/convert.h), the durable log
# reader, the g2o reader and the PCD reader.
# Usage: deploy/fuzz.sh [SECONDS]   (default 60 per target; FUZZ_BUILD_DIR overrides
# build-fuzz/; FUZZ_ACTORS=1 adds the message bodies and the durable log, whose sanitizer build
# takes the whole actor library: not yet run to completion on the 2-core machine, so off in CI)
# Builds only the fuzzer in its own clang build folder, writes a seed corpus of real encoded
# envelopes, fuzzes for SECONDS and exits non-zero when the fuzzer finds a crash, a leak or
# undefined behaviour (the input is kept in FUZZ_BUILD_DIR/artifacts/).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${FUZZ_BUILD_DIR:-$root/build-fuzz}"
seconds="${1:-60}"

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
cmake --build "$build" -j "${JOBS:-2}" --target fuzz_envelope fuzz_envelope_seeds fuzz_g2o fuzz_pcd
if [ "${FUZZ_ACTORS:-0}" = 1 ]; then
  cmake --build "$build" -j "${JOBS:-2}" --target fuzz_bodies fuzz_bodies_seeds fuzz_durable_log
fi

seeds="$build/seeds"
corpus="$build/corpus"
artifacts="$build/artifacts"
rm -rf "$seeds"
mkdir -p "$corpus" "$artifacts"
"$build/tests/fuzz/fuzz_envelope_seeds" "$seeds"

echo "fuzz: envelope decoder for ${seconds} s (corpus $corpus, crashes in $artifacts)"
# New inputs go to the first corpus folder; the seeds are read as well.
"$build/tests/fuzz/fuzz_envelope" "$corpus" "$seeds" \
  -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=8192 \
  -artifact_prefix="$artifacts/" -print_final_stats=1

# The readers: seeds are a small real g2o file and small PCD files of each DATA kind.
data="${CERTISLAM_DATA_DIR:-$root/../shared/data}"
for reader in g2o pcd; do
  mkdir -p "$build/corpus-$reader" "$build/seeds-$reader"
done
cp "$data/g2o/tinyGrid3D.g2o" "$build/seeds-g2o/" 2>/dev/null || true
printf 'FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n' \
  >"$build/seeds-pcd/ascii.pcd"
printf 'FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary\n0123456789ab' \
  >"$build/seeds-pcd/binary.pcd"
for reader in g2o pcd; do
  echo "fuzz: $reader reader for ${seconds} s"
  "$build/tests/fuzz/fuzz_$reader" "$build/corpus-$reader" "$build/seeds-$reader" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=8192 \
    -artifact_prefix="$artifacts/$reader-" -print_final_stats=1
done

[ "${FUZZ_ACTORS:-0}" = 1 ] || exit 0
# The message bodies (seeds: one real message per body and wire form) and the durable log
# reader (seeds: the bodies' seeds are not logs; a log starts empty and grows from there).
"$build/tests/fuzz/fuzz_bodies_seeds" "$build/seeds-bodies" >/dev/null
mkdir -p "$build/corpus-bodies" "$build/corpus-durable_log" "$build/seeds-durable_log"
printf '' >"$build/seeds-durable_log/empty"
for target in bodies durable_log; do
  echo "fuzz: $target for ${seconds} s"
  "$build/tests/fuzz/fuzz_$target" "$build/corpus-$target" "$build/seeds-$target" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
    -artifact_prefix="$artifacts/$target-" -print_final_stats=1
done
