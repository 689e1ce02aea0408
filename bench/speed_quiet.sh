#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Coding speed of `wvol compress` / `wvol decompress` on one and two threads, for a quiet
# machine (the shared development machine's wall times measure its other jobs): builds the
# program without the optional libraries into build-speed/, makes the noisy skull and the
# turbulence field at 256^3 and 512^3, and times compress (streamed from the raw file, the
# default path) and decompress at 40 and 60 dB, best of 3 runs, OpenMP waiting passively.
# Prints one JSON line per run and writes them to $OUT/speed.jsonl (or bench/results/).
#   bash bench/speed_quiet.sh [SIZES]      # default "256 512"
set -uo pipefail
cd "$(dirname "$0")/.."
SIZES=${1:-256 512}
OUTD=${OUT:-bench/results}
mkdir -p "$OUTD"
LOG="$OUTD/speed.jsonl"
: >"$LOG"
echo "tree: $(git rev-parse --abbrev-ref HEAD 2>/dev/null) $(git rev-parse --short HEAD 2>/dev/null); cpus $(nproc); $(grep -m1 'model name' /proc/cpuinfo)"
B=build-speed
if [ ! -x "$B/wvol" ]; then
  cmake -S . -B "$B" -DCMAKE_BUILD_TYPE=Release \
        -DWVOL_WITH_VTK=OFF -DWVOL_WITH_OPENVDB=OFF -DWVOL_WITH_TINYOBJLOADER=OFF -DWVOL_BUILD_TESTS=OFF \
        -DWVOL_BUILD_PYTHON=OFF -DWVOL_BUILD_BENCH=OFF >"$OUTD/speed_configure.log" 2>&1 || { tail -20 "$OUTD/speed_configure.log"; exit 1; }
  cmake --build "$B" -j "$(nproc)" --target wvol_app >"$OUTD/speed_build.log" 2>&1 || { tail -20 "$OUTD/speed_build.log"; exit 1; }
fi
W=$B/wvol
export OMP_WAIT_POLICY=passive
TMP=$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d) # outputs in memory: the disk's speed is not measured
trap 'rm -rf "$TMP"' EXIT
best() { # best wall seconds of 3 runs of "$@"
  local b=1e9 t
  for _ in 1 2 3; do
    local t0=$(date +%s.%N)
    "$@" >/dev/null 2>&1 || { echo null; return; }
    t=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.4f", b - a }')
    b=$(awk -v a="$t" -v b="$b" 'BEGIN { print (a < b ? a : b) }')
  done
  echo "$b"
}
for n in $SIZES; do
  for kind in skull turbulence; do
    extra=""; [ "$kind" = skull ] && extra="--noise 20"
    OMP_NUM_THREADS=$(nproc) $W synth $kind --size $n $extra -o "$TMP/v.raw" >/dev/null
    for t in 40 60; do
      $W compress "$TMP/v.raw" --dims ${n}x${n}x${n} -o "$TMP/v.wvc" --psnr $t --threads 1 --json >"$TMP/c.json"
      bytes=$(stat -c %s "$TMP/v.wvc")
      for th in 1 2; do
        c=$(OMP_NUM_THREADS=$th best $W compress "$TMP/v.raw" --dims ${n}x${n}x${n} -o "$TMP/x.wvc" --psnr $t --threads $th)
        d=$(OMP_NUM_THREADS=$th best $W decompress "$TMP/v.wvc" -o "$TMP/d.raw")
        line="{\"kind\":\"$kind\",\"n\":$n,\"target\":$t,\"threads\":$th,\"bytes\":$bytes,\"compress_s\":$c,\"decompress_s\":$d,\"mb\":$((4 * n * n * n / 1000000))}"
        echo "$line" | tee -a "$LOG"
      done
    done
  done
done
