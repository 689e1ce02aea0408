#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The library without its optional dependencies (PNG, OpenEXR, LAPACKE, VTK, OpenVDB):
# configures and builds only the `wvol` library into build-minimal/ (warnings are
# errors), installs it into a scratch prefix and runs tests/install's program
# against it, which checks that the missing parts answer WVOL_ERR_UNSUPPORTED.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${WVOL_MINIMAL_BUILD_DIR:-build-minimal}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DWVOL_WERROR=ON \
      -DWVOL_WITH_PNG=OFF -DWVOL_WITH_OPENEXR=OFF -DWVOL_WITH_LAPACKE=OFF -DWVOL_WITH_VTK=OFF -DWVOL_WITH_OPENVDB=OFF -DWVOL_WITH_TINYOBJLOADER=OFF \
      -DWVOL_BUILD_APPS=OFF -DWVOL_BUILD_TESTS=OFF -DWVOL_BUILD_PYTHON=OFF -DWVOL_BUILD_BENCH=OFF \
      > "$BUILD.configure.log" 2>&1 || { cat "$BUILD.configure.log"; exit 1; }
cmake --build "$BUILD" -j "$(nproc)" --target wvol
cmake -DWVOL_BUILD_DIR="$PWD/$BUILD" -DWVOL_WORK_DIR="$PWD/$BUILD/install-test" -DCMAKE_C_COMPILER=cc \
      -P tests/install/run.cmake
