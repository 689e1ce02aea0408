/* SPDX-License-Identifier: MIT
 * The pipeline's own rule for a PSNR target (pipeline/compress.c), shared by the in-memory
 * and the streamed compression. Not installed. */
#ifndef WVOL_PIPELINE_COMPRESS_FLOOR_H
#define WVOL_PIPELINE_COMPRESS_FLOOR_H

#include "wvol/compress.h"
#include "wvol/wavelet.h"

/* After wvol_compress_wvc_params with a PSNR target: what float32 adds to the quantiser's exact
 * error in a decoded file, which matters for volumes far from 0 against their range (1e4 + a
 * signal of range 1.4): the decoded samples rounded to float32 at their magnitude, and the
 * coarsest low-pass coefficients (the offset times the transform's gain) rounded to float32.
 * Their sum is taken out of wp->target_sse when it is at least 1e-3 of it (below, the file is
 * the one the rule alone makes, bit for bit), and a target it leaves less than half of is
 * refused (WVOL_ERR_ARG), naming the PSNR float32 allows there (wvol__f32_floor_sse). f, levels,
 * pad: the transform's filter, levels and padded sizes. */
wvol_status wvol__compress_float_floors(wvol_wvc_params *wp, const wvol_compress_quant *q, const wvol_filter *f,
                                        int levels, const size_t pad[3], double voxels, double vmin, double vmax,
                                        wvol_error *err);

#endif
