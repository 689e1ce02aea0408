/* Partial reconstruction: a coarser volume (stop at level s) and one brick of the finest
 * level from only the coefficients whose support reaches it. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "wavelet/wavelet_internal.h"

wvol_status wvol_idwt3_level(wvol_volume **out, const wvol_coeffs *c, int stop_level, wvol_error *err)
{
    size_t pad[3], dims[3], n;
    float *d;
    wvol_volume *v;
    wvol_status st;
    double scale = 1.0;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_idwt3_level: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__coeffs_check(c, err));
    WVOL_RETURN_IF(stop_level < 0 || stop_level > c->levels, err, WVOL_ERR_ARG,
                   "wvol_idwt3_level: level %d outside 0..%d", stop_level, c->levels);
    if (stop_level == 0) return wvol_idwt3(out, c, err);
    pad[0] = c->px, pad[1] = c->py, pad[2] = c->pz;
    dims[0] = c->nx, dims[1] = c->ny, dims[2] = c->nz;
    n = c->px * c->py * c->pz;
    d = malloc(n * sizeof *d);
    WVOL_RETURN_IF(!d, err, WVOL_ERR_NOMEM, "wvol_idwt3_level: no memory for %zu floats", n);
    memcpy(d, c->data, n * sizeof *d);
    st = wvol__idwt3_partial_f32(d, c->px, c->py, c->pz, c->filter, c->levels, stop_level, err);
    if (st != WVOL_OK) {
        free(d);
        return st;
    }
    size_t e[3];
    for (int a = 0; a < 3; a++) {
        size_t q = (size_t)1 << stop_level;
        e[a] = pad[a] == 1 ? 1 : (dims[a] + q - 1) / q; /* cells that touch the original grid */
        if (pad[a] > 1) scale *= pow(2.0, -0.5 * stop_level);
    }
    st = wvol_volume_create(&v, e[0], e[1], e[2], err);
    if (st != WVOL_OK) {
        free(d);
        return st;
    }
    for (size_t k = 0; k < e[2]; k++)
        for (size_t j = 0; j < e[1]; j++)
            for (size_t i = 0; i < e[0]; i++)
                v->data[i + e[0] * (j + e[1] * k)] = (float)(scale * d[i + c->px * (j + c->py * k)]);
    free(d);
    for (int a = 0; a < 3; a++) {
        double q = pad[a] == 1 ? 1.0 : ldexp(1.0, stop_level);
        v->spacing[a] = c->spacing[a] * q;
        /* a level-s scaling function covers voxels [2^s p, 2^s (p+1)) and is centred at
         * 2^s p + (2^s - 1) * centre in voxel units (DESIGN.md section 2) */
        v->origin[a] = c->origin[a] + c->spacing[a] * (q - 1.0) * c->filter->center;
    }
    *out = v;
    return WVOL_OK;
}

/* ---- bricks -------------------------------------------------------------------- */

static ptrdiff_t floor_div2(ptrdiff_t a) { return a >= 0 ? a / 2 : -((-a + 1) / 2); }

typedef struct region {
    ptrdiff_t lo[3], n[3]; /* unwrapped indices [lo, lo + n) per axis */
} region;

static size_t region_count(const region *r) { return (size_t)(r->n[0] * r->n[1] * r->n[2]); }

/* Band `band` of level m of c on region r (indices taken periodically) into dst. */
static void gather(double *dst, const wvol_coeffs *c, int m, int band, const region *r)
{
    size_t pad[3] = {c->px, c->py, c->pz}, e[3], off[3];
    for (int a = 0; a < 3; a++) {
        e[a] = wvol__extent(pad[a], m);
        off[a] = ((band >> a) & 1) ? e[a] : 0;
    }
    size_t t = 0;
    for (ptrdiff_t k = 0; k < r->n[2]; k++) {
        ptrdiff_t zk = (r->lo[2] + k) % (ptrdiff_t)e[2];
        size_t z = off[2] + (size_t)(zk < 0 ? zk + (ptrdiff_t)e[2] : zk);
        for (ptrdiff_t j = 0; j < r->n[1]; j++) {
            ptrdiff_t yj = (r->lo[1] + j) % (ptrdiff_t)e[1];
            size_t y = off[1] + (size_t)(yj < 0 ? yj + (ptrdiff_t)e[1] : yj);
            const float *row = c->data + c->px * (y + c->py * z) + off[0];
            ptrdiff_t xi = r->lo[0] % (ptrdiff_t)e[0];
            if (xi < 0) xi += (ptrdiff_t)e[0];
            for (ptrdiff_t i = 0; i < r->n[0]; i++) {
                dst[t++] = row[xi];
                if (++xi == (ptrdiff_t)e[0]) xi = 0;
            }
        }
    }
}

/* Synthesis along `axis` on unwrapped indices: in arrays lo/hi cover the region `in`
 * (along the axis [k0, k0+kn)), out covers [o0, o0+on) along the axis and in's extent
 * along the others. out[i] = sum_k h[i-2k] lo[k] + g[i-2k] hi[k], 0 <= i-2k < L. When
 * the input region is a whole period (full), k is taken modulo it. */
static void synth_axis(double *out, const double *lo, const double *hi, const region *in, ptrdiff_t o0,
                       ptrdiff_t on, int axis, int full, const wvol_filter *f)
{
    /* [outer][axis][inner] view, inner contiguous: the tap loop adds whole inner rows
     * (x for the y axis, xy-planes for z), which the compiler vectorises */
    ptrdiff_t inner = 1, outer = 1, kn = in->n[axis], k0 = in->lo[axis], L = f->length;
    for (int a = 0; a < axis; a++) inner *= in->n[a];
    for (int a = axis + 1; a < 3; a++) outer *= in->n[a];
    for (ptrdiff_t u = 0; u < outer; u++) {
        const double *lu = lo + u * kn * inner, *hu = hi ? hi + u * kn * inner : NULL;
        for (ptrdiff_t i = 0; i < on; i++) {
            double *restrict o = out + (u * on + i) * inner;
            ptrdiff_t gi = o0 + i, kmin = -floor_div2(L - 1 - gi), kmax = floor_div2(gi), k;
            if (!full) {
                if (kmin < k0) kmin = k0;
                if (kmax > k0 + kn - 1) kmax = k0 + kn - 1;
            }
            for (ptrdiff_t x = 0; x < inner; x++) o[x] = 0.0;
            /* rel = (k - k0) mod kn, stepped without a division per tap */
            ptrdiff_t rel = (kmin - k0) % kn;
            if (rel < 0) rel += kn;
            for (k = kmin; k <= kmax; k++) {
                double wh = f->h[gi - 2 * k], wg = f->g[gi - 2 * k];
                const double *restrict l = lu + rel * inner;
                if (hu) {
                    const double *restrict hh = hu + rel * inner;
                    for (ptrdiff_t x = 0; x < inner; x++) o[x] += wh * l[x] + wg * hh[x];
                } else {
                    for (ptrdiff_t x = 0; x < inner; x++) o[x] += wh * l[x];
                }
                if (++rel == kn) rel = 0;
            }
        }
    }
}

wvol_status wvol_idwt3_brick(wvol_volume **out, const wvol_coeffs *c, const size_t lo[3], const size_t hi[3],
                             wvol_error *err)
{
    size_t dims[3], pad[3];
    region reg[31];
    double *A = NULL, *bands[8] = {0};
    wvol_volume *v = NULL;
    wvol_status st = WVOL_OK;
    int M, a;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_idwt3_brick: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__coeffs_check(c, err));
    WVOL_RETURN_IF(!lo || !hi, err, WVOL_ERR_ARG, "wvol_idwt3_brick: box is NULL");
    dims[0] = c->nx, dims[1] = c->ny, dims[2] = c->nz;
    pad[0] = c->px, pad[1] = c->py, pad[2] = c->pz;
    for (a = 0; a < 3; a++)
        WVOL_RETURN_IF(lo[a] >= hi[a] || hi[a] > dims[a], err, WVOL_ERR_ARG,
                       "wvol_idwt3_brick: box [%zu, %zu) along %c is empty or outside 0..%zu", lo[a], hi[a],
                       "xyz"[a], dims[a]);
    M = c->levels;
    /* R_m: the level-m coefficients that reach R_{m-1}: 0 <= i - 2k <= L-1 */
    for (a = 0; a < 3; a++) {
        reg[0].lo[a] = (ptrdiff_t)lo[a];
        reg[0].n[a] = (ptrdiff_t)(hi[a] - lo[a]);
    }
    for (int m = 1; m <= M; m++)
        for (a = 0; a < 3; a++) {
            if (pad[a] == 1) {
                reg[m].lo[a] = 0, reg[m].n[a] = 1;
                continue;
            }
            ptrdiff_t l0 = reg[m - 1].lo[a], h0 = l0 + reg[m - 1].n[a];
            ptrdiff_t kl = -floor_div2(c->filter->length - 1 - l0), kh = floor_div2(h0 - 1) + 1;
            ptrdiff_t e = (ptrdiff_t)wvol__extent(pad[a], m);
            /* a region at least one period long is the whole period (long filters, deep
             * levels): its synthesis indexes the coefficients periodically */
            if (kh - kl >= e) kl = 0, kh = e;
            reg[m].lo[a] = kl, reg[m].n[a] = kh - kl;
        }
    A = malloc(region_count(&reg[M]) * sizeof *A);
    if (!A) goto nomem;
    gather(A, c, M, 0, &reg[M]);
    for (int m = M; m >= 1; m--) {
        const region *r = &reg[m], *q = &reg[m - 1];
        size_t cnt = region_count(r);
        bands[0] = A;
        A = NULL;
        for (int b = 1; b < 8; b++) {
            int valid = 1;
            for (a = 0; a < 3; a++)
                if (((b >> a) & 1) && pad[a] == 1) valid = 0;
            free(bands[b]);
            bands[b] = NULL;
            if (!valid) continue;
            if (!(bands[b] = malloc(cnt * sizeof(double)))) goto nomem;
            gather(bands[b], c, m, b, r);
        }
        /* z, then y, then x: each halves the number of band arrays */
        region cur = *r;
        int nb = 8;
        double **src = bands;
        for (int ax = 2; ax >= 0; ax--) {
            if (pad[ax] == 1) continue; /* untransformed: only the low band exists */
            region nxt = cur;
            nxt.lo[ax] = q->lo[ax], nxt.n[ax] = q->n[ax];
            size_t ncnt = region_count(&nxt);
            int half = 1 << ax; /* band bit of this axis */
            for (int b = 0; b < nb; b++) {
                if ((b & half) || !src[b]) continue; /* NULL: high-pass on a 1-voxel axis */
                double *o = malloc(ncnt * sizeof *o);
                if (!o) goto nomem;
                synth_axis(o, src[b], src[b | half], &cur, q->lo[ax], q->n[ax], ax,
                           cur.n[ax] == (ptrdiff_t)wvol__extent(pad[ax], m), c->filter);
                free(src[b]);
                free(src[b | half]);
                src[b] = o;
                src[b | half] = NULL;
            }
            cur = nxt;
        }
        A = bands[0];
        bands[0] = NULL;
    }
    st = wvol_volume_create(&v, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], err);
    if (st == WVOL_OK) {
        size_t cnt = wvol_volume_count(v);
        for (size_t i = 0; i < cnt; i++) v->data[i] = (float)A[i];
        for (a = 0; a < 3; a++) {
            v->spacing[a] = c->spacing[a];
            v->origin[a] = c->origin[a] + c->spacing[a] * (double)lo[a];
        }
        *out = v;
    }
    free(A);
    for (int b = 0; b < 8; b++) free(bands[b]);
    return st;
nomem:
    free(A);
    for (int b = 0; b < 8; b++) free(bands[b]);
    return wvol_error_set(err, WVOL_ERR_NOMEM, "wvol_idwt3_brick: out of memory");
}
