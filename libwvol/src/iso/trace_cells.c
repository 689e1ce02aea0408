/* SPDX-License-Identifier: MIT
 * Rigorous bounds of f^ on boxes for the implicit-surface ray tracer: per-store constants
 * (wvol__iso_boxk), the range of f^ on a box from the functions touching it
 * (wvol__iso_box_range), and the cell grid an image's rays step over where f^ cannot
 * reach iso (wvol__trace_cells). Based on: DESIGN.md section 9; docs/iso.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "iso_internal.h"

#define CELL 8.0           /* cell grid side, voxels */

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
}

/* The product of s over the transformed axes other than `skip` (-1: all). */
static void s_product(const wvol__iso_boxk *k, int skip, double *lo, double *hi)
{
    int a;
    *lo = *hi = 1;
    for (a = 0; a < 3; a++)
        if (a != skip && k->transformed[a]) imul(*lo, *hi, k->s1[0], k->s1[1], lo, hi);
}

wvol_status wvol__iso_box_range(const wvol__iso_boxk *k, const wvol_store *s, wvol_store_hits *hl, const double lo[3],
                                const double hi[3], double *vmin, double *vmax, wvol_error *err)
{
    size_t i, nlow = 0;
    double a0 = 0, pbar[3] = {0, 0, 0}, g[3] = {0, 0, 0}, sxx[3] = {0, 0, 0}, dev = 0, mag = 0, blo, bhi, t0, t1;
    int a;
    WVOL_FORWARD(wvol_store_query_box(s, lo, hi, hl, err));
    /* low-pass coefficients ~ a0 + g . (p - pbar), least squares over the touching ones
     * (p: the function's position on the level-M grid, periodic images included) */
    for (i = 0; i < hl->count; i++) {
        const wvol_store_hit *h = &hl->hits[i];
        if (h->band != 0) continue;
        nlow++;
        a0 += h->value;
        for (a = 0; a < 3; a++)
            if (k->transformed[a]) pbar[a] += (h->lo[a] + k->shift) / k->scale;
    }
    if (nlow) {
        a0 /= (double)nlow;
        for (a = 0; a < 3; a++) pbar[a] /= (double)nlow;
        for (i = 0; i < hl->count; i++) {
            const wvol_store_hit *h = &hl->hits[i];
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
    for (i = 0; i < hl->count; i++) {
        const wvol_store_hit *h = &hl->hits[i];
        double c = h->value;
        if (h->band == 0)
            for (a = 0, c -= a0; a < 3; a++)
                if (k->transformed[a]) c -= g[a] * ((h->lo[a] + k->shift) / k->scale - pbar[a]);
        dev += fabs(c) * k->fb[h->level][h->band];
        mag += fabs((double)h->value) * k->fb[h->level][h->band];
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
    dev += 1e-9 * (mag + fabs(blo) + fabs(bhi)); /* rounding of the sums */
    *vmin = blo - dev;
    *vmax = bhi + dev;
    return WVOL_OK;
}

/* Class of the closed box of cell idx (side `side` voxels): 1 when f^ > iso on all of it,
 * 0 when f^ < iso, -1 undecided. */
static int box_class(const tracer *tr, wvol_store_hits *hl, double side, const size_t idx[3], int *bad)
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz};
    double lo[3], hi[3], blo, bhi;
    int k;
    for (k = 0; k < 3; k++) {
        lo[k] = (double)idx[k] * side;
        hi[k] = fmin(lo[k] + side, n[k] > 1 ? (double)n[k] - 1 : 0.0);
    }
    if (wvol__iso_box_range(&tr->k, tr->g.s, hl, lo, hi, &blo, &bhi, NULL) != WVOL_OK) {
        (*bad)++;
        return -1;
    }
    return blo > tr->iso ? 1 : bhi < tr->iso ? 0 : -1;
}

/* Classifies cells of CELL voxels by wvol__iso_box_range, then halves the undecided ones
 * (cells of CELL/2; the decided ones pass their class on). Threads over cells. */
wvol_status wvol__trace_cells(tracer *tr, int nth, wvol_error *err)
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz}, nc[3], total = 1, ftotal = 1;
    signed char *coarse;
    int a, bad = 0;
    for (a = 0; a < 3; a++) {
        nc[a] = n[a] > 1 ? (size_t)ceil(((double)n[a] - 1) / CELL) : 1;
        tr->nc[a] = n[a] > 1 ? (size_t)ceil(((double)n[a] - 1) / (0.5 * CELL)) : 1;
        total *= nc[a];
        ftotal *= tr->nc[a];
    }
    tr->cell = 0.5 * CELL;
    coarse = malloc(total);
    tr->cls = malloc(ftotal);
    if (!coarse || !tr->cls) {
        free(coarse);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "iso trace: out of memory for %zu cells", ftotal);
    }
#pragma omp parallel num_threads(nth) reduction(+ : bad)
    {
        wvol_store_hits hl;
        memset(&hl, 0, sizeof hl);
#pragma omp for schedule(dynamic, 16)
        for (long c = 0; c < (long)total; c++) {
            size_t idx[3] = {(size_t)c % nc[0], ((size_t)c / nc[0]) % nc[1], (size_t)c / (nc[0] * nc[1])};
            coarse[c] = (signed char)box_class(tr, &hl, CELL, idx, &bad);
        }
#pragma omp for schedule(dynamic, 64)
        for (long c = 0; c < (long)ftotal; c++) {
            size_t idx[3] = {(size_t)c % tr->nc[0], ((size_t)c / tr->nc[0]) % tr->nc[1],
                             (size_t)c / (tr->nc[0] * tr->nc[1])};
            size_t p = idx[0] / 2 + nc[0] * (idx[1] / 2 + nc[1] * (idx[2] / 2));
            tr->cls[c] =
                coarse[p] >= 0 ? coarse[p] : (signed char)box_class(tr, &hl, 0.5 * CELL, idx, &bad);
        }
        wvol_store_hits_free(&hl);
    }
    free(coarse);
    WVOL_RETURN_IF(bad, err, WVOL_ERR_INTERNAL, "iso trace: store bounds failed on %d cells", bad);
    return WVOL_OK;
}
