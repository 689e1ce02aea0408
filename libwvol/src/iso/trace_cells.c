/* SPDX-License-Identifier: MIT
 * Rigorous bounds of f^ on boxes for the implicit-surface ray tracer: per-store constants
 * (wvol__iso_boxk), the range of f^ on a box from the functions touching it
 * (wvol__iso_box_range), and the lazily classified cell hierarchy an image's rays step over
 * where f^ cannot reach iso (wvol__trace_cells, wvol__trace_cell_class).
 * Based on: DESIGN.md section 9; docs/iso.md; Moore 1966 (interval arithmetic). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "core/clock.h"
#include "iso_internal.h"

#define CELL_FINE 2.0      /* the finest cells' side, voxels (doubled for large volumes: MAX_FINE_CELLS);
                              level L has 2^(LEVELS - 1 - L) times it */
#define MAX_FINE_CELLS 33554432.0 /* 32 MiB of finest classes at most */
#define CELL_UNKNOWN (-2)  /* not classified yet */
#define CELL_FINAL (-3)    /* undecided, and its children would be too (box_class): not refined */
#define STOP_SIDE 8.0      /* cells of this side or less may be left unrefined (box_class); larger
                              ones always are refined: their bounds include far functions */
/* ... when their bound would need to shrink more than tr->refine_gain: REFINE_GAIN_PER_RAY
 * times the rays across a finest cell's side, within [MIN, MAX] (wvol__trace_cells) */
#define REFINE_GAIN_PER_RAY 4.0
#define REFINE_GAIN_MIN 2.0
#define REFINE_GAIN_MAX 8.0
#define TENSOR_MIN_RAYS 2.0    /* rays across a finest cell's side for its tensor range */
#define TENSOR_REFINE_GAIN 16.0 /* the refinement gain with the tensor ranges */

int wvol__trace_tensor_off = 0;

typedef wvol__tracer tracer;

/* Range over [0, 1] of the polynomial a (degree deg <= 4): the hull of its Bernstein
 * coefficients, padded for rounding. */
static void bern_range(const double *a, int deg, double *lo, double *hi)
{
    static const double C[5][5] = {{1}, {1, 1}, {1, 2, 1}, {1, 3, 3, 1}, {1, 4, 6, 4, 1}};
    int j, i;
    for (j = 0; j <= deg; j++) {
        double b = 0, mag = 0;
        for (i = 0; i <= j; i++) {
            double t = C[j][i] / C[deg][i] * a[i];
            b += t;
            mag += fabs(t);
        }
        *lo = fmin(*lo, b - 1e-12 * mag);
        *hi = fmax(*hi, b + 1e-12 * mag);
    }
}

/* Ranges over all y of s(y) = sum_p phi(y - p) (the spline phi's partition of unity, ~1)
 * and m(y) = sum_p (y - p) phi(y - p) (its first moment, ~ the centre): per piece of the
 * unit, sums of the pieces' cubics (times the linear y - p for m). */
static void phi_sums_range(const wvol_basis *b, double s[2], double m[2])
{
    int j, q, k;
    s[0] = m[0] = INFINITY;
    s[1] = m[1] = -INFINITY;
    for (j = 0; j < b->per_unit && j < b->pieces; j++) {
        double c[4] = {0, 0, 0, 0}, c4[5] = {0, 0, 0, 0, 0}, hk = 1;
        for (q = j; q < b->pieces; q += b->per_unit) {
            const double *pc = wvol_basis_coeffs(b, WVOL_BASIS_PHI, WVOL_BASIS_VALUE, q);
            double v0 = q * b->h; /* y - p = v0 + u on this piece */
            for (k = 0; k < 4; k++) {
                c[k] += pc[k];
                c4[k] += v0 * pc[k];
                c4[k + 1] += pc[k];
            }
        }
        for (k = 0; k < 5; k++, hk *= b->h) { /* in u / h on [0, 1] */
            if (k < 4) c[k] *= hk;
            c4[k] *= hk;
        }
        bern_range(c, 3, &s[0], &s[1]);
        bern_range(c4, 4, &m[0], &m[1]);
    }
}

/* Interval product. */
static void imul(double a0, double a1, double b0, double b1, double *lo, double *hi)
{
    double p[4] = {a0 * b0, a0 * b1, a1 * b0, a1 * b1};
    *lo = fmin(fmin(p[0], p[1]), fmin(p[2], p[3]));
    *hi = fmax(fmax(p[0], p[1]), fmax(p[2], p[3]));
}

void wvol__iso_boxk_init(wvol__iso_boxk *k, const wvol_store *s)
{
    wvol_store_info info;
    const wvol_basis *b = wvol_store_basis(s);
    int m, l, a;
    memset(k, 0, sizeof *k);
    wvol_store_get_info(s, &info);
    k->levels = info.levels;
    for (m = 1; m <= info.levels; m++)
        for (l = 0; l < 8; l++) wvol_store_function_bounds(s, m, l, &k->fb[m][l], NULL);
    phi_sums_range(b, k->s1, k->m1);
    for (a = 0; a < 3; a++) k->transformed[a] = info.transformed[a];
    k->norm = pow(2.0, -0.5 * info.levels * (info.transformed[0] + info.transformed[1] + info.transformed[2]));
    k->scale = ldexp(1.0, info.levels);
    k->shift = b->center;
    for (m = 0; m <= WVOL_SELECT_MAX_LEVELS; m++) k->inv_size[m] = ldexp(1.0, -m);
    k->pieces = b->pieces;
    k->per_unit = b->per_unit;
    k->support = b->support;
    for (k->runs = 1; (1L << k->runs) <= b->pieces; k->runs++) {}
    k->basis = b;
    k->h = b->h;
    {
        double bm[2] = {0, 0};
        int w, band, a2;
        for (w = 0; w < 2; w++)
            for (int i = 0; i < b->pieces; i++) {
                double lo, hi;
                wvol_basis_piece_range(b, w, i, &lo, &hi);
                bm[w] = fmax(bm[w], fmax(fabs(lo), fabs(hi)));
            }
        for (band = 0; band < 8; band++) {
            k->bmax3[band] = 1;
            k->lip3[band] = 0;
            for (a2 = 0; a2 < 3; a2++) {
                int wa = (band >> a2) & 1;
                double o = b->dmax[wa];
                k->bmax3[band] *= bm[wa];
                for (w = 0; w < 3; w++)
                    if (w != a2) o *= b->vmax[(band >> w) & 1];
                k->lip3[band] += o;
            }
        }
    }
    k->prange = malloc((size_t)k->runs * (size_t)b->pieces * 4 * sizeof *k->prange);
    if (k->prange) { /* no table: every factor falls back to its global max (fb), as correct */
        for (int i = 0; i < b->pieces; i++)
            for (int w = 0; w < 2; w++)
                wvol_basis_piece_range(b, w, i, &k->prange[4 * (size_t)i + 2 * w], &k->prange[4 * (size_t)i + 2 * w + 1]);
        for (int r = 1; r < k->runs; r++)
            for (int i = 0; i + (1 << r) <= b->pieces; i++) {
                double *q = k->prange + 4 * ((size_t)r * b->pieces + i);
                const double *x = k->prange + 4 * ((size_t)(r - 1) * b->pieces + i),
                             *y = k->prange + 4 * ((size_t)(r - 1) * b->pieces + i + (1 << (r - 1)));
                for (int j = 0; j < 4; j++) q[j] = (j & 1) ? fmax(x[j], y[j]) : fmin(x[j], y[j]);
            }
    }
}

void wvol__iso_boxk_free(wvol__iso_boxk *k)
{
    if (!k) return;
    free(k->prange);
    k->prange = NULL;
}

static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

/* The range of the 1D factor `which` (phi 0, psi 1) over its variable's interval [u0, u1]
 * (0 outside the support [0, support]): the hull of the pieces the interval covers, from two
 * overlapping runs of the sparse table. */
static inline void factor_range(const wvol__iso_boxk *k, int which, double u0, double u1, double *lo, double *hi)
{
    double a0 = u0 * k->per_unit, a1 = u1 * k->per_unit, pu = k->pieces;
    long i0, i1;
    int r;
    const double *x, *y;
    /* a knot's rounding could put a point in either neighbour: take both */
    a0 -= 1e-9 * (1 + (a0 < 0 ? -a0 : a0));
    a1 += 1e-9 * (1 + (a1 < 0 ? -a1 : a1));
    if (a1 < 0 || a0 >= pu) { /* misses the support */
        *lo = *hi = 0.0;
        return;
    }
    i0 = a0 <= 0 ? 0 : (long)a0;
    i1 = a1 >= pu ? (long)pu - 1 : (long)a1;
    r = 63 - __builtin_clzll((unsigned long long)(i1 - i0 + 1)); /* 2^r <= run < 2^(r+1) */
    x = k->prange + 4 * ((size_t)r * (size_t)k->pieces + (size_t)i0) + 2 * which;
    y = k->prange + 4 * ((size_t)r * (size_t)k->pieces + (size_t)(i1 - (1L << r) + 1)) + 2 * which;
    *lo = dmin(x[0], y[0]);
    *hi = dmax(x[1], y[1]);
    if (u0 < 0.0 || u1 > k->support) { /* the box reaches outside the support, where w = 0 */
        *lo = dmin(*lo, 0.0);
        *hi = dmax(*hi, 0.0);
    }
}

/* The product of s over the transformed axes other than `skip` (-1: all). */
static void s_product(const wvol__iso_boxk *k, int skip, double *lo, double *hi)
{
    int a;
    *lo = *hi = 1;
    for (a = 0; a < 3; a++)
        if (a != skip && k->transformed[a]) imul(*lo, *hi, k->s1[0], k->s1[1], lo, hi);
}

/* The factors' ranges on one box, shared by the functions with the same (level, axis, image
 * translate j, band bit): a function's support on axis a is [j 2^m - s, (j + support) 2^m - s]
 * (every image with the same j has these bounds bit for bit), so the cached range is the one
 * factor_range computes for each of them. Levels above FC_LEVELS, or translates outside the
 * span a box can meet, go to factor_range directly. */
#define FC_SPAN 40
#define FC_LEVELS 8

typedef struct fcache {
    int64_t j0[FC_LEVELS + 1][3];
    int span[FC_LEVELS + 1][3];
    unsigned char have[FC_LEVELS + 1][3][FC_SPAN][2];
    double r[FC_LEVELS + 1][3][FC_SPAN][2][2];
} fcache;

static void fcache_init(fcache *fc, const wvol__iso_boxk *k, const double lo[3], const double hi[3])
{
    int m, a;
    for (m = 1; m <= k->levels && m <= FC_LEVELS; m++)
        for (a = 0; a < 3; a++) {
            double sc = k->inv_size[m];
            int64_t j0 = (int64_t)floor((lo[a] + k->shift) * sc - k->support) - 1;
            int64_t j1 = (int64_t)floor((hi[a] + k->shift) * sc) + 1;
            fc->j0[m][a] = j0;
            fc->span[m][a] = j1 - j0 + 1 <= FC_SPAN ? (int)(j1 - j0 + 1) : 0; /* 0: no cache on this axis */
            memset(fc->have[m][a], 0, sizeof fc->have[m][a]);
        }
}

/* factor_range of function h's factor on axis a over [lo_a, hi_a], through the cache. */
static inline void factor_cached(fcache *fc, const wvol__iso_boxk *k, const wvol_store_hit *h, int a, const double lo[3],
                                 const double hi[3], double *flo, double *fhi)
{
    int m = h->level, which = (h->band >> a) & 1;
    double sc = k->inv_size[m];
    int64_t j = m <= FC_LEVELS ? (int64_t)floor((h->lo[a] + k->shift) * sc + 0.5) - fc->j0[m][a] : -1;
    if (j >= 0 && j < fc->span[m][a]) {
        double *r = fc->r[m][a][j][which];
        if (!fc->have[m][a][j][which]) {
            factor_range(k, which, (lo[a] - h->lo[a]) * sc, (hi[a] - h->lo[a]) * sc, &r[0], &r[1]);
            fc->have[m][a][j][which] = 1;
        }
        *flo = r[0], *fhi = r[1];
        return;
    }
    factor_range(k, which, (lo[a] - h->lo[a]) * sc, (hi[a] - h->lo[a]) * sc, flo, fhi);
}

/* c w on the box lies in c [plo, phi] (plo = phi = the function's norm on entry): the product of
 * the factors' ranges there; adds its midpoint to *mid and its half-width to *dev. */
static inline void fn_interval(const wvol__iso_boxk *k, fcache *fc, const wvol_store_hit *h, double c, double plo,
                               double phi, const double lo[3], const double hi[3], double *mid, double *dev)
{
    int a;
    for (a = 0; a < 3; a++) {
        double flo, fhi, p0, p1, p2, p3;
        if (!k->transformed[a]) continue;
        factor_cached(fc, k, h, a, lo, hi, &flo, &fhi);
        /* the four products, no branch on their signs (which are unpredictable): rounding is
         * monotone, so the extreme rounded product is the rounded extreme one */
        p0 = plo * flo, p1 = plo * fhi, p2 = phi * flo, p3 = phi * fhi;
        plo = dmin(dmin(p0, p1), dmin(p2, p3));
        phi = dmax(dmax(p0, p1), dmax(p2, p3));
    }
    *mid += c * 0.5 * (plo + phi);
    *dev += fabs(c) * 0.5 * (phi - plo);
}

WVOL__CLONES void wvol__iso_box_range_list(const wvol__iso_boxk *k, const wvol_store_hit *hits, size_t n, const double lo[3],
                              const double hi[3], double *vmin, double *vmax, double *fine)
{
    double fmid = 0, fdev = 0, fmag = 0;
    size_t i, nlow = 0;
    double a0 = 0, pbar[3] = {0, 0, 0}, g[3] = {0, 0, 0}, sxx[3] = {0, 0, 0}, dev = 0, mid = 0, mag = 0, blo, bhi, t0,
           t1;
    int a;
    fcache fc;
    if (k->prange) fcache_init(&fc, k, lo, hi);
    /* low-pass coefficients ~ a0 + g . (p - pbar), least squares over the touching ones
     * (p: the function's position on the level-M grid, periodic images included) */
    for (i = 0; i < n; i++) {
        const wvol_store_hit *h = &hits[i];
        if (h->band != 0) continue;
        nlow++;
        a0 += h->value;
        for (a = 0; a < 3; a++)
            if (k->transformed[a]) pbar[a] += (h->lo[a] + k->shift) / k->scale;
    }
    if (nlow) {
        a0 /= (double)nlow;
        for (a = 0; a < 3; a++) pbar[a] /= (double)nlow;
        for (i = 0; i < n; i++) {
            const wvol_store_hit *h = &hits[i];
            if (h->band != 0) continue;
            for (a = 0; a < 3; a++)
                if (k->transformed[a]) {
                    double dp = (h->lo[a] + k->shift) / k->scale - pbar[a];
                    g[a] += (double)h->value * dp;
                    sxx[a] += dp * dp;
                }
        }
        for (a = 0; a < 3; a++) g[a] = sxx[a] > 0 ? g[a] / sxx[a] : 0.0;
    }
    for (i = 0; i < n; i++) {
        const wvol_store_hit *h = &hits[i];
        double c = h->value, plo = h->norm, phi = h->norm;
        if (h->band == 0)
            for (a = 0, c -= a0; a < 3; a++)
                if (k->transformed[a]) c -= g[a] * ((h->lo[a] + k->shift) / k->scale - pbar[a]);
        mag += fabs((double)h->value) * k->fb[h->level][h->band];
        if (!k->prange) {
            dev += fabs(c) * k->fb[h->level][h->band];
            continue;
        }
        if (h->level < k->levels) { /* a finer level's: also summed apart (fine) */
            double m1 = 0, d1 = 0;
            fn_interval(k, &fc, h, c, plo, phi, lo, hi, &m1, &d1);
            mid += m1, dev += d1;
            fmid += m1, fdev += d1;
            fmag += fabs((double)h->value) * k->fb[h->level][h->band];
        } else {
            fn_interval(k, &fc, h, c, plo, phi, lo, hi, &mid, &dev);
        }
    }
    if (fine) {
        fine[0] = fmid;
        fine[1] = fdev + 1e-9 * (fmag + fabs(fmid)); /* rounding of the sums, as below */
    }
    /* a0 sum_p w_p = a0 norm S(x) */
    s_product(k, -1, &t0, &t1);
    imul(a0 * k->norm, a0 * k->norm, t0, t1, &blo, &bhi);
    /* g_a sum_p (p_a - pbar_a) w_p = g_a norm [(y_a - pbar_a) s(y_a) - m(y_a)] prod_{b != a} s(y_b) */
    for (a = 0; a < 3; a++) {
        double y0, y1, l0, l1, o0, o1;
        if (!k->transformed[a] || g[a] == 0.0) continue;
        y0 = (lo[a] + k->shift) / k->scale - pbar[a];
        y1 = (hi[a] + k->shift) / k->scale - pbar[a];
        imul(y0, y1, k->s1[0], k->s1[1], &l0, &l1);
        l0 -= k->m1[1];
        l1 -= k->m1[0];
        s_product(k, a, &o0, &o1);
        imul(l0, l1, o0, o1, &l0, &l1);
        imul(g[a] * k->norm, g[a] * k->norm, l0, l1, &l0, &l1);
        blo += l0;
        bhi += l1;
    }
    blo += mid;
    bhi += mid;
    dev += 1e-9 * (mag + fabs(blo) + fabs(bhi)); /* rounding of the sums */
    *vmin = blo - dev;
    *vmax = bhi + dev;
}

wvol_status wvol__iso_box_range(const wvol__iso_boxk *k, const wvol_store *s, wvol_store_hits *hl, const double lo[3],
                                const double hi[3], double *vmin, double *vmax, wvol_error *err)
{
    WVOL_FORWARD(wvol_store_query_box(s, lo, hi, hl, err));
    wvol__iso_box_range_list(k, hl->hits, hl->count, lo, hi, vmin, vmax, NULL);
    return WVOL_OK;
}

/* Class of the closed box [lo, hi] from the functions touching it: 1 when f^ > iso on all of
 * it, 0 when f^ < iso, -1 undecided (its children will be looked at) or CELL_FINAL (undecided,
 * and not refined; also when hits is NULL, a failed query: tracing a cell exactly is always
 * right). may_stop: the box is small enough to be left unrefined. */
static int box_class(const tracer *tr, wvol__cell_ws *w, const wvol_store_hits *hits, const double lo[3],
                     const double hi[3], int may_stop, int finest)
{
    double blo, bhi, hw, gap, fine[2];
    if (!hits) return CELL_FINAL;
    wvol__iso_box_range_list(&tr->k, hits->hits, hits->count, lo, hi, &blo, &bhi, fine);
    if (blo > tr->iso) return 1;
    if (bhi < tr->iso) return 0;
    /* a finest cell the interval range leaves undecided: the tensor range (dense rays only) */
    if (finest && w && tr->tensor) {
        int c;
        if (!w->tt) w->tt = calloc(1, sizeof *w->tt);
        if (w->tt && (c = wvol__iso_box_class_tensor(&tr->k, w->tt, hits->hits, hits->count, lo, hi, fine, tr->iso)) >= 0)
            return c;
    }
    /* would halving the cell help? Only if the children's bounds could exclude iso, which
     * needs them tr->refine_gain times narrower than this one, or more: then they are not worth
     * their queries, and the rays trace this cell exactly */
    hw = 0.5 * (bhi - blo);
    gap = fabs(0.5 * (bhi + blo) - tr->iso);
    return may_stop && hw > tr->refine_gain * gap ? CELL_FINAL : -1;
}

void wvol__cell_ws_free(wvol__cell_ws *w)
{
    int L;
    for (L = 0; L < WVOL__CELL_LEVELS; L++) wvol_store_hits_free(&w->q[L]);
    if (w->tt) free(w->tt->order);
    free(w->tt);
    memset(w, 0, sizeof *w);
}

int wvol__iso_hits_in_box(const wvol_store_hits *src, const double lo[3], const double hi[3], wvol_store_hits *dst)
{
    size_t i, n = 0;
    if (dst->capacity < src->count) {
        wvol_store_hit *q = realloc(dst->hits, src->count * sizeof *q);
        if (!q) return 0;
        dst->hits = q;
        dst->capacity = src->count;
    }
    for (i = 0; i < src->count; i++) {
        const wvol_store_hit *h = &src->hits[i];
        if (h->hi[0] < lo[0] || h->lo[0] > hi[0] || h->hi[1] < lo[1] || h->lo[1] > hi[1] || h->hi[2] < lo[2] ||
            h->lo[2] > hi[2])
            continue;
        dst->hits[n++] = *h;
    }
    dst->count = n;
    return 1;
}

static int same_box(const double a0[3], const double a1[3], const double b0[3], const double b1[3])
{
    return a0[0] == b0[0] && a0[1] == b0[1] && a0[2] == b0[2] && a1[0] == b1[0] && a1[1] == b1[1] && a1[2] == b1[2];
}

/* The functions touching the level-L cell [lo, hi] (its parent [plo, phi]) into w->q[L]: filtered
 * from the parent's list when this thread holds it (the parent was classified, or its list
 * filtered, last at its level: consecutive cells along a ray share parents), else queried.
 * Querying a parent that is not held, only for its children to filter, does not pay.
 * NULL when a query fails. */
static const wvol_store_hits *cell_hits(const tracer *tr, wvol__cell_ws *w, int L, const double lo[3], const double hi[3],
                                        const double plo[3], const double phi[3])
{
    int a;
    w->have[L] = 0;
    if (L > 0 && w->have[L - 1] && same_box(w->lo[L - 1], w->hi[L - 1], plo, phi)) {
        if (!wvol__iso_hits_in_box(&w->q[L - 1], lo, hi, &w->q[L])) return NULL;
    } else if (wvol_store_query_box(tr->g.s, lo, hi, &w->q[L], NULL) != WVOL_OK) {
        return NULL;
    }
    w->have[L] = 1;
    for (a = 0; a < 3; a++) w->lo[L][a] = lo[a], w->hi[L][a] = hi[a];
    return &w->q[L];
}

wvol_status wvol__trace_cells(tracer *tr, double spacing, wvol_error *err)
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz};
    int L, a;
    /* the finest side: CELL_FINE, doubled while the finest level would hold more than
     * MAX_FINE_CELLS (one byte each: large volumes keep a bounded grid) */
    tr->cell = CELL_FINE;
    for (;;) {
        double c = 1;
        for (a = 0; a < 3; a++) c *= n[a] > 1 ? ceil(((double)n[a] - 1) / tr->cell) : 1;
        if (c <= MAX_FINE_CELLS) break;
        tr->cell *= 2;
    }
    for (L = 0; L < WVOL__CELL_LEVELS; L++) {
        double side = tr->cell * (double)(1 << (WVOL__CELL_LEVELS - 1 - L));
        size_t total = 1;
        for (a = 0; a < 3; a++) {
            tr->ncl[L][a] = n[a] > 1 ? (size_t)ceil(((double)n[a] - 1) / side) : 1;
            total *= tr->ncl[L][a];
        }
        tr->cls[L] = malloc(total);
        if (!tr->cls[L]) return wvol_error_set(err, WVOL_ERR_NOMEM, "iso trace: out of memory for %zu cells", total);
        memset(tr->cls[L], CELL_UNKNOWN, total);
    }
    for (a = 0; a < 3; a++) tr->nc[a] = tr->ncl[WVOL__CELL_LEVELS - 1][a];
    /* a cell's classification is paid once, what it saves once per ray crossing it: the sparser
     * the rays, the less refining pays (bench/results/iso_trace_profile.md, "Refinement by ray
     * density") */
    tr->refine_gain = REFINE_GAIN_MAX;
    tr->tensor = 0;
    if (spacing > 0 && isfinite(spacing)) {
        tr->refine_gain = fmax(REFINE_GAIN_MIN, fmin(REFINE_GAIN_MAX, REFINE_GAIN_PER_RAY * tr->cell / spacing));
        /* the finest cells' tensor ranges cost several interval ranges each: they pay where
         * TENSOR_MIN_RAYS or more rays cross a finest cell's side (bench/results/iso_trace_profile.md,
         * "Tensor ranges"); the cells they can decide are then worth refining down to */
        if (tr->cell / spacing >= TENSOR_MIN_RAYS && !wvol__trace_tensor_off) {
            tr->tensor = 1;
            tr->refine_gain = TENSOR_REFINE_GAIN;
        }
    }
    return WVOL_OK;
}

void wvol__trace_cells_free(tracer *tr)
{
    int L;
    for (L = 0; L < WVOL__CELL_LEVELS; L++) {
        free(tr->cls[L]);
        tr->cls[L] = NULL;
    }
}

/* Index of the level-L cell holding x (voxel coords), clamped to the grid. */
static size_t cell_index(const tracer *tr, int L, const double x[3], double side, double lo[3], double hi[3])
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz}, idx = 0, stride = 1;
    int a;
    for (a = 0; a < 3; a++) {
        double c = floor(x[a] / side);
        size_t ci = c < 0 ? 0 : (size_t)c;
        if (ci >= tr->ncl[L][a]) ci = tr->ncl[L][a] - 1;
        idx += ci * stride;
        stride *= tr->ncl[L][a];
        lo[a] = (double)ci * side;
        hi[a] = fmin(lo[a] + side, n[a] > 1 ? (double)n[a] - 1 : 0.0);
    }
    return idx;
}

int wvol__trace_cell_class(const tracer *tr, wvol__cell_ws *w, const double x[3], size_t *evaluated, double *seconds)
{
    int L, c = -1;
    double plo[3] = {0, 0, 0}, phi[3] = {0, 0, 0};
    for (L = 0; L < WVOL__CELL_LEVELS; L++) {
        double side = tr->cell * (double)(1 << (WVOL__CELL_LEVELS - 1 - L)), lo[3], hi[3];
        size_t idx = cell_index(tr, L, x, side, lo, hi);
        signed char *slot = tr->cls[L] + idx;
        c = __atomic_load_n(slot, __ATOMIC_RELAXED);
        if (c == CELL_UNKNOWN) {
            /* a pure function of the box: threads racing here store the same value */
            double t0 = seconds ? wvol__now() : 0.0;
            c = box_class(tr, w, cell_hits(tr, w, L, lo, hi, plo, phi), lo, hi, side <= STOP_SIDE,
                          L == WVOL__CELL_LEVELS - 1);
            __atomic_store_n(slot, (signed char)c, __ATOMIC_RELAXED);
            if (evaluated) (*evaluated)++;
            if (seconds) *seconds += wvol__now() - t0;
        }
        if (c >= 0) return c;
        if (c == CELL_FINAL) return -1;
        memcpy(plo, lo, sizeof plo);
        memcpy(phi, hi, sizeof phi);
    }
    return c;
}

void wvol__trace_cells_top(const tracer *tr, wvol_store_hits *hl, size_t cnt[3])
{
    size_t i, total = tr->ncl[0][0] * tr->ncl[0][1] * tr->ncl[0][2];
    double side = tr->cell * (double)(1 << (WVOL__CELL_LEVELS - 1));
    cnt[0] = cnt[1] = cnt[2] = 0;
    for (i = 0; i < total; i++) {
        double x[3], lo[3], hi[3];
        size_t j = i, a;
        signed char c;
        for (a = 0; a < 3; a++) {
            x[a] = ((double)(j % tr->ncl[0][a]) + 0.5) * side;
            j /= tr->ncl[0][a];
        }
        cell_index(tr, 0, x, side, lo, hi);
        c = __atomic_load_n(tr->cls[0] + i, __ATOMIC_RELAXED);
        if (c == CELL_UNKNOWN)
            c = (signed char)box_class(tr, NULL, wvol_store_query_box(tr->g.s, lo, hi, hl, NULL) == WVOL_OK ? hl : NULL,
                                       lo, hi, side <= STOP_SIDE, 0);
        tr->cls[0][i] = c;
        if (c == CELL_FINAL) c = -1;
        cnt[c + 1]++;
    }
}

size_t wvol__trace_cells_undecided(const tracer *tr)
{
    size_t i, u = 0;
    int L;
    for (L = 0; L < WVOL__CELL_LEVELS; L++) {
        size_t total = tr->ncl[L][0] * tr->ncl[L][1] * tr->ncl[L][2];
        for (i = 0; i < total; i++) u += tr->cls[L][i] == CELL_FINAL || (L == WVOL__CELL_LEVELS - 1 && tr->cls[L][i] == -1);
    }
    return u;
}
