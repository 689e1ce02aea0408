#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The same .wvc bytes and the same decoded values whatever CPU level the library's kernels run
# at (docs/wvc-format.md, "The same bytes on every CPU"). Usage: test_same_bytes.sh WVOL_A WVOL_B,
# two builds of the program: scripts/test.sh passes the release build, whose hot loops are
# function clones picked at load time (x86-64-v3 on a CPU with AVX2 and FMA), and the sanitizer
# build, which has no clones (baseline x86-64 code, no fused multiply-adds). Each compresses
# and decompresses the same volumes (three phantoms, every candidate filter, low and high
# PSNR, the streamed, in-memory, compact-coder and version-1 paths, region and level reads);
# any byte that differs fails. On a CPU without AVX2 both builds run baseline code and the
# check passes trivially.
set -euo pipefail
A=$1
B=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail=0
same() { # what, file a, file b
  if ! cmp -s "$2" "$3"; then
    echo "test_same_bytes: $1: the two builds' outputs differ ($(cmp "$2" "$3" 2>&1 | head -1))" >&2
    fail=1
  fi
}
"$A" synth skull --size 48 --noise 20 -o "$T/skull.nrrd" > /dev/null
"$A" synth turbulence --size 40 -o "$T/turbulence.nrrd" > /dev/null
"$A" synth shepp-logan --size 36 -o "$T/shepp.nrrd" > /dev/null
n=0
for v in skull turbulence shepp; do
  for w in auto haar db2 db4 coif2 bl3; do
    for p in 40 60; do
      for extra in "" "--in-memory" "--coder compact" "--format 1"; do
        what="$v $w ${p} dB ${extra:-default}"
        # shellcheck disable=SC2086
        "$A" compress "$T/$v.nrrd" -o "$T/a.wvc" --wavelet "$w" --psnr "$p" $extra > /dev/null
        # shellcheck disable=SC2086
        "$B" compress "$T/$v.nrrd" -o "$T/b.wvc" --wavelet "$w" --psnr "$p" $extra > /dev/null
        same "compress $what" "$T/a.wvc" "$T/b.wvc"
        "$A" decompress "$T/a.wvc" -o "$T/a.raw" > /dev/null
        "$B" decompress "$T/a.wvc" -o "$T/b.raw" > /dev/null
        same "decompress $what" "$T/a.raw" "$T/b.raw"
        n=$((n + 1))
      done
    done
  done
  "$A" compress "$T/$v.nrrd" -o "$T/a.wvc" --psnr 50 > /dev/null
  for read in "--roi 3,5,7,30,31,33" "--level 1" "--level 2 --roi 0,0,0,24,24,24"; do
    # shellcheck disable=SC2086
    "$A" decompress "$T/a.wvc" -o "$T/a.raw" $read > /dev/null
    # shellcheck disable=SC2086
    "$B" decompress "$T/a.wvc" -o "$T/b.raw" $read > /dev/null
    same "decompress $v $read" "$T/a.raw" "$T/b.raw"
  done
done
[ "$fail" = 0 ] || exit 1
echo "test_same_bytes: $n compressions and their decodes, and region and level reads: the same bytes from both builds"
