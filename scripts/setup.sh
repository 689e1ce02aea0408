#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs every dependency from Debian's packages (as root, or through sudo), then
# configures and builds libwvol into build/. Idempotent: fast when all is there.
set -euo pipefail
cd "$(dirname "$0")/.."

mapfile -t pkgs < <(grep -v '^\s*#' scripts/packages.txt | sed '/^\s*$/d')
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

BUILD=${WVOL_BUILD_DIR:-build}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DWVOL_WITH_OPENVDB=ON -DWVOL_WITH_VTK=ON \
      -DWVOL_WERROR="${WVOL_WERROR:-OFF}" ${WVOL_CMAKE_ARGS:-} > "$BUILD.configure.log" 2>&1 \
  || { cat "$BUILD.configure.log"; exit 1; }
cmake --build "$BUILD" -j "$(nproc)"

# ParaView (docs/paraview.md). The reader plugin (paraview/: vtkWVCReader, C++ against
# paraview-dev) links the static libwvol of a second build without the VTK and OpenVDB adapters,
# $PV_BUILD: ParaView carries its own VTK, and Debian's VTK 9.1 must not come into its process.
# Debian's python3-paraview conflicts with python3-vtk9 (both ship the `vtkmodules` package),
# which the VTK adapter's tests need: its files are unpacked into $PV_BUILD/paraview-python
# instead of installed (the plugin's build takes the VTK wrapping's class hierarchies from
# there, paraview/CMakeLists.txt), and the wrappers $PV_BUILD/pvpython and $PV_BUILD/pvbatch
# put them on PYTHONPATH, with python/paraview/site/sitecustomize.py, which keeps pvpython off
# Debian's VTK Python package.
PV_BUILD=${WVOL_PARAVIEW_BUILD_DIR:-$BUILD-paraview}
PV_BUILD=$(mkdir -p "$PV_BUILD" && cd "$PV_BUILD" && pwd)
PVPY="$PV_BUILD/paraview-python"
if [ ! -f "$PVPY/usr/lib/python3/dist-packages/paraview/__init__.py" ]; then
  pv_version=$(dpkg-query -W -f='${Version}' paraview)
  pv_tmp=$(mktemp -d)
  chmod 755 "$pv_tmp"  # apt's download sandbox user must be able to write there
  chown _apt "$pv_tmp" 2>/dev/null || true
  (cd "$pv_tmp" && { apt-get download -qq "python3-paraview=$pv_version" 2>/dev/null \
     || { SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"; $SUDO apt-get update -qq \
          && apt-get download -qq "python3-paraview=$pv_version"; }; })
  rm -rf "$PVPY.tmp"
  dpkg-deb -x "$pv_tmp"/python3-paraview_*.deb "$PVPY.tmp"
  rm -rf "$pv_tmp" "$PVPY"
  mv "$PVPY.tmp" "$PVPY"
fi
for tool in pvpython pvbatch; do
  exe=/usr/bin/pvbatch
  [ "$tool" = pvbatch ] || exe=$(ls "$PVPY"/usr/bin/pvpython3.*)
  cat > "$PV_BUILD/$tool" <<WRAP
#!/bin/sh
# $tool with ParaView's Python modules (scripts/setup.sh)
PYTHONPATH="$PVPY/usr/lib/python3/dist-packages:$PWD/python/paraview/site\${PYTHONPATH:+:\$PYTHONPATH}" exec "$exe" "\$@"
WRAP
  chmod +x "$PV_BUILD/$tool"
done
cmake -S . -B "$PV_BUILD" -DCMAKE_BUILD_TYPE=Release -DWVOL_WITH_OPENVDB=OFF -DWVOL_WITH_VTK=OFF \
      -DWVOL_BUILD_APPS=OFF -DWVOL_BUILD_TESTS=OFF -DWVOL_BUILD_BENCH=OFF -DWVOL_BUILD_PYTHON=OFF \
      -DWVOL_BUILD_PARAVIEW_PLUGIN=ON \
      -DWVOL_WERROR="${WVOL_WERROR:-OFF}" > "$PV_BUILD.configure.log" 2>&1 \
  || { cat "$PV_BUILD.configure.log"; exit 1; }
cmake --build "$PV_BUILD" -j "$(nproc)" --target WvolReader
