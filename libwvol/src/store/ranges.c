/* SPDX-License-Identifier: MIT */
/* Rigorous value ranges of the basis splines (phi, psi and their derivatives)
 * over any interval, for the store's value and gradient bounds.
 *
 * Each spline piece is a cubic on [0, h]; its exact range comes from the ends
 * and the real roots of its derivative inside. Every piece range is then padded
 * for rounding in the evaluation (16 eps times the sum of the terms' magnitudes)
 * and for a neighbouring piece evaluated a rounding error outside its interval
 * (1e-12 of the table's largest value). These ranges bound the spline model f^
 * (what every evaluator samples). The global maxima used for the per-node
 * bounds (wvol__ranges_periodic_max) add the spline's measured error against the
 * cascade (wvol_basis.spline_error) on top, so they hold for the cascade's phi
 * and psi as well. A segment tree over the pieces answers a range query in
 * O(log pieces); queries widen by one piece each side. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "store/store_internal.h"

static void cubic_range(const double *c, double h, double *lo, double *hi)
{
    double v0 = wvol__horner3(c, 0.0), v1 = wvol__horner3(c, h), mn = v0 < v1 ? v0 : v1, mx = v0 < v1 ? v1 : v0;
    /* roots of c1 + 2 c2 u + 3 c3 u^2 */
    double A = 3.0 * c[3], B = 2.0 * c[2], C = c[1], r[2];
    int nr = 0;
    if (A != 0.0) {
        double disc = B * B - 4.0 * A * C;
        if (disc >= 0.0) {
            double sq = sqrt(disc), qq = -0.5 * (B + (B >= 0 ? sq : -sq));
            if (qq != 0.0) r[nr++] = qq / A, r[nr++] = C / qq;
            else r[nr++] = 0.0;
        }
    } else if (B != 0.0) {
        r[nr++] = -C / B;
    }
    for (int i = 0; i < nr; i++)
        if (r[i] > 0.0 && r[i] < h) {
            double v = wvol__horner3(c, r[i]);
            if (v < mn) mn = v;
            if (v > mx) mx = v;
        }
    /* rounding of the evaluation, and of the root itself (a sampled max is a max) */
    double mag = fabs(c[0]) + fabs(c[1]) * h + fabs(c[2]) * h * h + fabs(c[3]) * h * h * h;
    *lo = mn - 16.0 * DBL_EPSILON * mag;
    *hi = mx + 16.0 * DBL_EPSILON * mag;
}

wvol_status wvol__ranges_build(wvol__ranges *rg, const wvol_basis *b, wvol_error *err)
{
    const double *tab[WVOL__KINDS];
    int n = 1;
    memset(rg, 0, sizeof *rg);
    WVOL_RETURN_IF(!b || b->pieces < 1 || !b->phi || !b->psi || !b->dphi || !b->dpsi, err, WVOL_ERR_INTERNAL,
                   "store: basis tables are missing");
    rg->pieces = b->pieces;
    rg->J = b->J;
    rg->per_unit = ldexp(1.0, b->J);
    rg->h = ldexp(1.0, -b->J);
    rg->support = b->support;
    WVOL_RETURN_IF(fabs(rg->pieces / rg->per_unit - rg->support) > 1e-9, err, WVOL_ERR_INTERNAL,
                   "store: basis has %d pieces at 2^%d per unit for support %g", b->pieces, b->J, b->support);
    while (n < rg->pieces) n <<= 1;
    rg->n = n;
    tab[WVOL__PHI] = b->phi, tab[WVOL__PSI] = b->psi, tab[WVOL__DPHI] = b->dphi, tab[WVOL__DPSI] = b->dpsi;
    double h = 1.0 / rg->per_unit;
    for (int k = 0; k < WVOL__KINDS; k++) {
        double *mn = malloc(2 * (size_t)n * sizeof *mn), *mx = malloc(2 * (size_t)n * sizeof *mx), big = 0.0, pad;
        if (!mn || !mx) {
            free(mn), free(mx);
            wvol__ranges_free(rg);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "store: out of memory for basis ranges");
        }
        rg->mn[k] = mn, rg->mx[k] = mx;
        for (int i = 0; i < n; i++) {
            double lo = INFINITY, hi = -INFINITY;
            if (i < rg->pieces) cubic_range(tab[k] + 4 * (size_t)i, h, &lo, &hi);
            mn[n + i] = lo, mx[n + i] = hi;
            if (i < rg->pieces) {
                if (fabs(lo) > big) big = fabs(lo);
                if (fabs(hi) > big) big = fabs(hi);
            }
        }
        pad = 1e-12 * big;
        for (int i = 0; i < rg->pieces; i++) mn[n + i] -= pad, mx[n + i] += pad;
        for (int i = n - 1; i >= 1; i--) {
            mn[i] = fmin(mn[2 * i], mn[2 * i + 1]);
            mx[i] = fmax(mx[2 * i], mx[2 * i + 1]);
        }
        rg->absmax[k] = fmax(fabs(mn[1]), fabs(mx[1]));
    }
    rg->spline_error = b->spline_error;
    return WVOL_OK;
}

void wvol__ranges_free(wvol__ranges *rg)
{
    for (int k = 0; k < WVOL__KINDS; k++) {
        free(rg->mn[k]), free(rg->mx[k]);
        rg->mn[k] = rg->mx[k] = NULL;
    }
}

void wvol__ranges_query(const wvol__ranges *rg, int kind, double u0, double u1, double *lo, double *hi)
{
    double mn = INFINITY, mx = -INFINITY;
    long i0, i1;
    if (!(u1 >= 0.0) || !(u0 <= rg->support) || u1 < u0) {
        *lo = *hi = 0.0;
        return;
    }
    /* the function is 0 outside its support: a box reaching past it sees 0 too */
    if (u0 < 0.0 || u1 > rg->support) mn = mx = 0.0;
    i0 = u0 <= 0.0 ? 0 : (long)floor(u0 * rg->per_unit) - 1;
    i1 = u1 >= rg->support ? rg->pieces - 1 : (long)floor(u1 * rg->per_unit) + 1;
    if (i0 < 0) i0 = 0;
    if (i1 > rg->pieces - 1) i1 = rg->pieces - 1;
    for (long a = i0 + rg->n, b = i1 + rg->n + 1; a < b; a >>= 1, b >>= 1) {
        if (a & 1) {
            mn = wvol__min(mn, rg->mn[kind][a]), mx = wvol__max(mx, rg->mx[kind][a]);
            a++;
        }
        if (b & 1) {
            b--;
            mn = wvol__min(mn, rg->mn[kind][b]), mx = wvol__max(mx, rg->mx[kind][b]);
        }
    }
    *lo = mn, *hi = mx;
}

double wvol__ranges_periodic_max(const wvol__ranges *rg, int kind, size_t period_pieces)
{
    double best = 0.0, extra = kind < WVOL__DPHI ? rg->spline_error : 0.0;
    size_t T = period_pieces, np = (size_t)rg->pieces;
    if (T == 0 || T >= np) return rg->absmax[kind] + extra;
    /* u and u + n T lie in pieces i and i + n T: the largest sum over one residue class */
    for (size_t r = 0; r < T; r++) {
        double sum = 0.0;
        size_t copies = 0;
        for (size_t i = r; i < np; i += T, copies++)
            sum += fmax(fabs(rg->mn[kind][rg->n + i]), fabs(rg->mx[kind][rg->n + i]));
        sum += (double)copies * extra;
        if (sum > best) best = sum;
    }
    return best * (1.0 + 1e-12);
}
