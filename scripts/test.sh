#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The whole test suite: setup + build (warnings are errors), C tests under ctest,
# Python tests under pytest, the C tests again under AddressSanitizer and
# UndefinedBehaviorSanitizer (built with clang), the Python module's in-process tests under the
# same sanitizers and under Python's debug allocator, the same .wvc bytes from the release and the sanitizer builds
# (scripts/test_same_bytes.sh), the library built without its optional dependencies
# (scripts/test_minimal.sh), and bounded libFuzzer runs of the readers (scripts/fuzz.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

WVOL_WERROR=ON bash scripts/setup.sh
echo "== C tests"
ctest --test-dir build --output-on-failure -j 2

echo "== Python tests"
PYTHONPATH="$PWD/build/python${PYTHONPATH:+:$PYTHONPATH}" WVOL_BIN="$PWD/build/wvol" \
  /usr/bin/python3 -m pytest -q tests/python

echo "== C tests under ASan + UBSan, built with clang"
# clang, not the release build's GCC: its UBSan checks more (float-to-integer overflow among
# them), its warnings are other warnings, and the byte check below then compares the two
# compilers' files as well as the CPU levels'
cmake -S . -B build-asan -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
      -DCMAKE_BUILD_TYPE=Debug -DWVOL_SANITIZE=ON -DWVOL_WERROR=ON \
      -DWVOL_BUILD_PYTHON=ON -DWVOL_WITH_OPENVDB=ON -DWVOL_WITH_VTK=ON > build-asan.configure.log 2>&1 \
  || { cat build-asan.configure.log; exit 1; }
cmake --build build-asan -j "$(nproc)"
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build-asan --output-on-failure -j 2

echo "== the Python module's in-process tests under ASan + UBSan, and under Python's debug allocator"
# The extension built with the sanitizers loads into the uninstrumented interpreter with clang's
# runtime preloaded; its objects then come from malloc, so the module's own reads and writes are
# checked. Reads the interpreter makes for it (a borrowed reference used after its owner was
# freed) are not instrumented: Python's debug allocator, which overwrites freed memory, turns
# those into wrong values or crashes instead.
LD_PRELOAD="$(clang -print-file-name=libclang_rt.asan-x86_64.so)" PYTHONMALLOC=malloc \
  ASAN_OPTIONS=detect_leaks=0 UBSAN_OPTIONS=print_stacktrace=1 \
  PYTHONPATH="$PWD/build-asan/python" WVOL_BIN="$PWD/build/wvol" /usr/bin/python3 -m pytest -q tests/python/test_py_*.py
PYTHONMALLOC=debug PYTHONPATH="$PWD/build/python" WVOL_BIN="$PWD/build/wvol" \
  /usr/bin/python3 -m pytest -q tests/python/test_py_*.py

echo "== the same bytes from the release build (GCC, CPU-level clones) and the sanitizer build (clang, none)"
ASAN_OPTIONS=detect_leaks=1 bash scripts/test_same_bytes.sh build/wvol build-asan/wvol

echo "== the library without its optional dependencies"
bash scripts/test_minimal.sh

if [ -x scripts/fuzz.sh ]; then
  echo "== fuzzing"
  bash scripts/fuzz.sh
fi
echo "== all tests passed"
