/* SPDX-License-Identifier: MIT */
/* Rigorous bounds of reconstructed samples on a box, from the coefficients alone
 * (used to skip bricks without reconstructing them: iso/bricks.c, render/bricks.c).
 *
 * A sample is v(n) = sum over coefficients c R(n - 2^m k), with R the
 * discrete synthesis response of the coefficient's level and band: a product of
 * 1D responses phi_m (low-pass) and psi_m (high-pass) per axis. Per axis
 *   Leb(r) = max over residues rho of sum_t |r[rho + 2^m t]|
 * bounds sum_k |R(n - 2^m k)| at every n. So on a box
 *   |detail part| <= sum over (m, band) of max|c| (over coefficients reaching the
 *                    box) * prod_axes Leb,
 *   low-pass part  = a0 S(n) + sum (a_k - a0) R(...), a0 = mid-range of the reaching
 *                    low-pass coefficients, S(n) = sum_t Phi(n - 2^M t) in [Smin, Smax],
 *                    |second term| <= half-range * prod Leb.
 * max|c| per box comes from per-(level, band) block maxima, filled in one pass over
 * dense coefficients or coefficient by coefficient (a sparse store).
 * Based on: DESIGN.md section 9. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/clones.h"
#include "wavelet/wavelet_internal.h"

/* ---- 1D responses ----------------------------------------------------------------- */

/* A response split into a core window [lo, hi] and tails: the core carries all but
 * a 1e-4 share of sum |r|, so long filters (Battle-Lemarie's truncated taps, deep
 * levels) do not make every coefficient "reach" every brick; the tails are
 * bounded with the band's global maximum instead. */
typedef struct resp1 {
    double leb;        /* max_rho sum_t |r[rho + 2^m t]| over the core */
    double tail;       /* sum |r| outside the core */
    double smin, smax; /* min/max_rho sum_t r[rho + 2^m t] (whole response) */
    long lo, hi;       /* core window, offsets in [0, len) */
    long len;          /* the whole response: offsets [0, len) */
} resp1;

static void split_core(resp1 *o, const double *r, long nl, long P)
{
    double total = 0.0, cut, out = 0.0;
    long n, rho, lo = 0, hi = nl - 1;
    for (n = 0; n < nl; n++) total += fabs(r[n]);
    cut = 1e-4 * total;
    /* peel the smaller end while the peeled mass stays under the cut */
    while (lo < hi) {
        double a = fabs(r[lo]), b = fabs(r[hi]);
        if (a <= b && out + a <= cut) out += a, lo++;
        else if (b < a && out + b <= cut) out += b, hi--;
        else if (out + a <= cut) out += a, lo++;
        else break;
    }
    o->lo = lo;
    o->hi = hi;
    o->len = nl;
    o->tail = 0.0;
    for (n = 0; n < nl; n++)
        if (n < lo || n > hi) o->tail += fabs(r[n]);
    o->leb = 0.0;
    o->smin = INFINITY;
    o->smax = -INFINITY;
    for (rho = 0; rho < P; rho++) {
        double sa = 0.0, sum = 0.0;
        for (n = rho; n < nl; n += P) {
            if (n >= lo && n <= hi) sa += fabs(r[n]);
            sum += r[n];
        }
        if (sa > o->leb) o->leb = sa;
        if (sum < o->smin) o->smin = sum;
        if (sum > o->smax) o->smax = sum;
    }
}

/* phi_m and psi_m responses for m = 1..M into lp[m], hp[m]. */
static wvol_status responses(resp1 *lp, resp1 *hp, const wvol_filter *f, int M, wvol_error *err)
{
    long L = f->length, len = 1, m;
    double *phi = malloc(sizeof(double));
    if (!phi) return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
    phi[0] = 1.0;
    for (m = 1; m <= M; m++) {
        long step = 1L << (m - 1), nl = len + step * (L - 1), n, t;
        double *nphi = calloc((size_t)nl, sizeof(double)), *npsi = calloc((size_t)nl, sizeof(double));
        if (!nphi || !npsi) {
            free(nphi);
            free(npsi);
            free(phi);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
        }
        for (t = 0; t < L; t++)
            for (n = 0; n < len; n++) {
                nphi[n + step * t] += f->h[t] * phi[n];
                npsi[n + step * t] += f->g[t] * phi[n];
            }
        split_core(&lp[m], nphi, nl, 1L << m);
        split_core(&hp[m], npsi, nl, 1L << m);
        free(phi);
        free(npsi);
        phi = nphi;
        len = nl;
    }
    free(phi);
    return WVOL_OK;
}

/* ---- block maxima of the detail coefficients ---------------------------------------- */

typedef struct band_blocks {
    size_t e[3];       /* band extent (coefficient positions) */
    size_t bs[3];      /* block size (a power of two) */
    int bshift[3];     /* log2 bs */
    size_t nb[3];      /* blocks per axis */
    float *absmax;     /* nb0 nb1 nb2; detail bands only (the low-pass cube is scanned) */
    float gmax;        /* max |c| over the whole band */
    double leb;        /* prod over axes of the core sums */
    double tailw;      /* prod (leb + tail) - prod leb: weight of everything off the cores */
    double smin, smax; /* low-pass: prod over axes of [smin, smax] */
    long lo[3], hi[3]; /* core windows */
    long len[3];       /* whole responses: offsets [0, len) */
    int m, band;
} band_blocks;

struct wvol__brick_bounds {
    const float *low;  /* low-pass cube: value (x, y, z) at low[x + low_sy y + low_sz z] */
    size_t low_sy, low_sz;
    int M;
    int nbands;
    float *own_low;    /* the low-pass cube when the bound reconstructed it (create_src) */
    float *maxima;     /* every detail band's absmax, one allocation (whole huge pages when
                        * large: a fresh bound's first touches of many small tables cost more
                        * than its filling) */
    size_t bytes;      /* tables beyond the struct */
    int kept;          /* held by its maker (wvol__bounds_keep): wvol__bounds_free leaves it */
    band_blocks bb[7 * 32 + 1];
};
typedef struct wvol__brick_bounds brick_bounds;

void wvol__bounds_keep(brick_bounds *b, int kept)
{
    if (b) b->kept = kept;
}

void wvol__bounds_free(brick_bounds *b)
{
    if (!b || b->kept) return;
    free(b->maxima);
    free(b->own_low);
    free(b);
}

/* block: NULL, or per axis a least block edge (positions; rounded down to a power of two). */
static wvol_status bounds_create(brick_bounds **out, const wvol_filter *f, int levels, const size_t pad[3],
                                 const float *low, size_t low_sy, size_t low_sz, const size_t block[3],
                                 wvol_error *err)
{
    brick_bounds *b;
    resp1 lp[33], hp[33];
    int m, l, a;
    size_t total = 0; /* detail blocks of every band */
    *out = NULL;
    WVOL_RETURN_IF(levels < 1 || levels > 32, err, WVOL_ERR_ARG, "brick bounds: %d levels", levels);
    for (a = 0; a < 3; a++)
        WVOL_RETURN_IF(pad[a] < 2, err, WVOL_ERR_DIMS, "brick bounds: axis %c is not transformed", "xyz"[a]);
    WVOL_FORWARD(responses(lp, hp, f, levels, err));
    b = calloc(1, sizeof *b);
    if (!b) return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
    b->low = low;
    b->low_sy = low_sy;
    b->low_sz = low_sz;
    b->M = levels;
    for (m = 1; m <= b->M; m++)
        for (l = (m == b->M ? 0 : 1); l < 8; l++) {
            band_blocks *q = &b->bb[b->nbands++];
            double full = 1.0;
            size_t nblk;
            q->m = m;
            q->band = l;
            q->leb = 1.0;
            q->smin = q->smax = 1.0;
            for (a = 0; a < 3; a++) {
                const resp1 *r = ((l >> a) & 1) ? &hp[m] : &lp[m];
                q->e[a] = pad[a] >> m;
                /* blocks of 4, 2, 1 positions at levels 1, 2, >= 3: about 8 samples wide */
                q->bshift[a] = m >= 3 ? 0 : 3 - m;
                if (block)
                    while (((size_t)2 << q->bshift[a]) <= block[a] && q->bshift[a] < 30) q->bshift[a]++;
                q->bs[a] = (size_t)1 << q->bshift[a];
                q->nb[a] = (q->e[a] + q->bs[a] - 1) / q->bs[a];
                q->leb *= r->leb;
                full *= r->leb + r->tail;
                q->smin *= r->smin;
                q->smax *= r->smax;
                q->lo[a] = r->lo;
                q->hi[a] = r->hi;
                q->len[a] = r->len;
            }
            q->tailw = full - q->leb;
            b->bytes += sizeof *q;
            if (l == 0) continue;
            nblk = q->nb[0] * q->nb[1] * q->nb[2];
            total += nblk;
        }
    /* the detail bands' tables carved from one zeroed allocation, in band order */
    {
        size_t bytes = total * sizeof(float), at = 0;
        b->maxima = total <= SIZE_MAX / sizeof(float) ? wvol__malloc_pages(&bytes) : NULL;
        if (!b->maxima) {
            wvol__bounds_free(b);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
        }
        memset(b->maxima, 0, total * sizeof(float));
        for (int qi = 0; qi < b->nbands; qi++) {
            band_blocks *q = &b->bb[qi];
            if (q->band == 0) continue;
            q->absmax = b->maxima + at;
            at += q->nb[0] * q->nb[1] * q->nb[2];
        }
        b->bytes += total * sizeof(float);
    }
    *out = b;
    return WVOL_OK;
}

static band_blocks *band_of(brick_bounds *b, int m, int band);

int wvol__bounds_levels_for(const size_t pad[3], int levels)
{
    int L = levels < WVOL__BOUNDS_LEVELS ? levels : WVOL__BOUNDS_LEVELS;
    /* a finer low-pass cube bounds a brick from the values near it, a coarser one holds less */
    while (L < levels && (pad[0] >> L) * (pad[1] >> L) * (pad[2] >> L) * sizeof(float) > WVOL__BOUNDS_LOW_BYTES) L++;
    return L;
}

wvol_status wvol__bounds_create_src(brick_bounds **out, const wvol__coef_source *src, const size_t block[3],
                                    wvol_error *err)
{
    const int L = wvol__bounds_levels_for(src->pad, src->levels);
    size_t e[3], n;
    const size_t zero[3] = {0, 0, 0};
    wvol__coef_skip sk;
    wvol__coef_source coarse;
    wvol__brick_scratch scr;
    float *low;
    wvol_status st;
    *out = NULL;
    WVOL_RETURN_IF(L < 1, err, WVOL_ERR_ARG, "brick bounds: %d levels", src->levels);
    for (int a = 0; a < 3; a++)
        WVOL_RETURN_IF(src->pad[a] < 2, err, WVOL_ERR_DIMS, "brick bounds: axis %c is not transformed", "xyz"[a]);
    for (int a = 0; a < 3; a++) e[a] = src->pad[a] >> L;
    n = e[0] * e[1] * e[2];
    {
        size_t bytes = n * sizeof *low; /* written whole by the reconstruction below */
        low = wvol__malloc_pages(&bytes);
    }
    WVOL_RETURN_IF(!low, err, WVOL_ERR_NOMEM, "brick bounds: out of memory for a %zu x %zu x %zu low-pass cube", e[0],
                   e[1], e[2]);
    /* the pyramid above level L, reconstructed: its samples are the level-L low-pass */
    wvol__coef_source_skip(&coarse, &sk, src, L);
    memset(&scr, 0, sizeof scr);
    st = wvol__idwt3_brick_src(low, &coarse, zero, e, &scr, err);
    wvol__brick_scratch_free(&scr);
    if (st == WVOL_OK) st = bounds_create(out, src->filter, L, src->pad, low, e[0], e[0] * e[1], block, err);
    if (st != WVOL_OK) {
        free(low);
        return st;
    }
    (*out)->own_low = low;
    (*out)->bytes += n * sizeof *low;
    return WVOL_OK;
}

int wvol__bounds_levels(const brick_bounds *b) { return b ? b->M : 0; }

size_t wvol__bounds_block(const brick_bounds *b, int m)
{
    const band_blocks *q = band_of((brick_bounds *)b, m, 1);
    size_t e = 0;
    for (int a = 0; q && a < 3; a++)
        if (!e || q->bs[a] < e) e = q->bs[a];
    return e;
}

/* The (level, band) entry of the table; NULL for the low-pass cube and out of range. */
static band_blocks *band_of(brick_bounds *b, int m, int band)
{
    int qi;
    if (m < 1 || m > b->M || band < 1 || band > 7) return NULL;
    qi = 7 * (m - 1) + band - 1; /* levels 1..M-1 hold bands 1..7; level M holds 0..7 */
    if (m == b->M) qi++;
    return &b->bb[qi];
}

void wvol__bounds_add(brick_bounds *b, int m, int band, size_t p, size_t q, size_t r, float value)
{
    band_blocks *bq = band_of(b, m, band);
    float av = fabsf(value), *slot;
    if (!bq || p >= bq->e[0] || q >= bq->e[1] || r >= bq->e[2]) return;
    slot = &bq->absmax[(p >> bq->bshift[0]) + bq->nb[0] * ((q >> bq->bshift[1]) + bq->nb[1] * (r >> bq->bshift[2]))];
    if (!(av <= *slot)) *slot = isnan(av) ? INFINITY : av;
}

float *wvol__bounds_table(brick_bounds *b, int m, int band, size_t nb[3], int shift[3])
{
    band_blocks *bq = band_of(b, m, band);
    if (!bq) return NULL;
    for (int a = 0; a < 3; a++) nb[a] = bq->nb[a], shift[a] = bq->bshift[a];
    return bq->absmax;
}

void wvol__bounds_add_box(brick_bounds *b, int m, int band, const size_t lo[3], const size_t hi[3], float value)
{
    band_blocks *bq = band_of(b, m, band);
    float av = fabsf(value);
    size_t b0[3], b1[3];
    if (!bq) return;
    for (int a = 0; a < 3; a++) {
        if (lo[a] >= hi[a] || lo[a] >= bq->e[a]) return;
        b0[a] = lo[a] >> bq->bshift[a];
        b1[a] = ((hi[a] < bq->e[a] ? hi[a] : bq->e[a]) - 1) >> bq->bshift[a];
    }
    for (size_t z = b0[2]; z <= b1[2]; z++)
        for (size_t y = b0[1]; y <= b1[1]; y++)
            for (size_t x = b0[0]; x <= b1[0]; x++) {
                float *slot = &bq->absmax[x + bq->nb[0] * (y + bq->nb[1] * z)];
                if (!(av <= *slot)) *slot = isnan(av) ? INFINITY : av;
            }
}

/* The block maxima of a region, in two steps that vectorise: the magnitudes' bits (as integers
 * they order as the values, and NaN's above +inf's) folded row by row into one row per block row
 * of the current z-block (an element-wise maximum over whole rows), then each such row's blocks
 * reduced into the table when the z-block is done. The same maxima as one value at a time. */
#define FOLD_ROWS 64 /* block rows folded at once (a region's rows in one z-block) */

static void flush_fold(band_blocks *q, const size_t lo[3], size_t z, size_t y0, size_t y1, const uint32_t *fold,
                       size_t n0)
{
    const int sh = q->bshift[0], shy = q->bshift[1];
    for (size_t yb = (lo[1] + y0) >> shy, k = 0; yb <= (lo[1] + y1 - 1) >> shy; yb++, k++) {
        float *brow = q->absmax + q->nb[0] * (yb + q->nb[1] * ((lo[2] + z) >> q->bshift[2]));
        const uint32_t *f = fold + k * n0;
        for (size_t x = 0; x < n0;) {
            const size_t bx = (lo[0] + x) >> sh, end = ((bx + 1) << sh) - lo[0] < n0 ? ((bx + 1) << sh) - lo[0] : n0;
            uint32_t m = 0;
            float av;
            for (; x < end; x++) m = f[x] > m ? f[x] : m;
            if (m > 0x7f800000u) m = 0x7f800000u; /* NaN propagates as +inf */
            memcpy(&av, &m, sizeof av);
            if (!(av <= brow[bx])) brow[bx] = av;
        }
    }
}

WVOL__CLONES void wvol__bounds_add_dense(brick_bounds *b, int m, int band, const size_t lo[3], const size_t n[3],
                                         const float *v, size_t sy, size_t sz)
{
    band_blocks *q = band_of(b, m, band);
    uint32_t *fold;
    size_t nfold;
    if (!q) return;
    for (int a = 0; a < 3; a++)
        if (lo[a] >= q->e[a] || n[a] > q->e[a] - lo[a]) return; /* outside the band: the caller's error */
    if (!n[0] || !n[1] || !n[2]) return;
    /* the block rows of a stretch of y: the region's, at most FOLD_ROWS of them, n[0] wide */
    nfold = ((lo[1] + n[1] - 1) >> q->bshift[1]) - (lo[1] >> q->bshift[1]) + 1;
    if (nfold > FOLD_ROWS) nfold = FOLD_ROWS;
    fold = malloc(nfold * n[0] * sizeof *fold);
    if (!fold) { /* one value at a time */
        for (size_t z = 0; z < n[2]; z++)
            for (size_t y = 0; y < n[1]; y++) {
                const float *row = v + sy * y + sz * z;
                float *brow = q->absmax + q->nb[0] * (((lo[1] + y) >> q->bshift[1]) + q->nb[1] * ((lo[2] + z) >> q->bshift[2]));
                for (size_t x = 0; x < n[0]; x++) {
                    float av = fabsf(row[x]);
                    size_t bx = (lo[0] + x) >> q->bshift[0];
                    if (!(av <= brow[bx])) brow[bx] = isnan(av) ? INFINITY : av;
                }
            }
        return;
    }
    /* y stretches of at most FOLD_ROWS block rows; within one, z-blocks in turn */
    for (size_t y0 = 0; y0 < n[1];) {
        const size_t yb0 = (lo[1] + y0) >> q->bshift[1];
        size_t y1 = (((yb0 + FOLD_ROWS) << q->bshift[1]) - lo[1]);
        if (y1 > n[1]) y1 = n[1];
        for (size_t z0 = 0; z0 < n[2];) {
            const size_t zb = (lo[2] + z0) >> q->bshift[2];
            size_t z1 = ((zb + 1) << q->bshift[2]) - lo[2];
            if (z1 > n[2]) z1 = n[2];
            memset(fold, 0, (((lo[1] + y1 - 1) >> q->bshift[1]) - yb0 + 1) * n[0] * sizeof *fold);
            for (size_t z = z0; z < z1; z++)
                for (size_t y = y0; y < y1; y++) {
                    const uint32_t *row = (const uint32_t *)(const void *)(v + sy * y + sz * z);
                    uint32_t *f = fold + (((lo[1] + y) >> q->bshift[1]) - yb0) * n[0];
                    for (size_t x = 0; x < n[0]; x++) {
                        const uint32_t a = row[x] & 0x7fffffffu;
                        f[x] = a > f[x] ? a : f[x];
                    }
                }
            flush_fold(q, lo, z0, y0, y1, fold, n[0]);
            z0 = z1;
        }
        y0 = y1;
    }
    free(fold);
}

void wvol__bounds_fill_coeffs(brick_bounds *b, const wvol_coeffs *c)
{
    /* one pass over the coefficients; a thread owns whole z-slabs of blocks */
    for (int qi = 0; qi < b->nbands; qi++) {
        band_blocks *q = &b->bb[qi];
        long zb;
        size_t off[3];
        int a;
        if (q->band == 0) continue;
        for (a = 0; a < 3; a++) off[a] = ((q->band >> a) & 1) ? q->e[a] : 0;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1)
#endif
        for (zb = 0; zb < (long)q->nb[2]; zb++) {
            size_t z0 = (size_t)zb * q->bs[2], z1 = z0 + q->bs[2] < q->e[2] ? z0 + q->bs[2] : q->e[2];
            const size_t lo[3] = {0, 0, z0}, n[3] = {q->e[0], q->e[1], z1 - z0};
            wvol__bounds_add_dense(b, q->m, q->band, lo, n, c->data + off[0] + c->px * (off[1] + c->py * (off[2] + z0)),
                                   c->px, c->px * c->py);
        }
    }
}

void wvol__bounds_finish(brick_bounds *b)
{
    for (int qi = 0; qi < b->nbands; qi++) {
        band_blocks *q = &b->bb[qi];
        float gmax = 0.0f;
        if (q->band == 0) { /* global max of the low-pass cube, for the tail terms */
            size_t x, y, z;
            for (z = 0; z < q->e[2]; z++)
                for (y = 0; y < q->e[1]; y++)
                    for (x = 0; x < q->e[0]; x++) {
                        float av = fabsf(b->low[x + b->low_sy * y + b->low_sz * z]);
                        if (!(av <= gmax)) gmax = isnan(av) ? INFINITY : av;
                    }
        } else {
            /* the block maxima are magnitudes (+0 to +inf; NaN never stored): as int32 their
             * bits order as the values, so the maximum is an integer one, which vectorises
             * (a fresh 512^3 bound holds 14 MB of them); a NaN's bits sort above +inf's */
            size_t i, nblk = q->nb[0] * q->nb[1] * q->nb[2];
            int32_t top = 0;
            for (i = 0; i < nblk; i++) {
                int32_t bits;
                memcpy(&bits, &q->absmax[i], sizeof bits);
                top = bits > top ? bits : top;
            }
            if (top > 0x7f800000) top = 0x7f800000;
            memcpy(&gmax, &top, sizeof gmax);
        }
        q->gmax = gmax;
    }
}

size_t wvol__bounds_bytes(const brick_bounds *b) { return b ? sizeof *b + b->bytes : 0; }

/* Coefficient positions [*k0, *k0 + *kn) (unwrapped) whose response window [wlo, whi]
 * (the core, or the whole response) reaches samples [s0, s1] along axis a; the whole
 * band when that covers the period. */
static void reach(const band_blocks *q, int a, long wlo, long whi, long s0, long s1, long *k0, long *kn)
{
    long step = 1L << q->m, e = (long)q->e[a], klo = s0 - whi, khi = s1 - wlo;
    long c0 = klo >= 0 ? (klo + step - 1) / step : -((-klo) / step); /* ceil */
    long c1 = khi >= 0 ? khi / step : -((-khi + step - 1) / step);   /* floor */
    *k0 = c0;
    *kn = c1 - c0 + 1;
    if (*kn > e) *k0 = 0, *kn = e;
    if (*kn < 0) *kn = 0;
}

static inline long wrap(long k, long e) { return ((k % e) + e) % e; }

/* Positions of one band reaching a box along each axis. */
typedef struct band_reach {
    long k0[3], kn[3];
} band_reach;

static band_reach reach_box(const band_blocks *q, int whole, const long s0[3], const long s1[3])
{
    band_reach r;
    for (int a = 0; a < 3; a++)
        reach(q, a, whole ? 0 : q->lo[a], whole ? q->len[a] - 1 : q->hi[a], s0[a], s1[a], &r.k0[a], &r.kn[a]);
    return r;
}

/* min and max of the low-pass coefficients at the reached positions (+inf, -inf if none). */
static void low_range(const brick_bounds *b, const band_blocks *q, const band_reach *r, float *cmin, float *cmax)
{
    long x, y, z;
    *cmin = INFINITY;
    *cmax = -INFINITY;
    for (z = 0; z < r->kn[2]; z++) {
        size_t kz = (size_t)wrap(r->k0[2] + z, (long)q->e[2]);
        for (y = 0; y < r->kn[1]; y++) {
            size_t ky = (size_t)wrap(r->k0[1] + y, (long)q->e[1]);
            const float *row = b->low + b->low_sy * ky + b->low_sz * kz;
            size_t kx = (size_t)wrap(r->k0[0], (long)q->e[0]); /* stepped: no division per position */
            for (x = 0; x < r->kn[0]; x++) {
                float v = row[kx];
                if (!(v >= *cmin)) *cmin = v;
                if (!(v <= *cmax)) *cmax = v;
                if (++kx == q->e[0]) kx = 0;
            }
        }
    }
}

/* Blocks of a detail band covering the reached positions [k0, k0 + kn) along axis a: [*b0,
 * *b1] (unwrapped); their count, 0 when none is reached. */
static long axis_span(const band_blocks *q, int a, long k0, long kn, long *b0, long *b1)
{
    long bs = (long)q->bs[a], nbk = (long)q->nb[a];
    if (kn <= 0) return 0;
    if (kn >= (long)q->e[a]) {
        *b0 = 0, *b1 = nbk - 1;
    } else {
        long m0 = wrap(k0, (long)q->e[a]), last = m0 + kn - 1;
        *b0 = m0 / bs;
        *b1 = last < (long)q->e[a] ? last / bs : nbk + (last - (long)q->e[a]) / bs;
        if (*b1 - *b0 + 1 > nbk) *b1 = *b0 + nbk - 1;
    }
    return *b1 - *b0 + 1;
}

/* Blocks of a detail band covering the reached positions, per axis [b0, b1] (unwrapped). */
static size_t block_span(const band_blocks *q, const band_reach *r, long b0[3], long b1[3])
{
    size_t count = 1;
    for (int a = 0; a < 3; a++) {
        long n = axis_span(q, a, r->k0[a], r->kn[a], &b0[a], &b1[a]);
        if (!n) return 0;
        count *= (size_t)n;
    }
    return count;
}

/* Largest block maximum of a detail band over the blocks [b0, b1]. */
static float block_absmax(const band_blocks *q, const long b0[3], const long b1[3])
{
    float amax = 0.0f;
    long x, y, z;
    for (z = b0[2]; z <= b1[2]; z++) {
        size_t bz = (size_t)(z % (long)q->nb[2]);
        for (y = b0[1]; y <= b1[1]; y++) {
            size_t by = (size_t)(y % (long)q->nb[1]);
            const float *row = q->absmax + q->nb[0] * (by + q->nb[1] * bz);
            size_t bx = (size_t)(b0[0] % (long)q->nb[0]); /* stepped: no division per block */
            for (x = b0[0]; x <= b1[0]; x++) {
                float v = row[bx];
                if (!(v <= amax)) amax = v;
                if (++bx == q->nb[0]) bx = 0;
            }
        }
    }
    return amax;
}

/* Scans of the whole responses' reach longer than this many blocks (or low-pass
 * positions) fall back to the band's global maximum: long filters at deep levels
 * reach most of a band, and the scan would cost more than the bound saves. */
#define WHOLE_SCAN_MAX 4096

/* What a box's bound takes from one band: a detail band's largest block maxima over the
 * core's and the whole response's reach (whole: the band's global maximum when that reach is
 * too long to scan); the low-pass band's range over the core's reach and the magnitude its
 * tails carry. */
typedef struct band_stat {
    float a, b; /* detail: amax, wmax; low-pass: cmin, cmax (core) */
    double wabs; /* low-pass: the tails' magnitude */
} band_stat;

/* The low-pass band's stat from its ranges over the core's reach (cmin > cmax: none) and
 * the whole response's (scanned: whether it was, wmin > wmax: none). */
static band_stat low_stat(const band_blocks *q, float cmin, float cmax, int scanned, float wmin, float wmax)
{
    band_stat r;
    r.wabs = (double)q->gmax;
    if (cmin > cmax) cmin = cmax = 0.0f; /* no core reaches (cannot happen for a non-empty box) */
    if (q->tailw > 0 && scanned) r.wabs = wmin > wmax ? 0.0 : fmax(fabs((double)wmin), fabs((double)wmax));
    else if (q->tailw == 0) r.wabs = fmax(fabs((double)cmin), fabs((double)cmax));
    r.a = cmin, r.b = cmax;
    return r;
}

/* The bound from every band's stat (st[qi]), in band order. Rounding: float coefficients
 * summed in double, the result rounded to float; no absolute term, so that a box reached by
 * zeros only is bounded by exactly [0, 0]. */
static void combine(const brick_bounds *b, const band_stat *st, double *vmin, double *vmax)
{
    double detail = 0.0, lo = 0.0, hi = 0.0, mag = 0.0;
    for (int qi = 0; qi < b->nbands; qi++) {
        const band_blocks *q = &b->bb[qi];
        if (q->band == 0) {
            double a0 = 0.5 * ((double)st[qi].a + (double)st[qi].b), half = 0.5 * ((double)st[qi].b - (double)st[qi].a);
            double p1 = a0 * q->smin, p2 = a0 * q->smax;
            double off = half * q->leb + (st[qi].wabs + fabs(a0)) * q->tailw;
            lo = (p1 < p2 ? p1 : p2) - off;
            hi = (p1 > p2 ? p1 : p2) + off;
            mag += st[qi].wabs * (q->leb + q->tailw);
        } else {
            detail += (double)st[qi].a * q->leb + (double)st[qi].b * q->tailw;
        }
    }
    mag += detail;
    {
        double pad = 1e-5 * mag;
        *vmin = lo - detail - pad;
        *vmax = hi + detail + pad;
    }
}

/* Bound of the reconstructed samples in the box [s0, s1] (inclusive, voxel indices).
 * The coefficients whose core reaches the box carry the core sums; those reached only
 * by the tails carry the tail weights, with their own maximum when the whole response's
 * reach is small enough to scan (always for Haar, Daubechies and Coiflets at the usual
 * depths), else the band's. So where every coefficient whose support reaches the box is
 * zero, the bound is exactly [0, 0] (the samples are exact zeros there: a sum of
 * products with zero), and the rounding pad scales with the magnitude of what reaches
 * the box rather than with the whole volume's. */
void wvol__bounds_box(const brick_bounds *b, const long s0[3], const long s1[3], double *vmin, double *vmax)
{
    band_stat st[7 * 32 + 1];
    for (int qi = 0; qi < b->nbands; qi++) {
        const band_blocks *q = &b->bb[qi];
        band_reach core = reach_box(q, 0, s0, s1), whole = reach_box(q, 1, s0, s1);
        if (q->band == 0) {
            float cmin, cmax, wmin = 0.0f, wmax = 0.0f;
            const int scan = q->tailw > 0 && (size_t)whole.kn[0] * (size_t)whole.kn[1] * (size_t)whole.kn[2] <= WHOLE_SCAN_MAX;
            low_range(b, q, &core, &cmin, &cmax);
            if (scan) low_range(b, q, &whole, &wmin, &wmax);
            st[qi] = low_stat(q, cmin, cmax, scan, wmin, wmax);
            continue;
        }
        /* detail band: block maxima over the reach */
        {
            long b0[3], b1[3];
            float amax = block_span(q, &core, b0, b1) ? block_absmax(q, b0, b1) : 0.0f, wmax = q->gmax;
            if (q->tailw > 0) {
                size_t nw = block_span(q, &whole, b0, b1);
                if (nw <= WHOLE_SCAN_MAX) wmax = nw ? block_absmax(q, b0, b1) : 0.0f;
            }
            st[qi].a = amax, st[qi].b = wmax, st[qi].wabs = 0.0;
        }
    }
    combine(b, st, vmin, vmax);
}

/* ---- the bounds of a grid of boxes -------------------------------------------------- */

/* One axis's windows: box t reads positions start[t] .. start[t] + len[t] - 1 of an axis of
 * extent e, taken modulo e (len 0: none). */
typedef struct axis_windows {
    long *start, *len;
} axis_windows;

/* red[t] = the largest of a[x + sy y + sz z] (from init) over box t's windows along the three
 * axes, t = t0 + n0 (t1 + n1 t2); with both, also red[nbox + t] = the least (from +inf), in
 * the same pass (the low-pass cube's range). Taken axis by axis: x into tmp1 (n0 x e1 x e2,
 * the least after the largest), then y into tmp2 (n0 x n1 x e2), then z. The same values as
 * the box by box scans: a minimum or maximum does not depend on the order. */
static void reduce_grid(const float *a, const size_t e[3], size_t sy, size_t sz, const axis_windows w[3],
                        const size_t n[3], int both, float init, float *tmp1, float *tmp2, float *red)
{
#define UP_MAX(acc, v) ((acc) = !((v) <= (acc)) ? (v) : (acc))
#define UP_MIN(acc, v) ((acc) = !((v) >= (acc)) ? (v) : (acc))
    const size_t t1n = n[0] * e[1] * e[2], t2n = n[0] * n[1] * e[2], nbox = n[0] * n[1] * n[2];
    for (size_t z = 0; z < e[2]; z++)
        for (size_t y = 0; y < e[1]; y++) {
            const float *row = a + sy * y + sz * z;
            float *o = tmp1 + n[0] * (y + e[1] * z);
            for (size_t t = 0; t < n[0]; t++) {
                float hi = init, lo = INFINITY;
                size_t x = (size_t)w[0].start[t];
                for (long k = 0; k < w[0].len[t]; k++) {
                    UP_MAX(hi, row[x]);
                    if (both) UP_MIN(lo, row[x]);
                    if (++x == e[0]) x = 0;
                }
                o[t] = hi;
                if (both) o[t1n + t] = lo;
            }
        }
    for (size_t z = 0; z < e[2]; z++)
        for (size_t t1 = 0; t1 < n[1]; t1++) {
            float *o = tmp2 + n[0] * (t1 + n[1] * z);
            size_t y = (size_t)w[1].start[t1];
            for (size_t t0 = 0; t0 < n[0]; t0++) {
                o[t0] = init;
                if (both) o[t2n + t0] = INFINITY;
            }
            for (long k = 0; k < w[1].len[t1]; k++) {
                const float *in = tmp1 + n[0] * (y + e[1] * z);
                for (size_t t0 = 0; t0 < n[0]; t0++) UP_MAX(o[t0], in[t0]);
                if (both)
                    for (size_t t0 = 0; t0 < n[0]; t0++) UP_MIN(o[t2n + t0], in[t1n + t0]);
                if (++y == e[1]) y = 0;
            }
        }
    for (size_t t2 = 0; t2 < n[2]; t2++) {
        float *o = red + n[0] * n[1] * t2;
        size_t z = (size_t)w[2].start[t2];
        for (size_t t = 0; t < n[0] * n[1]; t++) {
            o[t] = init;
            if (both) o[nbox + t] = INFINITY;
        }
        for (long k = 0; k < w[2].len[t2]; k++) {
            const float *in = tmp2 + n[0] * n[1] * z;
            for (size_t t = 0; t < n[0] * n[1]; t++) UP_MAX(o[t], in[t]);
            if (both)
                for (size_t t = 0; t < n[0] * n[1]; t++) UP_MIN(o[nbox + t], in[t2n + t]);
            if (++z == e[2]) z = 0;
        }
    }
#undef UP_MAX
#undef UP_MIN
}

/* Box t's windows along axis a for band q (whole: the whole response's reach, else the
 * core's): low-pass positions (blocks = 0), or the detail blocks block_span covers. */
static void grid_windows(const band_blocks *q, int a, int whole, int blocks, const long *s0, const long *s1, size_t n,
                         axis_windows *w)
{
    for (size_t t = 0; t < n; t++) {
        long k0, kn;
        reach(q, a, whole ? 0 : q->lo[a], whole ? q->len[a] - 1 : q->hi[a], s0[t], s1[t], &k0, &kn);
        if (!blocks) {
            w->start[t] = kn > 0 ? wrap(k0, (long)q->e[a]) : 0;
            w->len[t] = kn > 0 ? kn : 0;
            continue;
        }
        {
            long b0 = 0, b1 = 0, nblk = axis_span(q, a, k0, kn, &b0, &b1);
            w->start[t] = nblk ? b0 % (long)q->nb[a] : 0, w->len[t] = nblk;
        }
    }
}

int wvol__bounds_grid(const brick_bounds *b, const long *const s0[3], const long *const s1[3], const size_t n[3],
                      double *range)
{
    const size_t nbox = n[0] * n[1] * n[2];
    size_t ntmp = 0, nw = n[0] + n[1] + n[2];
    long *wbuf;
    float *tmp1, *tmp2, *red, *red2;
    band_stat *st;
    axis_windows core[3], whole[3];
    if (!nbox) return 1;
    /* the scratch of the largest band */
    for (int qi = 0; qi < b->nbands; qi++) {
        const band_blocks *q = &b->bb[qi];
        const size_t *ext = q->band == 0 ? q->e : q->nb;
        size_t t1 = n[0] * ext[1] * ext[2], t2 = n[0] * n[1] * ext[2];
        if (t1 > ntmp) ntmp = t1;
        if (t2 > ntmp) ntmp = t2;
    }
    wbuf = malloc(4 * nw * sizeof *wbuf);
    tmp1 = malloc((4 * ntmp + 4 * nbox) * sizeof *tmp1); /* tmp1, tmp2: largest and least */
    st = malloc(nbox * (size_t)b->nbands * sizeof *st);
    if (!wbuf || !tmp1 || !st) {
        free(wbuf);
        free(tmp1);
        free(st);
        return 0;
    }
    tmp2 = tmp1 + 2 * ntmp;
    red = tmp2 + 2 * ntmp;
    red2 = red + 2 * nbox;
    for (int a = 0, at = 0; a < 3; at += 2 * (int)n[a], a++) {
        core[a].start = wbuf + at, core[a].len = wbuf + at + n[a];
        whole[a].start = wbuf + 2 * nw + at, whole[a].len = wbuf + 2 * nw + at + n[a];
    }
    for (int qi = 0; qi < b->nbands; qi++) {
        const band_blocks *q = &b->bb[qi];
        const int low = q->band == 0;
        for (int a = 0; a < 3; a++) {
            grid_windows(q, a, 0, !low, s0[a], s1[a], n[a], &core[a]);
            grid_windows(q, a, 1, !low, s0[a], s1[a], n[a], &whole[a]);
        }
        if (low) {
            /* red: cmax, cmin over the core; red2: wmax, wmin over the whole reach */
            reduce_grid(b->low, q->e, b->low_sy, b->low_sz, core, n, 1, -INFINITY, tmp1, tmp2, red);
            if (q->tailw > 0) reduce_grid(b->low, q->e, b->low_sy, b->low_sz, whole, n, 1, -INFINITY, tmp1, tmp2, red2);
            for (size_t t = 0, k = 0; k < n[2]; k++)
                for (size_t j = 0; j < n[1]; j++)
                    for (size_t i = 0; i < n[0]; i++, t++) {
                        const size_t cells = (size_t)whole[0].len[i] * (size_t)whole[1].len[j] * (size_t)whole[2].len[k];
                        const int scan = q->tailw > 0 && cells <= WHOLE_SCAN_MAX;
                        st[t * (size_t)b->nbands + (size_t)qi] =
                            low_stat(q, red[nbox + t], red[t], scan, scan ? red2[nbox + t] : 0.0f, scan ? red2[t] : 0.0f);
                    }
        } else {
            reduce_grid(q->absmax, q->nb, q->nb[0], q->nb[0] * q->nb[1], core, n, 0, 0.0f, tmp1, tmp2, red);
            if (q->tailw > 0) reduce_grid(q->absmax, q->nb, q->nb[0], q->nb[0] * q->nb[1], whole, n, 0, 0.0f, tmp1, tmp2, red2);
            for (size_t t = 0, k = 0; k < n[2]; k++)
                for (size_t j = 0; j < n[1]; j++)
                    for (size_t i = 0; i < n[0]; i++, t++) {
                        const size_t blocks = (size_t)whole[0].len[i] * (size_t)whole[1].len[j] * (size_t)whole[2].len[k];
                        band_stat *o = &st[t * (size_t)b->nbands + (size_t)qi];
                        o->a = red[t];
                        o->b = q->tailw > 0 && blocks <= WHOLE_SCAN_MAX ? red2[t] : q->gmax;
                        o->wabs = 0.0;
                    }
        }
    }
    for (size_t t = 0; t < nbox; t++) combine(b, st + t * (size_t)b->nbands, &range[2 * t], &range[2 * t + 1]);
    free(wbuf);
    free(tmp1);
    free(st);
    return 1;
}
