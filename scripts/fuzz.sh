#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Builds the libFuzzer targets with clang in build-fuzz/ and runs each for a bounded
# time on its corpus (new inputs they find go to a scratch folder, not into the tree):
# the .wvc reader on tests/fuzz/corpus for FUZZ_SECONDS (default 35), the DICOM file
# parser on tests/fuzz/corpus_dicom for FUZZ_DICOM_SECONDS (default 10), the NRRD readers and
# the MetaImage header on tests/fuzz/corpus_nrrd for FUZZ_NRRD_SECONDS (default 15), the
# camera and transfer-function text on tests/fuzz/corpus_text for FUZZ_TEXT_SECONDS
# (default 5); the last two with a dictionary of their formats' words.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang >/dev/null || { echo "fuzz.sh: clang not found (scripts/setup.sh installs it)"; exit 1; }
cmake -S . -B build-fuzz -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=Debug \
      -DWVOL_BUILD_FUZZ=ON -DWVOL_BUILD_TESTS=OFF -DWVOL_BUILD_PYTHON=OFF \
      -DWVOL_WITH_OPENVDB=OFF -DWVOL_WITH_VTK=OFF > build-fuzz.configure.log 2>&1 \
  || { cat build-fuzz.configure.log; exit 1; }
cmake --build build-fuzz -j "$(nproc)" --target fuzz_wvc fuzz_dicom fuzz_nrrd fuzz_text
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
run() { # target seconds corpus [libFuzzer options]
  local target=$1 seconds=$2 corpus=$3
  shift 3
  mkdir -p "$scratch/$target"
  OMP_NUM_THREADS=1 ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    build-fuzz/tests/fuzz/"$target" -max_total_time="$seconds" -max_len=4096 -timeout=10 \
    -rss_limit_mb=2048 -artifact_prefix=build-fuzz/ -print_final_stats=1 "$@" "$scratch/$target" "$corpus" 2>&1 \
    | grep -v '^"' | tail -n 25
  echo "fuzz.sh: $target: no crash in $seconds s"
}
run fuzz_wvc "${FUZZ_SECONDS:-35}" tests/fuzz/corpus
run fuzz_dicom "${FUZZ_DICOM_SECONDS:-10}" tests/fuzz/corpus_dicom
run fuzz_nrrd "${FUZZ_NRRD_SECONDS:-15}" tests/fuzz/corpus_nrrd -dict=tests/fuzz/nrrd.dict
run fuzz_text "${FUZZ_TEXT_SECONDS:-5}" tests/fuzz/corpus_text -dict=tests/fuzz/text.dict
