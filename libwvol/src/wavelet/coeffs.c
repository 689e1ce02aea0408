/* SPDX-License-Identifier: MIT */
/* Coefficient pyramids: forward/inverse transforms of volumes (padding and cropping),
 * the Mallat-layout accessor, create/clone/destroy. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/finite.h"
#include "wavelet/wavelet_internal.h"

int wvol_dwt_max_levels(size_t nx, size_t ny, size_t nz)
{
    size_t n[3] = {nx, ny, nz}, lo = 0;
    int m = 0;
    for (int a = 0; a < 3; a++)
        if (n[a] > 1 && (lo == 0 || n[a] < lo)) lo = n[a];
    /* 2^M <= the shortest transformed axis: the padding never more than doubles it */
    while (lo >= ((size_t)2 << m) && m < 30) m++;
    return m;
}

size_t wvol_dwt_padded_size(size_t n, int levels)
{
    size_t q;
    if (n <= 1 || levels < 1 || levels > 30) return n;
    q = (size_t)1 << levels;
    return (n + q - 1) / q * q;
}

static wvol_status check_levels(const wvol_filter *f, int levels, size_t nx, size_t ny, size_t nz,
                                wvol_error *err)
{
    int mx = wvol_dwt_max_levels(nx, ny, nz);
    WVOL_RETURN_IF(!f || !f->h, err, WVOL_ERR_ARG, "wavelet transform: filter is NULL");
    WVOL_RETURN_IF(nx == 0 || ny == 0 || nz == 0, err, WVOL_ERR_DIMS,
                   "wavelet transform: empty volume %zu x %zu x %zu", nx, ny, nz);
    WVOL_RETURN_IF(mx == 0, err, WVOL_ERR_DIMS, "wavelet transform: a 1 x 1 x 1 volume has no levels");
    WVOL_RETURN_IF(levels < 1 || levels > mx, err, WVOL_ERR_ARG,
                   "wavelet transform: levels = %d for a %zu x %zu x %zu volume (1..%d)", levels, nx, ny,
                   nz, mx);
    return WVOL_OK;
}

wvol_status wvol_coeffs_create(wvol_coeffs **out, const wvol_filter *f, int levels, size_t nx, size_t ny,
                               size_t nz, wvol_error *err)
{
    wvol_coeffs *c;
    size_t count;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_coeffs_create: out is NULL");
    *out = NULL;
    WVOL_FORWARD(check_levels(f, levels, nx, ny, nz, err));
    c = calloc(1, sizeof *c);
    WVOL_RETURN_IF(!c, err, WVOL_ERR_NOMEM, "wvol_coeffs_create: out of memory");
    c->filter = f;
    c->levels = levels;
    c->nx = nx, c->ny = ny, c->nz = nz;
    c->px = wvol_dwt_padded_size(nx, levels);
    c->py = wvol_dwt_padded_size(ny, levels);
    c->pz = wvol_dwt_padded_size(nz, levels);
    for (int a = 0; a < 3; a++) c->spacing[a] = 1.0, c->origin[a] = 0.0;
    if (!wvol_size_mul3(c->px, c->py, c->pz, sizeof(float), &count) || c->px < nx || c->py < ny ||
        c->pz < nz || !(c->data = wvol__calloc_large(count / sizeof(float), sizeof(float)))) {
        free(c);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wavelet coefficients for %zu x %zu x %zu: out of memory",
                              nx, ny, nz);
    }
    *out = c;
    return WVOL_OK;
}

void wvol_coeffs_destroy(wvol_coeffs *c)
{
    if (!c) return;
    free(c->data);
    free(c);
}

wvol_status wvol_coeffs_clone(wvol_coeffs **out, const wvol_coeffs *c, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_coeffs_clone: out is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!c || !c->data, err, WVOL_ERR_ARG, "wvol_coeffs_clone: coefficients are NULL");
    WVOL_FORWARD(wvol_coeffs_create(out, c->filter, c->levels, c->nx, c->ny, c->nz, err));
    memcpy((*out)->data, c->data, c->px * c->py * c->pz * sizeof(float));
    memcpy((*out)->spacing, c->spacing, sizeof c->spacing);
    memcpy((*out)->origin, c->origin, sizeof c->origin);
    return WVOL_OK;
}

/* The padded grid filled from v: (i, j, k) beyond the volume take the pad rule's value. */
#define PAD_FILL(T)                                                                          \
    static void pad_fill_##T(T *dst, const wvol_coeffs *c, const wvol_volume *v, wvol_pad_mode pad) \
    {                                                                                        \
        long long planes = (long long)c->pz;                                                 \
        _Pragma("omp parallel for schedule(static) if (c->px * c->py * c->pz > 65536)")        \
        for (long long kk = 0; kk < planes; kk++) {                                          \
            size_t k = (size_t)kk, sk, sj;                                                   \
            int zero_k = k >= v->nz && pad == WVOL_PAD_ZERO;                                 \
            sk = k < v->nz ? k : pad == WVOL_PAD_PERIODIC ? k % v->nz : v->nz - 1;           \
            for (size_t j = 0; j < c->py; j++) {                                             \
                T *row = dst + c->px * (j + c->py * k);                                      \
                int zero = zero_k || (j >= v->ny && pad == WVOL_PAD_ZERO);                   \
                const float *src;                                                            \
                sj = j < v->ny ? j : pad == WVOL_PAD_PERIODIC ? j % v->ny : v->ny - 1;       \
                src = v->data + v->nx * (sj + v->ny * sk);                                   \
                for (size_t i = 0; i < v->nx; i++) row[i] = zero ? 0 : (T)src[i];            \
                for (size_t i = v->nx; i < c->px; i++)                                       \
                    row[i] = (zero || pad == WVOL_PAD_ZERO) ? 0                              \
                             : (T)src[pad == WVOL_PAD_PERIODIC ? i % v->nx : v->nx - 1];     \
            }                                                                                \
        }                                                                                    \
    }
PAD_FILL(float)
PAD_FILL(double)

wvol_status wvol_dwt3_ex(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                         wvol_pad_mode pad, int use_f64, wvol_error *err)
{
    wvol_coeffs *c;
    wvol_status st;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_dwt3: out is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "wvol_dwt3: volume is NULL");
    WVOL_RETURN_IF(pad != WVOL_PAD_EDGE && pad != WVOL_PAD_ZERO && pad != WVOL_PAD_PERIODIC, err,
                   WVOL_ERR_ARG, "wvol_dwt3: unknown pad mode %d", (int)pad);
    WVOL_FORWARD(check_levels(f, levels, v->nx, v->ny, v->nz, err));
    WVOL_FORWARD(wvol__geometry_check(v->spacing, v->origin, err));
    WVOL_FORWARD(wvol_check_finite(v->data, v->nx, v->ny, v->nz, "wavelet transform input", err));
    WVOL_FORWARD(wvol_coeffs_create(&c, f, levels, v->nx, v->ny, v->nz, err));
    memcpy(c->spacing, v->spacing, sizeof c->spacing);
    memcpy(c->origin, v->origin, sizeof c->origin);
    if (use_f64) {
        size_t n = c->px * c->py * c->pz;
        double *d = malloc(n * sizeof *d);
        if (!d) {
            wvol_coeffs_destroy(c);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "wvol_dwt3: no memory for %zu doubles", n);
        }
        pad_fill_double(d, c, v, pad);
        st = wvol_dwt3_inplace_f64(d, c->px, c->py, c->pz, f, levels, err);
        for (size_t i = 0; i < n; i++) c->data[i] = (float)d[i];
        free(d);
    } else {
        pad_fill_float(c->data, c, v, pad);
        st = wvol__dwt3_inplace_f32_finite(c->data, c->px, c->py, c->pz, f, levels, err);
    }
    /* the low-pass gains 2^(3/2) per level: inputs near FLT_MAX overflow float32 */
    if (st == WVOL_OK &&
        wvol_check_finite(c->data, c->px, c->py, c->pz, "wavelet coefficients", NULL) != WVOL_OK)
        st = wvol_error_set(err, WVOL_ERR_NONFINITE,
                            "wvol_dwt3: coefficients overflow float32 (the low-pass grows by 2^1.5 per "
                            "level; input magnitudes must stay below about FLT_MAX / 2^(1.5 * %d))",
                            levels);
    if (st != WVOL_OK) {
        wvol_coeffs_destroy(c);
        return st;
    }
    *out = c;
    return WVOL_OK;
}

wvol_status wvol_dwt3_pad(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                          wvol_pad_mode pad, wvol_error *err)
{
    return wvol_dwt3_ex(out, v, f, levels, pad, 0, err);
}

wvol_status wvol_dwt3(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                      wvol_error *err)
{
    return wvol_dwt3_ex(out, v, f, levels, WVOL_PAD_EDGE, 0, err);
}

wvol_status wvol__coeffs_check(const wvol_coeffs *c, wvol_error *err)
{
    WVOL_RETURN_IF(!c || !c->data, err, WVOL_ERR_ARG, "wavelet coefficients are NULL");
    WVOL_FORWARD(check_levels(c->filter, c->levels, c->nx, c->ny, c->nz, err));
    WVOL_RETURN_IF(c->px != wvol_dwt_padded_size(c->nx, c->levels) ||
                       c->py != wvol_dwt_padded_size(c->ny, c->levels) ||
                       c->pz != wvol_dwt_padded_size(c->nz, c->levels),
                   err, WVOL_ERR_DIMS, "wavelet coefficients: padded size %zu x %zu x %zu does not match %zu x %zu x %zu at %d levels",
                   c->px, c->py, c->pz, c->nx, c->ny, c->nz, c->levels);
    return WVOL_OK;
}

wvol_status wvol_idwt3_ex(wvol_volume **out, const wvol_coeffs *c, int use_f64, wvol_error *err)
{
    wvol_volume *v;
    size_t n;
    wvol_status st;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_idwt3: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__coeffs_check(c, err));
    n = c->px * c->py * c->pz;
    WVOL_FORWARD(wvol_volume_create(&v, c->nx, c->ny, c->nz, err));
    memcpy(v->spacing, c->spacing, sizeof v->spacing);
    memcpy(v->origin, c->origin, sizeof v->origin);
    if (use_f64) {
        double *d = malloc(n * sizeof *d);
        st = WVOL_ERR_NOMEM;
        if (d) {
            for (size_t i = 0; i < n; i++) d[i] = c->data[i];
            st = wvol_idwt3_inplace_f64(d, c->px, c->py, c->pz, c->filter, c->levels, err);
            if (st == WVOL_OK)
                for (size_t k = 0; k < c->nz; k++)
                    for (size_t j = 0; j < c->ny; j++)
                        for (size_t i = 0; i < c->nx; i++)
                            v->data[i + c->nx * (j + c->ny * k)] = (float)d[i + c->px * (j + c->py * k)];
            free(d);
        } else {
            wvol_error_set(err, st, "wvol_idwt3: no memory for %zu doubles", n);
        }
    } else {
        float *d = (c->px == c->nx && c->py == c->ny && c->pz == c->nz) ? v->data : wvol__malloc_large(n * sizeof *d);
        st = WVOL_ERR_NOMEM;
        if (d) {
            memcpy(d, c->data, n * sizeof *d);
            st = wvol_idwt3_inplace_f32(d, c->px, c->py, c->pz, c->filter, c->levels, err);
            if (st == WVOL_OK && d != v->data)
                for (size_t k = 0; k < c->nz; k++)
                    for (size_t j = 0; j < c->ny; j++)
                        memcpy(v->data + c->nx * (j + c->ny * k), d + c->px * (j + c->py * k),
                               c->nx * sizeof(float));
            if (d != v->data) free(d);
        } else {
            wvol_error_set(err, st, "wvol_idwt3: no memory for %zu floats", n);
        }
    }
    if (st == WVOL_OK && wvol_check_finite(v->data, v->nx, v->ny, v->nz, "reconstruction", NULL) != WVOL_OK)
        st = wvol_error_set(err, WVOL_ERR_NONFINITE, "wvol_idwt3: the reconstruction overflows float32");
    if (st != WVOL_OK) {
        wvol_volume_destroy(v);
        return st;
    }
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_idwt3_consume(wvol_volume **out, wvol_coeffs **cp, wvol_error *err)
{
    wvol_coeffs *c = cp ? *cp : NULL;
    wvol_volume *v = NULL;
    wvol_status st;
    WVOL_RETURN_IF(!out || !cp, err, WVOL_ERR_ARG, "wvol_idwt3_consume: NULL argument");
    *out = NULL;
    *cp = NULL;
    st = wvol__coeffs_check(c, err);
    if (st == WVOL_OK)
        st = wvol_idwt3_inplace_f32(c->data, c->px, c->py, c->pz, c->filter, c->levels, err);
    if (st == WVOL_OK) {
        /* crop in place: every row moves to an index at or below its own, so front to back */
        if (c->px != c->nx || c->py != c->ny || c->pz != c->nz)
            for (size_t k = 0; k < c->nz; k++)
                for (size_t j = 0; j < c->ny; j++)
                    memmove(c->data + c->nx * (j + c->ny * k), c->data + c->px * (j + c->py * k),
                            c->nx * sizeof(float));
        st = wvol_volume_wrap(&v, c->data, c->nx, c->ny, c->nz, err);
    }
    if (st == WVOL_OK) {
        v->owns = 1;
        c->data = NULL;
        memcpy(v->spacing, c->spacing, sizeof v->spacing);
        memcpy(v->origin, c->origin, sizeof v->origin);
        if (wvol_check_finite(v->data, v->nx, v->ny, v->nz, "reconstruction", NULL) != WVOL_OK)
            st = wvol_error_set(err, WVOL_ERR_NONFINITE, "wvol_idwt3: the reconstruction overflows float32");
    }
    wvol_coeffs_destroy(c);
    if (st != WVOL_OK) {
        wvol_volume_destroy(v);
        return st;
    }
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_idwt3(wvol_volume **out, const wvol_coeffs *c, wvol_error *err)
{
    return wvol_idwt3_ex(out, c, 0, err);
}

size_t wvol_coeffs_index(const wvol_coeffs *c, int level, int band, size_t p, size_t q, size_t r)
{
    size_t pos[3] = {p, q, r}, pad[3], at[3];
    if (!c || level < 1 || level > c->levels || band < 0 || band > 7) return SIZE_MAX;
    if (band == 0 && level != c->levels) return SIZE_MAX;
    pad[0] = c->px, pad[1] = c->py, pad[2] = c->pz;
    for (int a = 0; a < 3; a++) {
        size_t e = wvol__extent(pad[a], level);
        int hi = (band >> a) & 1;
        if (hi && pad[a] == 1) return SIZE_MAX;
        if (pos[a] >= e) return SIZE_MAX;
        at[a] = (hi ? e : 0) + pos[a];
    }
    return at[0] + c->px * (at[1] + c->py * at[2]);
}

void wvol_coeffs_locate(const wvol_coeffs *c, size_t index, int *level, int *band, size_t *p, size_t *q,
                        size_t *r)
{
    size_t at[3], pad[3], pos[3];
    int m, l = 0, lev;
    if (level) *level = 0;
    if (!c || index >= c->px * c->py * c->pz) return;
    pad[0] = c->px, pad[1] = c->py, pad[2] = c->pz;
    at[0] = index % c->px, at[1] = (index / c->px) % c->py, at[2] = index / (c->px * c->py);
    /* the deepest level whose low-pass cube still holds the point */
    for (m = 0; m < c->levels; m++) {
        int inside = 1;
        for (int a = 0; a < 3; a++)
            if (at[a] >= wvol__extent(pad[a], m + 1)) inside = 0;
        if (!inside) break;
    }
    lev = m == c->levels ? c->levels : m + 1;
    for (int a = 0; a < 3; a++) {
        size_t e = wvol__extent(pad[a], lev);
        pos[a] = at[a];
        if (m < c->levels && at[a] >= e) {
            l |= 1 << a;
            pos[a] -= e;
        }
    }
    if (level) *level = lev;
    if (band) *band = l;
    if (p) *p = pos[0];
    if (q) *q = pos[1];
    if (r) *r = pos[2];
}
