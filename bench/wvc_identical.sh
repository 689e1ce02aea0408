#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Byte-for-byte comparison of this tree's `wvol compress` / `wvol decompress` with another
# program's (e.g. main's build) on the speed benchmark's volumes: the noisy skull and the
# turbulence field, four wavelet families, 40, 50 and 60 dB, one thread and two; the whole
# volume decoded and two region reads (--roi) of each file. A change
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
        # region reads (the brick synthesis and the chunk gather): a box of odd bounds, and
        # whole x rows (the x pass then synthesises full periodic rows)
        roi1="3,5,7,$((N - 9)),$((N / 2 + 3)),$((N / 2 + 11))" roi2="0,$((N / 4)),$((N / 3)),$N,$((N / 2)),$((N / 2 + 5))"
        "$W" decompress "$TMP/a.wvc" --roi "$roi1" -o "$TMP/a1.raw" >/dev/null || exit 1
        "$BASE" decompress "$TMP/a.wvc" --roi "$roi1" -o "$TMP/b1.raw" >/dev/null || exit 1
        "$W" decompress "$TMP/a.wvc" --roi "$roi2" -o "$TMP/a2.raw" >/dev/null || exit 1
        "$BASE" decompress "$TMP/a.wvc" --roi "$roi2" -o "$TMP/b2.raw" >/dev/null || exit 1
        n=$((n + 1))
        if cmp -s "$TMP/a.wvc" "$TMP/b.wvc" && cmp -s "$TMP/a.raw" "$TMP/b.raw" && cmp -s "$TMP/a1.raw" "$TMP/b1.raw" &&
          cmp -s "$TMP/a2.raw" "$TMP/b2.raw"; then
          echo "same   $kind $fam ${t} dB threads $th ($(stat -c %s "$TMP/a.wvc") bytes)"
        else
          echo "DIFFER $kind $fam ${t} dB threads $th"
          bad=$((bad + 1))
        fi
      done
    done
  done
done
echo "$((n - bad)) of $n cases: identical files, decoded volumes and regions"
[ "$bad" -eq 0 ]
