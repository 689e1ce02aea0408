/* SPDX-License-Identifier: MIT */
/* Internal declarations shared by the wavelet sources (not installed). */
#ifndef WVOL_WAVELET_INTERNAL_H
#define WVOL_WAVELET_INTERNAL_H

#include <stddef.h>
#include "wvol/wavelet.h"
#include "core/status_internal.h"

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
/* Validates a coefficient pyramid (sizes consistent with its levels). */
wvol_status wvol__coeffs_check(const wvol_coeffs *c, wvol_error *err);

/* Inverse of levels..stop+1 only, in place: the corner cube of extent n >> stop then
 * holds the level-`stop` low-pass coefficients. */
wvol_status wvol__idwt3_partial_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                    int levels, int stop, wvol_error *err);

/* Extent of axis a at level m (0 = the padded grid): 1 stays 1. */
static inline size_t wvol__extent(size_t p, int m) { return p == 1 ? 1 : p >> m; }

/* ---- local reconstruction (partial.c) ---------------------------------------------- */

/* Where a brick reconstruction reads coefficients: gather() fills dst with band `band`
 * of level m (band 0 of level `levels` is the low-pass cube; level 0 band 0: the
 * samples themselves, for levels == 0) on the region lo .. lo + n - 1 per axis, indices
 * taken modulo the band's extent, x fastest; it returns 0 when every value there is
 * zero (dst need not be written then), which lets the synthesis skip that band. */
typedef struct wvol__coef_source {
    int (*gather)(const void *ctx, float *dst, int m, int band, const ptrdiff_t lo[3], const ptrdiff_t n[3]);
    const void *ctx;
    const wvol_filter *filter;
    int levels;
    size_t dims[3], pad[3];
} wvol__coef_source;

void wvol__coef_source_of_coeffs(wvol__coef_source *src, const wvol_coeffs *c);

/* Reusable scratch of one reconstruction (one per thread). Start zeroed. */
#define WVOL__BRICK_SCRATCH 16
typedef struct wvol__brick_scratch {
    float *buf[WVOL__BRICK_SCRATCH];
    size_t cap[WVOL__BRICK_SCRATCH];
} wvol__brick_scratch;

void wvol__brick_scratch_free(wvol__brick_scratch *s);
size_t wvol__brick_scratch_bytes(const wvol__brick_scratch *s);

/* The finest-level samples of the box [lo, hi) (lo < hi <= dims, unchecked) into out,
 * (hi - lo) sized, x fastest, synthesising only the coefficients whose support reaches
 * the box (wvol_idwt3_brick is this on a dense wvol_coeffs). */
wvol_status wvol__idwt3_brick_src(float *out, const wvol__coef_source *src, const size_t lo[3], const size_t hi[3],
                                  wvol__brick_scratch *scr, wvol_error *err);

/* ---- brick bounds (bounds.c) --------------------------------------------------------- */

/* Rigorous [vmin, vmax] of the reconstructed samples of a box, from per-(level, band)
 * block maxima of the detail coefficients and the low-pass cube. Every axis must be
 * transformed (pad >= 2). Create, fill the maxima (from dense coefficients, or with
 * _add per kept coefficient), finish, then query (concurrently). low: the low-pass
 * cube, value (x, y, z) at low[x + low_sy y + low_sz z]; it must outlive the bounds. */
typedef struct wvol__brick_bounds wvol__brick_bounds;
wvol_status wvol__bounds_create(wvol__brick_bounds **out, const wvol_filter *f, int levels, const size_t pad[3],
                                const float *low, size_t low_sy, size_t low_sz, wvol_error *err);
void wvol__bounds_fill_coeffs(wvol__brick_bounds *b, const wvol_coeffs *c);
void wvol__bounds_add(wvol__brick_bounds *b, int m, int band, size_t p, size_t q, size_t r, float value);
void wvol__bounds_finish(wvol__brick_bounds *b);
/* Bound of the samples in the box [s0, s1] (inclusive voxel indices). */
void wvol__bounds_box(const wvol__brick_bounds *b, const long s0[3], const long s1[3], double *vmin, double *vmax);
size_t wvol__bounds_bytes(const wvol__brick_bounds *b);
void wvol__bounds_free(wvol__brick_bounds *b);

#endif
