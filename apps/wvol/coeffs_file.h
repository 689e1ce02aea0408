/* SPDX-License-Identifier: MIT */
/* The command line's coefficient files: OUT.raw holds the Mallat-layout pyramid as
 * float32 little-endian (px*py*pz values, x fastest) and OUT.json beside it says what
 * it is (docs/wavelets.md, "Coefficient files"). */
#ifndef WVOL_APP_COEFFS_FILE_H
#define WVOL_APP_COEFFS_FILE_H

#include "wvol/wavelet.h"

/* "a/b.raw" -> "a/b.json" (any other name gets ".json" appended); malloc'ed. */
char *coeffs_sidecar_path(const char *raw_path);

/* Writes both files atomically. pad and precision are recorded for the reader. */
wvol_status coeffs_file_write(const wvol_coeffs *c, const char *raw_path, const char *pad,
                              const char *precision, wvol_error *err);

/* Reads a pair written by coeffs_file_write. */
wvol_status coeffs_file_read(wvol_coeffs **out, const char *raw_path, wvol_error *err);

#endif
