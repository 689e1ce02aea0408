#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Coding speed of `wvol compress` / `wvol decompress` on one and two threads, for a quiet
# machine (the shared development machine's wall times measure its other jobs): builds the
# program without the optional libraries into build-speed/, makes the noisy skull and the
# turbulence field at 256^3 and 512^3, and times compress (streamed from the raw file, the
# default path) and decompress at 40 and 60 dB, best of 3 runs, OpenMP waiting passively.
# Prints one JSON line per run and writes them to $OUT/speed.jsonl (or bench/results/).
# WVOL_BASE=path: a second program (e.g. main's build) timed on the same inputs, its runs
# alternating with this tree's (base_compress_s, base_decompress_s: the same measure, its
# own file; base_bytes its size).
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
BASE=${WVOL_BASE:-}
wall() { # wall seconds of one run of "$@", or null
  local t0=$(date +%s.%N)
  "$@" >/dev/null 2>&1 || { echo null; return; }
  awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.4f", b - a }'
}
minof() { awk -v a="$1" -v b="$2" 'BEGIN { print (a == "null" || b == "null") ? "null" : (a < b ? a : b) }'; }
best2() { # best wall seconds of 3 runs of command A ($1, a string) and B ($2), alternating
  local a=1e9 b=1e9
  for _ in 1 2 3; do
    a=$(minof "$(eval wall $1)" "$a")
    if [ -n "$2" ]; then b=$(minof "$(eval wall $2)" "$b"); fi
  done
  [ -n "$2" ] || b=null
  echo "$a $b"
}
for n in $SIZES; do
  for kind in skull turbulence; do
    extra=""; [ "$kind" = skull ] && extra="--noise 20"
    OMP_NUM_THREADS=$(nproc) $W synth $kind --size $n $extra -o "$TMP/v.raw" >/dev/null
    for t in 40 60; do
      $W compress "$TMP/v.raw" --dims ${n}x${n}x${n} -o "$TMP/v.wvc" --psnr $t --threads 1 --json >"$TMP/c.json"
      bytes=$(stat -c %s "$TMP/v.wvc")
      bbytes=null
      if [ -n "$BASE" ]; then
        "$BASE" compress "$TMP/v.raw" --dims ${n}x${n}x${n} -o "$TMP/b.wvc" --psnr $t --threads 1 >/dev/null
        bbytes=$(stat -c %s "$TMP/b.wvc")
      fi
      for th in 1 2; do
        export OMP_NUM_THREADS=$th
        cx="$W compress $TMP/v.raw --dims ${n}x${n}x${n} -o $TMP/x.wvc --psnr $t --threads $th"
        dx="$W decompress $TMP/v.wvc -o $TMP/d.raw"
        cb="" db=""
        if [ -n "$BASE" ]; then
          cb="$BASE compress $TMP/v.raw --dims ${n}x${n}x${n} -o $TMP/y.wvc --psnr $t --threads $th"
          db="$BASE decompress $TMP/b.wvc -o $TMP/d.raw"
        fi
        read -r c bc <<<"$(best2 "$cx" "$cb")"
        read -r d bd <<<"$(best2 "$dx" "$db")"
        unset OMP_NUM_THREADS
        line="{\"kind\":\"$kind\",\"n\":$n,\"target\":$t,\"threads\":$th,\"bytes\":$bytes,\"compress_s\":$c,\"decompress_s\":$d,\"base_bytes\":$bbytes,\"base_compress_s\":$bc,\"base_decompress_s\":$bd,\"mb\":$((4 * n * n * n / 1000000))}"
        echo "$line" | tee -a "$LOG"
      done
    done
  done
done
