#!/usr/bin/env bash
# Builds the libFuzzer target of the .wvc reader with clang in build-fuzz/ and runs
# it for a bounded time on the corpus kept in tests/fuzz/corpus (new inputs it
# finds go to a scratch folder, not into the tree). FUZZ_SECONDS (default 45).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang >/dev/null || { echo "fuzz.sh: clang not found (scripts/setup.sh installs it)"; exit 1; }
cmake -S . -B build-fuzz -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=Debug \
      -DWVOL_BUILD_FUZZ=ON -DWVOL_BUILD_TESTS=OFF -DWVOL_BUILD_PYTHON=OFF \
      -DWVOL_WITH_OPENVDB=OFF -DWVOL_WITH_VTK=OFF > build-fuzz.configure.log 2>&1 \
  || { cat build-fuzz.configure.log; exit 1; }
cmake --build build-fuzz -j "$(nproc)" --target fuzz_wvc
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
OMP_NUM_THREADS=1 ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  build-fuzz/tests/fuzz/fuzz_wvc -max_total_time="${FUZZ_SECONDS:-45}" -max_len=4096 -timeout=10 \
  -rss_limit_mb=2048 -artifact_prefix=build-fuzz/ -print_final_stats=1 "$scratch" tests/fuzz/corpus 2>&1 | tail -n 25
echo "fuzz.sh: no crash in ${FUZZ_SECONDS:-45} s"
