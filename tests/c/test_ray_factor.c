/* SPDX-License-Identifier: MIT
 * The factorised piece builder of store/ray_pieces.c (the default for values: per piece each
 * (axis, translate, band) cubic composed once, the sum formed as sum_x X sum_y Y sum_z c Z)
 * against the per-function builder it replaces, kept as the reference (ws.per_function):
 * on random rays (general, in a coordinate plane, axis-parallel) through random sparse stores
 * of every family with splines (db, coif: 1 to 4 levels; bl3: 1 and 2), and a slab volume whose z
 * axis is not transformed, every level's piece polynomials, the merged ones, and the
 * small functions added afterwards on a sub-range (wvol__spline_add_finest_list) agree.
 *
 * Bound: both sum the same composed cubics (bit-identical per axis) in a different order, so
 * they differ by rounding only. Every coefficient is a sum over the ray's functions of the
 * products of three cubics' coefficients; one function's product coefficients are at most
 * |c| norm vmax^3 G^3, G the largest monomial coefficient of a cubic bounded by 1 on [0, 1]
 * (32 for the shifted Chebyshev polynomial), and each sum's rounding is below 64 DBL_EPSILON
 * of the summed magnitudes: a difference below 64 eps 32^3 S ~ 4.7e-10 S, with
 * S = sum over the ray's functions of |c| norm vmax^3. The test allows TOL_REL S = 1e-9 S and
 * prints the largest difference / S measured (about 1e-16). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "store/store_ray.h"
#include "wvol/store.h"

#define NC WVOL__NC
#define TOL_REL 1e-9 /* of S (see above): the bound 64 eps 32^3 S with margin */

static uint64_t rs = 0x9E3779B97F4A7C15ull;
static double rnd(void)
{
    return fixture_urand(&rs);
}

/* The shell and blob plus uniform noise: coefficients in every band and level. */
static double noisy(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)ctx;
    return fixture_shell_blob(v, i, j, k, NULL) + 0.3 * (rnd() - 0.5);
}

static double worst_rel; /* largest difference / S measured */
static int compared, added; /* rays whose builds were compared with functions on them; and the add path */

/* Largest |a - b| over n coefficients. */
static double maxdiff(const double *a, const double *b, size_t n)
{
    double m = 0;
    size_t i;
    for (i = 0; i < n; i++) m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

static double ray_scale(const wvol__spline_geom *g, const wvol_store_hit *h, size_t n)
{
    double vm = fmax(g->b->vmax[0], g->b->vmax[1]), S = 0;
    size_t i;
    for (i = 0; i < n; i++) S += fabs((double)h[i].value) * g->norm[h[i].level] * vm * vm * vm;
    return S;
}

/* One ray: both builders, every level's pieces and the merged ones; then the second half of
 * the functions added to the merged pieces [elo, ehi) after a build from the first half. */
static void one_ray(const wvol__spline_geom *g, wvol__spline_ws *ref, wvol__spline_ws *fac, const double o[3],
                    const double d[3], double ta, double tb, const char *what)
{
    wvol__spline_count cr = {0, 0}, cf = {0, 0};
    wvol_error err;
    wvol_store_hit *copy;
    size_t n, half, E, elo, ehi;
    double S, diff = 0;
    int m;
    CHECK(wvol__spline_ray(g, ref, o, d, ta, tb, 0, 1, &cr, &err) == WVOL_OK, "%s: reference build", what);
    CHECK(wvol__spline_ray(g, fac, o, d, ta, tb, 0, 1, &cf, &err) == WVOL_OK, "%s: factorised build", what);
    n = ref->hits.count;
    CHECK(fac->hits.count == n, "%s: same functions", what);
    S = ray_scale(g, ref->hits.hits, n);
    for (m = 1; m <= g->info.levels; m++) {
        const wvol__level_ws *a = &ref->lev[m], *b = &fac->lev[m];
        CHECK(a->used == b->used && a->E == b->E, "%s: level %d used %d/%d, %zu/%zu pieces", what, m, a->used, b->used,
              a->E, b->E);
        if (a->used && a->E == b->E) diff = fmax(diff, maxdiff(a->acc, b->acc, a->E * NC));
    }
    E = ref->lev[1].E;
    CHECK(fac->lev[1].E == E, "%s: merged pieces", what);
    if (fac->lev[1].E == E) diff = fmax(diff, maxdiff(ref->macc, fac->macc, E * NC));
    CHECK(diff <= TOL_REL * S, "%s: %zu functions, %zu pieces: difference %.3g, S %.3g", what, n, E, diff, S);
    if (S > 0) worst_rel = fmax(worst_rel, diff / S), compared++;
    if (n < 2 || !E) return;
    /* the small functions' path: a build from the first half, the rest on a sub-range */
    copy = malloc(n * sizeof *copy);
    CHECK(copy != NULL, "%s: memory", what);
    if (!copy) return;
    memcpy(copy, ref->hits.hits, n * sizeof *copy);
    half = n / 2;
    elo = (size_t)(rnd() * (double)E);
    ehi = elo + 1 + (size_t)(rnd() * (double)(E - elo));
    CHECK(wvol__spline_build(g, ref, o, d, ta, tb, copy, half, 0, 1, &cr, &err) == WVOL_OK, "%s: reference half", what);
    CHECK(wvol__spline_build(g, fac, o, d, ta, tb, copy, half, 0, 1, &cf, &err) == WVOL_OK, "%s: factorised half", what);
    CHECK(wvol__spline_add_finest_list(g, ref, o, d, copy + half, n - half, elo, ehi, &cr), "%s: reference add", what);
    CHECK(wvol__spline_add_finest_list(g, fac, o, d, copy + half, n - half, elo, ehi, &cf), "%s: factorised add", what);
    if (ref->lev[1].E == E && fac->lev[1].E == E) {
        diff = maxdiff(ref->macc, fac->macc, E * NC);
        CHECK(diff <= TOL_REL * S, "%s: add on [%zu, %zu) of %zu: difference %.3g, S %.3g", what, elo, ehi, E, diff, S);
        if (S > 0) worst_rel = fmax(worst_rel, diff / S), added++;
    }
    free(copy);
}

static void family(const char *filter, int levels, size_t nx, size_t ny, size_t nz, double keep, int nrays, double minlen,
                   double maxlen)
{
    const int compared0 = compared, added0 = added;
    wvol_volume *v = fixture_volume(nx, ny, nz, noisy, NULL);
    wvol_store *s = v ? fixture_store(v, filter, levels, keep, 4) : NULL;
    wvol__spline_geom g;
    wvol__spline_ws ref, fac;
    wvol_error err;
    size_t dims[3] = {nx, ny, nz};
    char what[96];
    int r, a;
    CHECK(s != NULL, "%s %d levels keep %g: store", filter, levels, keep);

    if (!s) {
        wvol_volume_destroy(v);
        return;
    }
    CHECK(wvol__spline_geom_init(&g, s, &err) == WVOL_OK, "%s: geometry", filter);
    memset(&ref, 0, sizeof ref);
    memset(&fac, 0, sizeof fac);
    ref.per_function = 1;
    for (r = 0; r < nrays; r++) {
        double o[3], d[3], len = 0, ta, tb;
        for (a = 0; a < 3; a++) {
            o[a] = dims[a] > 1 ? -4.0 + rnd() * ((double)dims[a] + 8.0) : 0.0;
            d[a] = rnd() - 0.5;
        }
        if (r % 5 == 3) d[(size_t)r % 3] = 0.0;                  /* in a coordinate plane */
        if (r % 5 == 4) d[(r + 1) % 3] = d[(r + 2) % 3] = 0.0;  /* axis-parallel */
        if (nz == 1) d[2] = 0.0;
        for (a = 0; a < 3; a++) len += d[a] * d[a];
        if (!(len > 0)) d[0] = 1.0, len = 1.0;
        for (a = 0; a < 3; a++) d[a] /= sqrt(len);
        ta = rnd() * 2.0;
        tb = ta + minlen + rnd() * maxlen;
        snprintf(what, sizeof what, "%s L%d keep %g ray %d", filter, levels, keep, r);
        one_ray(&g, &ref, &fac, o, d, ta, tb, what);
    }
    /* random rays can miss every kept function: at least one of each family's must meet some */
    CHECK(compared > compared0 && added > added0, "%s L%d keep %g: no ray compared (%d) or added (%d)", filter, levels,
          keep, compared - compared0, added - added0);
    wvol__spline_ws_free(&ref);
    wvol__spline_ws_free(&fac);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

int main(void)
{
    static const char *families[] = {"db2", "db4", "coif1", "coif2"};
    static const double keeps[] = {0.02, 0.1, 0.4};
    size_t f;
    int L;
    for (f = 0; f < sizeof families / sizeof *families; f++)
        for (L = 1; L <= 4; L++) family(families[f], L, 32, 32, 32, keeps[(f + (size_t)L) % 3], 6, 2.0, 14.0);
    /* bl3's support is 127 units: a function has (127 2^m / n)^3 periodic images near a ray,
     * so the per-function reference is slow: levels 1 and 2, 0.3% kept, one short ray each */
    for (L = 1; L <= 2; L++) family("bl3", L, 16, 16, 16, 0.003, 1, 0.1, 0.2);
    family("db2", 2, 32, 32, 1, 0.3, 8, 2.0, 14.0); /* z not transformed */
    printf("largest difference / S: %.3g (allowed %.3g)\n", worst_rel, TOL_REL);
    return check_summary("test_ray_factor");
}
