/* SPDX-License-Identifier: MIT */
/* Separable periodic 3D wavelet transform in place (non-standard / Mallat decomposition,
 * DESIGN.md section 4), float32 and float64, multi-threaded with OpenMP.
 * Based on: Mallat 1989 (pyramid algorithm); the kernels are in dwt3_impl.h. */
#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/clones.h"
#include "core/finite.h"
#include "wavelet/wavelet_internal.h"

int wvol__thread_id(void) { return omp_get_thread_num(); }

/* Columns per block of a strided-axis pass: the block's n + L rows are copied into scratch
 * and filtered there, so the scratch (rows x width) should stay in L2 beside the rows being
 * written, while each strided row read fetches several cache lines rather than one: a
 * quarter of a 1 MiB L2, and at least 48 columns (3 lines per row read), which large slices
 * (1024^2, 2048^2) would otherwise cut to 16, one line per read (measured in
 * bench/results/speed_profile.md); at 256^2 and below a block is the whole row. The width
 * only groups columns: every column is filtered with the same arithmetic whatever the
 * block. */
size_t wvol__block_width(size_t cx, size_t n, int L, size_t elem)
{
    const size_t budget = 256 * 1024;
    size_t rows = n + (size_t)L, B = budget / (elem * rows), nb;
    B = B < 48 ? 48 : B & ~(size_t)15;
    if (cx <= B) return cx;
    nb = (cx + B - 1) / B;         /* even blocks: no thin last block */
    B = (cx + nb - 1) / nb;
    return (B + 15) & ~(size_t)15;
}

wvol_status wvol__dwt_plan(dwt_plan *pl, const void *data, const size_t n[3], const wvol_filter *f,
                           int levels, size_t elem, wvol_error *err)
{
    size_t total, need = 0;
    WVOL_RETURN_IF(!data, err, WVOL_ERR_ARG, "wavelet transform: data is NULL");
    WVOL_RETURN_IF(!f || !f->h || f->length < 2 || f->length > WVOL__MAX_TAPS, err, WVOL_ERR_ARG,
                   "wavelet transform: no valid filter given");
    WVOL_RETURN_IF(levels < 1 || levels > 30, err, WVOL_ERR_ARG,
                   "wavelet transform: levels = %d (must be at least 1)", levels);
    WVOL_RETURN_IF(!wvol_size_mul3(n[0], n[1], n[2], elem, &total) || total == 0, err, WVOL_ERR_DIMS,
                   "wavelet transform: bad size %zu x %zu x %zu", n[0], n[1], n[2]);
    int transformed = 0;
    for (int a = 0; a < 3; a++) {
        if (n[a] == 1) continue;
        transformed = 1;
        WVOL_RETURN_IF(n[a] % ((size_t)1 << levels) != 0, err, WVOL_ERR_DIMS,
                       "wavelet transform: size %zu along %c is not 1 or a multiple of 2^%d = %zu", n[a],
                       "xyz"[a], levels, (size_t)1 << levels);
    }
    WVOL_RETURN_IF(!transformed, err, WVOL_ERR_DIMS, "wavelet transform: a 1 x 1 x 1 volume has no levels");
    pl->L = f->length;
    pl->threads = omp_get_max_threads();
    if (pl->threads < 1) pl->threads = 1;
    for (int m = 0; m < levels; m++) {
        size_t cx = wvol__extent(n[0], m);
        size_t x = 4 * (cx / 2 + (size_t)f->length);
        if (x > need) need = x;
        for (int a = 1; a < 3; a++) {
            size_t na = wvol__extent(n[a], m), B;
            if (na < 2) continue;
            B = wvol__block_width(cx, na, f->length, elem);
            if ((na + (size_t)f->length) * B > need) need = (na + (size_t)f->length) * B;
        }
    }
    pl->scratch = (need + 15) & ~(size_t)15; /* keeps every thread's slot 64-byte apart */
    WVOL_RETURN_IF(pl->scratch > SIZE_MAX / elem / (size_t)pl->threads, err, WVOL_ERR_NOMEM,
                   "wavelet transform: scratch size overflows");
    return WVOL_OK;
}

/* The kernels: noinline, multi-versioned (core/clones.h). */
#define WVOL__KERNEL __attribute__((noinline)) WVOL__CLONES

#define T float
#define SUF f32
#include "wavelet/dwt3_impl.h"
#undef T
#undef SUF
#define T double
#define SUF f64
#include "wavelet/dwt3_impl.h"
#undef T
#undef SUF

/* The float32 transforms with a large offset taken out (dc_offset.c): forward, the first
 * slice's offset out of every sample and, times the kernels' gain, into the low-pass band;
 * inverse, the band's offset out of it and, over the gain, into every sample. The transforms
 * are periodic on the array they are given, on which a constant goes to the low-pass band
 * alone, whatever padding made it. */
static wvol_status forward_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f, int levels,
                               wvol_error *err)
{
    const size_t n = nx * ny * nz, p[3] = {nx, ny, nz};
    const float mu = wvol__slice_offset(data, nx * ny);
    if (mu != 0.0f)
        for (size_t i = 0; i < n; i++) data[i] -= mu;
    WVOL_FORWARD(transform_f32(data, nx, ny, nz, f, levels, 0, 0, err));
    if (mu != 0.0f) wvol__lowpass_add(data, p, levels, (double)mu * wvol__dc_gain_f32(f, levels, p));
    return WVOL_OK;
}

static wvol_status inverse_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f, int levels,
                               wvol_error *err)
{
    const size_t n = nx * ny * nz, p[3] = {nx, ny, nz};
    const float mu = wvol__lowpass_offset(data, p, levels);
    double back = 0.0;
    if (mu != 0.0f) {
        wvol__lowpass_add(data, p, levels, -(double)mu); /* exact: the band lies within a factor 2 of mu */
        back = (double)mu / wvol__dc_gain_f32(f, levels, p);
    }
    WVOL_FORWARD(transform_f32(data, nx, ny, nz, f, levels, 1, 0, err));
    if (mu != 0.0f)
        for (size_t i = 0; i < n; i++) data[i] = (float)((double)data[i] + back);
    return WVOL_OK;
}

wvol_status wvol_dwt3_inplace_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                  int levels, wvol_error *err)
{
    dwt_plan pl;
    const size_t n[3] = {nx, ny, nz};
    /* the plan's checks first: data and its size are valid before the finite test reads it */
    WVOL_FORWARD(wvol__dwt_plan(&pl, data, n, f, levels, sizeof(float), err));
    WVOL_RETURN_IF(!wvol__all_finite(data, nx * ny * nz), err, WVOL_ERR_NONFINITE,
                   "wavelet transform: the input holds NaN or Inf");
    return forward_f32(data, nx, ny, nz, f, levels, err);
}

wvol_status wvol__dwt3_inplace_f32_finite(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                          int levels, wvol_error *err)
{
    return forward_f32(data, nx, ny, nz, f, levels, err);
}

wvol_status wvol_idwt3_inplace_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                   int levels, wvol_error *err)
{
    return inverse_f32(data, nx, ny, nz, f, levels, err);
}

wvol_status wvol_dwt3_inplace_f64(double *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                  int levels, wvol_error *err)
{
    return transform_f64(data, nx, ny, nz, f, levels, 0, 0, err);
}

wvol_status wvol_idwt3_inplace_f64(double *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                   int levels, wvol_error *err)
{
    return transform_f64(data, nx, ny, nz, f, levels, 1, 0, err);
}

wvol_status wvol__idwt3_partial_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                    int levels, int stop, wvol_error *err)
{
    WVOL_RETURN_IF(stop < 0 || stop > levels, err, WVOL_ERR_ARG,
                   "partial inverse: stop level %d outside 0..%d", stop, levels);
    if (stop == levels) return WVOL_OK;
    {
        /* the band's offset out and back into level stop's low-pass last, as inverse_f32 does */
        const size_t p[3] = {nx, ny, nz};
        const float mu = wvol__lowpass_offset(data, p, levels);
        if (mu != 0.0f) wvol__lowpass_add(data, p, levels, -(double)mu);
        WVOL_FORWARD(transform_f32(data, nx, ny, nz, f, levels, 1, stop, err));
        if (mu != 0.0f) wvol__lowpass_add(data, p, stop, (double)mu / wvol__dc_gain_f32(f, levels - stop, p));
        return WVOL_OK;
    }
}

/* ---- kernels of the streamed transform (dwt3_stream.c), float32 --------------------- */

void wvol__dwt_slice_xy_f32(float *slice, size_t cx, size_t cy, const float *h, const float *g, int L,
                            float *scratch)
{
    dwt_plan pl;
    memset(&pl, 0, sizeof pl);
    pl.L = L;
    slice_xy_f32(slice, cx, cy, cx, &pl, h, g, scratch, 0);
}

void wvol__dwt_slice_xy_from_f32(float *dst, const float *src, size_t sstride, size_t ny, size_t cx, size_t cy,
                                 const float *h, const float *g, int L, float *scratch)
{
    slice_xy_from_f32(dst, src, sstride, ny, cx, cy, L, h, g, scratch);
}

/* One level of the inverse along y then x on one z-slice (the in-place transform's own
 * kernels): the cx x cy corner of a slice of row length NX; scratch holds
 * wvol__idwt_slice_xy_scratch(cx, cy, L) floats. */
size_t wvol__idwt_slice_xy_scratch(size_t cx, size_t cy, int L)
{
    size_t need = 4 * (cx / 2 + (size_t)L);
    if (cy > 1) {
        size_t B = wvol__block_width(cx, cy, L, sizeof(float));
        if ((cy + (size_t)L) * B > need) need = (cy + (size_t)L) * B;
    }
    return (need + 15) & ~(size_t)15;
}

void wvol__idwt_slice_xy_f32(float *slice, size_t cx, size_t cy, size_t NX, const float *h, const float *g, int L,
                             float *scratch)
{
    dwt_plan pl;
    memset(&pl, 0, sizeof pl);
    pl.L = L;
    slice_xy_f32(slice, cx, cy, NX, &pl, h, g, scratch, 1);
}

void wvol__dwt_zrows_f32(float *a, float *d, const float *const *rows, size_t cx, size_t y0, size_t y1, size_t cz,
                         const float *h, const float *g, int L)
{
    zrows_f32(a, d, rows, cx, y0, y1, wvol__block_width(cx, cz, L, sizeof(float)), h, g, L);
}
