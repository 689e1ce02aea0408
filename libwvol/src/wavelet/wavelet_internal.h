/* SPDX-License-Identifier: MIT */
/* Internal declarations shared by the wavelet sources (not installed). */
#ifndef WVOL_WAVELET_INTERNAL_H
#define WVOL_WAVELET_INTERNAL_H

#include <stddef.h>
#include "wvol/wavelet.h"
#include "core/status_internal.h"
#include "wavelet/wavelet_bricks.h"

/* Longest filter the engine handles (bl3 truncated at 1e-10 is well under this). */
#define WVOL__MAX_TAPS 256

/* Battle-Lemarie filter of spline order `order` (3 = cubic) from its Fourier form,
 * centred (h[K] is the centre tap), truncated where |h| < tol and renormalised to
 * sum sqrt(2), then one zero tap appended (the length must be even for the QMF pair).
 * Writes *len <= cap taps; returns 0 on success, -1 if unsupported or longer than cap. */
int wvol__bl_compute(int order, double tol, double *h, int cap, int *len);

/* Defect max_k |sum_n h[n] h[n+2k] - delta_k| of a low-pass filter. */
double wvol__filter_defect(const double *h, int length);

/* Plan of an in-place multi-level transform: validated sizes, scratch per thread. */
typedef struct dwt_plan {
    int L;           /* taps */
    int threads;     /* scratch slots (omp_get_max_threads at plan time) */
    size_t scratch;  /* values of scratch per thread */
} dwt_plan;

/* Validates an in-place transform request (n[a] == 1 or a multiple of 2^levels) and
 * sizes the scratch. */
wvol_status wvol__dwt_plan(dwt_plan *pl, const void *data, const size_t n[3], const wvol_filter *f,
                           int levels, size_t elem, wvol_error *err);
/* Width of the column blocks of the y/z passes for a cube row length cx, n samples
 * along the axis, L taps: the block's extended copy stays within ~128 KiB. */
size_t wvol__block_width(size_t cx, size_t n, int L, size_t elem);
int wvol__thread_id(void);

/* wvol_dwt3_inplace_f32 without its test for NaN and Inf: for data already tested (the
 * padded copy of a volume wvol_dwt3 has tested), which is then read once, not twice. */
wvol_status wvol__dwt3_inplace_f32_finite(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                          int levels, wvol_error *err);

/* Inverse of levels..stop+1 only, in place: the corner cube of extent n >> stop then
 * holds the level-`stop` low-pass coefficients. */
wvol_status wvol__idwt3_partial_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                    int levels, int stop, wvol_error *err);

/* The streamed transform's kernels (float32), the same as the in-memory level's: the x
 * then y pass of one compact cx x cy slice (scratch as the plan sizes it), and the z pass
 * of rows y0 .. y1 - 1 of a cube of cz slices from the L rows 2k .. 2k + L - 1 (mod cz),
 * read in place (cz sets the column blocks, those of the in-memory z pass). */
void wvol__dwt_slice_xy_f32(float *slice, size_t cx, size_t cy, const float *h, const float *g, int L,
                            float *scratch);
/* The x then y pass of slice_xy_f32 on cx x cy slice dst made from rows of cx samples at
 * src, sstride apart, row j from src row min(j, ny - 1), without a copy first (cx >= 2;
 * bit-identical to copying the rows in and calling wvol__dwt_slice_xy_f32). */
void wvol__dwt_slice_xy_from_f32(float *dst, const float *src, size_t sstride, size_t ny, size_t cx, size_t cy,
                                 const float *h, const float *g, int L, float *scratch);
void wvol__dwt_zrows_f32(float *a, float *d, const float *const *rows, size_t cx, size_t y0, size_t y1, size_t cz,
                         const float *h, const float *g, int L);

#endif
