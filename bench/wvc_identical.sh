#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Byte-for-byte comparison of this tree's `wvol compress` / `wvol decompress` with another
# program's (e.g. main's build) on the speed benchmark's volumes: the noisy skull and the
# turbulence field, four wavelet families, 40, 50 and 60 dB, one thread and two. A change
# meant to make the coder faster without changing its output must print no DIFFER line.
#   WVOL_BASE=path/to/wvol bash bench/wvc_identical.sh [SIZE] [WVOL]   # default 256, build/wvol
set -uo pipefail
cd "$(dirname "$0")/.."
N=${1:-256}
W=${2:-build/wvol}
BASE=${WVOL_BASE:?set WVOL_BASE to the program to compare with}
TMP=$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)
trap 'rm -rf "$TMP"' EXIT
bad=0 n=0
for kind in skull turbulence; do
  extra=""; [ "$kind" = skull ] && extra="--noise 20"
  "$W" synth $kind --size "$N" $extra -o "$TMP/v.raw" >/dev/null || exit 1
  for fam in haar db2 coif2 bl3; do
    for t in 40 50 60; do
      for th in 1 2; do
        OMP_NUM_THREADS=$th "$W" compress "$TMP/v.raw" --dims ${N}x${N}x${N} --wavelet $fam --psnr $t --threads $th -o "$TMP/a.wvc" >/dev/null || exit 1
        OMP_NUM_THREADS=$th "$BASE" compress "$TMP/v.raw" --dims ${N}x${N}x${N} --wavelet $fam --psnr $t --threads $th -o "$TMP/b.wvc" >/dev/null || exit 1
        "$W" decompress "$TMP/a.wvc" -o "$TMP/a.raw" >/dev/null || exit 1
        "$BASE" decompress "$TMP/a.wvc" -o "$TMP/b.raw" >/dev/null || exit 1
        n=$((n + 1))
        if cmp -s "$TMP/a.wvc" "$TMP/b.wvc" && cmp -s "$TMP/a.raw" "$TMP/b.raw"; then
          echo "same   $kind $fam ${t} dB threads $th ($(stat -c %s "$TMP/a.wvc") bytes)"
        else
          echo "DIFFER $kind $fam ${t} dB threads $th"
          bad=$((bad + 1))
        fi
      done
    done
  done
done
echo "$((n - bad)) of $n cases: identical files and decoded volumes"
[ "$bad" -eq 0 ]
