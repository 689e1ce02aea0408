/* SPDX-License-Identifier: MIT */
#include "core/alloc.h"
#include "core/clones.h"
#include "core/finite.h"
#include "core/status_internal.h"
#include "wvol/volume.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

int wvol_size_mul3(size_t a, size_t b, size_t c, size_t elem, size_t *out)
{
    size_t r = a;
    if (!out) return 0;
    if (b && r > SIZE_MAX / b) return 0;
    r *= b;
    if (c && r > SIZE_MAX / c) return 0;
    r *= c;
    if (elem && r > SIZE_MAX / elem) return 0;
    r *= elem;
    *out = r;
    return 1;
}

static wvol_status volume_new(wvol_volume **out, size_t nx, size_t ny, size_t nz, wvol_error *err)
{
    size_t bytes;
    wvol_volume *v;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "volume: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(nx == 0 || ny == 0 || nz == 0, err, WVOL_ERR_DIMS,
                   "volume dimensions %zux%zux%zu: every dimension must be at least 1", nx, ny, nz);
    WVOL_RETURN_IF(!wvol_size_mul3(nx, ny, nz, sizeof(float), &bytes) || bytes > (SIZE_MAX >> 1),
                   err, WVOL_ERR_DIMS, "volume dimensions %zux%zux%zu overflow the address space",
                   nx, ny, nz);
    v = calloc(1, sizeof *v);
    WVOL_RETURN_IF(!v, err, WVOL_ERR_NOMEM, "volume: out of memory");
    v->nx = nx;
    v->ny = ny;
    v->nz = nz;
    v->spacing[0] = v->spacing[1] = v->spacing[2] = 1.0;
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_volume_create(wvol_volume **out, size_t nx, size_t ny, size_t nz, wvol_error *err)
{
    wvol_volume *v;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "volume_create: output pointer is NULL");
    WVOL_FORWARD(volume_new(&v, nx, ny, nz, err));
    v->data = wvol__calloc_large(nx * ny * nz, sizeof(float));
    if (!v->data) {
        free(v);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "volume %zux%zux%zu: out of memory (%zu bytes)",
                              nx, ny, nz, nx * ny * nz * sizeof(float));
    }
    v->owns = 1;
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_volume_wrap(wvol_volume **out, float *data, size_t nx, size_t ny, size_t nz,
                             wvol_error *err)
{
    wvol_volume *v;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "volume_wrap: output pointer is NULL");
    WVOL_RETURN_IF(!data, err, WVOL_ERR_ARG, "volume_wrap: data pointer is NULL");
    WVOL_FORWARD(volume_new(&v, nx, ny, nz, err));
    v->data = data;
    v->owns = 0;
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_volume_clone(wvol_volume **out, const wvol_volume *v, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "volume_clone: output pointer is NULL");
    WVOL_RETURN_IF(!v, err, WVOL_ERR_ARG, "volume_clone: input is NULL");
    WVOL_RETURN_IF(!v->data, err, WVOL_ERR_ARG, "volume_clone: input has no data");
    WVOL_FORWARD(wvol_volume_create(out, v->nx, v->ny, v->nz, err));
    memcpy((*out)->data, v->data, wvol_volume_count(v) * sizeof(float));
    memcpy((*out)->spacing, v->spacing, sizeof v->spacing);
    memcpy((*out)->origin, v->origin, sizeof v->origin);
    return WVOL_OK;
}

void wvol_volume_destroy(wvol_volume *v)
{
    if (!v) return;
    if (v->owns) free(v->data);
    free(v);
}

size_t wvol_volume_count(const wvol_volume *v)
{
    return v ? v->nx * v->ny * v->nz : 0;
}

wvol_status wvol__geometry_check(const double spacing[3], const double origin[3], wvol_error *err)
{
    for (int a = 0; a < 3; a++) {
        if (spacing) {
            WVOL_RETURN_IF(!(spacing[a] > 0) || !isfinite(spacing[a]), err, WVOL_ERR_ARG,
                           "spacing[%d] = %g: spacing must be finite and positive", a, spacing[a]);
        }
        if (origin) {
            WVOL_RETURN_IF(!isfinite(origin[a]), err, WVOL_ERR_ARG,
                           "origin[%d] = %g: origin must be finite", a, origin[a]);
        }
    }
    return WVOL_OK;
}

wvol_status wvol_volume_set_geometry(wvol_volume *v, const double spacing[3], const double origin[3],
                                     wvol_error *err)
{
    WVOL_RETURN_IF(!v, err, WVOL_ERR_ARG, "volume is NULL");
    WVOL_FORWARD(wvol__geometry_check(spacing, origin, err));
    if (spacing) memcpy(v->spacing, spacing, sizeof v->spacing);
    if (origin) memcpy(v->origin, origin, sizeof v->origin);
    return WVOL_OK;
}

/* A float is NaN or Inf exactly when its exponent bits are all ones: tested without an
 * early exit, which the compiler vectorises (the exit-on-first-hit loop stays scalar). */
WVOL__CLONES int wvol__all_finite(const float *d, size_t n)
{
    uint32_t bad = 0;
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, d + i, sizeof u);
        bad |= (uint32_t)((u & 0x7F800000u) == 0x7F800000u);
    }
    return !bad;
}

/* The first block of 1024 of data[0..n) that is not all finite (the tail from the last
 * whole block on when all are); only that block is searched value by value. */
static size_t first_nonfinite_block(const float *data, size_t n)
{
    enum { BLOCK = 1024 };
    size_t b;
    for (b = 0; b + BLOCK <= n; b += BLOCK)
        if (!wvol__all_finite(data + b, BLOCK)) return b;
    return b;
}

/* The threads a scan of n values takes: all of OpenMP's from 1 Mi values (a volume or a
 * slab after a parallel read, transform or decode, which one thread would scan while the
 * others wait), one below that or inside a parallel region. */
static int scan_threads(size_t n)
{
#ifdef _OPENMP
    if (n >= ((size_t)1 << 20) && !omp_in_parallel()) return omp_get_max_threads();
#endif
    (void)n;
    return 1;
}

/* The same on the threads (scan_threads): contiguous parts of whole blocks, and the
 * earliest part's first block that is not all finite, so the same block as the serial
 * search (and the same voxel named). */
static size_t first_nonfinite_block_threads(const float *data, size_t n)
{
    enum { BLOCK = 1024 };
    const int threads = scan_threads(n);
    size_t part, first = n;
    if (threads < 2) return first_nonfinite_block(data, n);
    part = (n / (size_t)threads + BLOCK - 1) / BLOCK * BLOCK;
#pragma omp parallel for schedule(static, 1) num_threads(threads) reduction(min : first)
    for (int t = 0; t < threads; t++) {
        size_t a = (size_t)t * part, b = a + part < n ? a + part : n, r;
        if (a >= n) continue;
        r = a + first_nonfinite_block(data + a, b - a);
        /* a part's tail (only the last part has one) is searched by the caller */
        if (r < b) first = r < first ? r : first;
    }
    if (first == n) first = n / BLOCK * BLOCK; /* all whole blocks finite: the tail */
    return first;
}

wvol_status wvol_check_finite(const float *data, size_t nx, size_t ny, size_t nz, const char *what,
                              wvol_error *err)
{
    size_t n, idx;
    WVOL_RETURN_IF(!wvol_size_mul3(nx, ny, nz, 1, &n), err, WVOL_ERR_ARG, "%s: dimensions %zux%zux%zu overflow",
                   what ? what : "input", nx, ny, nz);
    WVOL_RETURN_IF(!data && n, err, WVOL_ERR_ARG, "%s: no samples (NULL)", what ? what : "input");
    for (idx = first_nonfinite_block_threads(data, n); idx < n; idx++) {
        if (!isfinite(data[idx])) {
            size_t i = idx % nx, j = (idx / nx) % ny, k = idx / (nx * ny);
            return wvol_error_set(err, WVOL_ERR_NONFINITE,
                                  "%s: %s at voxel (i=%zu, j=%zu, k=%zu); NaN and Inf are refused",
                                  what ? what : "input", isnan(data[idx]) ? "NaN" : "Inf", i, j, k);
        }
    }
    return WVOL_OK;
}

/* Eight lanes of a running minimum, maximum and exponent test (explicit vectors: GCC
 * leaves a scalar float min/max reduction scalar without -ffast-math), in four independent
 * accumulators: one would make every group of eight wait on the previous one's compare and
 * blend. Which zero a zero extreme comes out as depends on the order; callers store it as +0. */
typedef float fr_v8f __attribute__((vector_size(32)));
typedef int32_t fr_v8i __attribute__((vector_size(32)));

static inline __attribute__((always_inline)) void fr_step(const float *d, fr_v8f *lo, fr_v8f *hi, fr_v8i *bad)
{
    const fr_v8i expo = {0x7F800000, 0x7F800000, 0x7F800000, 0x7F800000,
                         0x7F800000, 0x7F800000, 0x7F800000, 0x7F800000};
    fr_v8f v;
    fr_v8i mlo, mhi;
    memcpy(&v, d, sizeof v);
    *bad |= ((fr_v8i)v & expo) == expo;
    mlo = v < *lo;
    mhi = v > *hi;
    *lo = (fr_v8f)(((fr_v8i)v & mlo) | ((fr_v8i)*lo & ~mlo));
    *hi = (fr_v8f)(((fr_v8i)v & mhi) | ((fr_v8i)*hi & ~mhi));
}

WVOL__CLONES static int finite_range_serial(const float *d, size_t n, float range[2])
{
    fr_v8f lo[4], hi[4];
    fr_v8i bad = {0, 0, 0, 0, 0, 0, 0, 0};
    float l = INFINITY, h = -INFINITY;
    uint32_t b = 0;
    size_t i = 0;
    for (int a = 0; a < 4; a++)
        for (int k = 0; k < 8; k++) lo[a][k] = INFINITY, hi[a][k] = -INFINITY;
    for (; i + 32 <= n; i += 32)
        for (int a = 0; a < 4; a++) fr_step(d + i + 8 * a, &lo[a], &hi[a], &bad);
    for (; i + 8 <= n; i += 8) fr_step(d + i, &lo[0], &hi[0], &bad);
    for (int a = 0; a < 4; a++)
        for (int k = 0; k < 8; k++) {
            l = lo[a][k] < l ? lo[a][k] : l;
            h = hi[a][k] > h ? hi[a][k] : h;
        }
    for (int k = 0; k < 8; k++) b |= (uint32_t)bad[k];
    for (; i < n; i++) {
        uint32_t u;
        memcpy(&u, d + i, sizeof u);
        b |= (uint32_t)((u & 0x7F800000u) == 0x7F800000u);
        l = d[i] < l ? d[i] : l;
        h = d[i] > h ? d[i] : h;
    }
    range[0] = l;
    range[1] = h;
    return !b;
}

int wvol__finite_range(const float *d, size_t n, float range[2])
{
    const int threads = scan_threads(n);
    int finite = 1;
    float lo = INFINITY, hi = -INFINITY;
    if (threads < 2) return finite_range_serial(d, n, range);
    /* a min and a max: the same whatever the split (but for which zero a zero extreme is) */
#pragma omp parallel for schedule(static, 1) num_threads(threads) reduction(& : finite) reduction(min : lo) \
    reduction(max : hi)
    for (int t = 0; t < threads; t++) {
        size_t a = n / (size_t)threads * (size_t)t, b = t + 1 == threads ? n : a + n / (size_t)threads;
        float r[2];
        finite &= finite_range_serial(d + a, b - a, r);
        lo = r[0] < lo ? r[0] : lo;
        hi = r[1] > hi ? r[1] : hi;
    }
    range[0] = lo, range[1] = hi;
    return finite;
}

void wvol_volume_range(const wvol_volume *v, double *vmin, double *vmax, double *mean)
{
    size_t n = wvol_volume_count(v), i;
    double lo = 0, hi = 0, sum = 0;
    if (n) {
        lo = hi = v->data[0];
        for (i = 0; i < n; i++) {
            double x = v->data[i];
            if (x < lo) lo = x;
            if (x > hi) hi = x;
            sum += x;
        }
        sum /= (double)n;
    }
    if (vmin) *vmin = lo;
    if (vmax) *vmax = hi;
    if (mean) *mean = sum;
}
