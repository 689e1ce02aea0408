/* SPDX-License-Identifier: MIT */
/* Wavelet engine: filters, 1D and 3D periodic transforms, partial reconstruction. */
#include <float.h>
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/wavelet.h"

/* First use from several threads at once (must run before any other lookup): every
 * thread sees the same, fully built bl3 (pthread_once). */
static void first_lookup_is_thread_safe(void)
{
    const wvol_filter *seen[8] = {0};
    double sums[8] = {0};
#pragma omp parallel num_threads(8)
    {
        int t = omp_get_thread_num();
        const wvol_filter *f = NULL;
        if (wvol_filter_get(&f, "bl3", NULL) == WVOL_OK) {
            seen[t] = f;
            for (int n = 0; n < f->length; n++) sums[t] += f->h[n];
        }
    }
    for (int t = 0; t < 8; t++) {
        CHECK(seen[t] != NULL && seen[t] == seen[0], "thread %d got filter %p", t, (const void *)seen[t]);
        CHECK(sums[t] == sums[0] && fabs(sums[t] - sqrt(2.0)) < 1e-14, "thread %d taps sum %.17g", t, sums[t]);
    }
}

/* Every filter: sum h = sqrt2, orthonormal to < 1e-12 (bl3: its reported defect < 1e-8,
 * the price of truncating at 1e-10), g from h, the stated vanishing moments hold
 * (sum (-1)^n n^k h[n] = 0 for k < vm, relative to sum |n^k h[n]|), and the centre is
 * sum n h[n] / sqrt2. */
static void filters_are_orthonormal_qmf(void)
{
    int count = wvol_filter_count();
    CHECK(count == 17, "17 filters, got %d", count);
    for (int i = 0; i < count; i++) {
        const wvol_filter *f = wvol_filter_at(i), *g = NULL;
        double sum = 0.0, m1 = 0.0;
        int bl = f->family == WVOL_FAMILY_BATTLE_LEMARIE;
        for (int n = 0; n < f->length; n++) sum += f->h[n], m1 += n * f->h[n];
        CHECK_NEAR(sum, sqrt(2.0), 1e-14, f->name);
        CHECK(f->defect < (bl ? 1e-8 : 1e-12), "%s defect %g", f->name, f->defect);
        CHECK(f->defect >= 0.0, "%s defect %g", f->name, f->defect);
        CHECK_NEAR(f->center, m1 / sqrt(2.0), 1e-12, f->name);
        for (int n = 0; n < f->length; n++)
            CHECK(f->g[n] == ((n & 1) ? -1.0 : 1.0) * f->h[f->length - 1 - n], "%s g[%d]", f->name, n);
        for (int k = 0; k < f->vanishing_moments; k++) {
            double acc = 0.0, mag = 0.0;
            for (int n = 0; n < f->length; n++) {
                double t = pow(n - f->center, k) * f->g[n];
                acc += t;
                mag += fabs(t);
            }
            /* db10's 9th moment sums terms of size 1e9: relative 1e-9 (bl3: 1e-6, truncation) */
            CHECK(fabs(acc) <= (bl ? 1e-6 : 1e-9) * mag, "%s moment %d: %g of %g", f->name, k, acc, mag);
        }
        CHECK(wvol_filter_get(&g, f->name, NULL) == WVOL_OK && g == f, "lookup %s", f->name);
    }
    const wvol_filter *f = NULL;
    wvol_error err;
    CHECK(wvol_filter_get(&f, "db11", &err) == WVOL_ERR_ARG && f == NULL, "db11 refused");
    CHECK(strstr(err.message, "db11") != NULL, "message names it: %s", err.message);
    CHECK(wvol_filter_get(&f, NULL, NULL) == WVOL_ERR_ARG, "NULL name refused");
    CHECK(wvol_filter_get(NULL, "db2", NULL) == WVOL_ERR_ARG, "NULL out refused");
    CHECK(wvol_filter_at(-1) == NULL && wvol_filter_at(count) == NULL, "out of range index");
    wvol_filter_get(&f, "haar", NULL);
    CHECK_NEAR(f->center, 0.5, 1e-15, "haar centre");
}


/* ---- helpers ---------------------------------------------------------------------- */

static uint64_t rng_state = 88172645463325252ull;
static double urand(void) { return fixture_urand(&rng_state); }

static wvol_volume *random_volume(size_t nx, size_t ny, size_t nz, double lo, double hi)
{
    wvol_volume *v = NULL;
    if (wvol_volume_create(&v, nx, ny, nz, NULL) != WVOL_OK) return NULL;
    for (size_t i = 0; i < wvol_volume_count(v); i++) v->data[i] = (float)(lo + (hi - lo) * urand());
    return v;
}

static double max_abs_diff(const float *a, const float *b, size_t n)
{
    double m = 0.0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)a[i] - (double)b[i]);
        if (!(d <= m)) m = d; /* NaN propagates */
    }
    return m;
}

/* Reconstruction error bound. Each 1D pass forms outputs as sums of L products with
 * |sum| <= ||h||_1 max|x|; in floating point each output is off by at most about
 * L * eps * ||h||_1 * max|x| (||h||_1 < 3 for every filter here, bl3 included). A level
 * is 3 forward + 3 inverse passes and errors of earlier levels pass through orthonormal
 * synthesis, so err <= 6 * levels * L * 3 * eps * range is a safe, still small, bound
 * (float32: 17x13x7, db2, 2 levels -> 1.7e-5 of the range; measured ~1e-7). Truncated
 * bl3 is orthonormal only to its defect d (3e-10): add 6 * levels * d * range. */
static double recon_bound(const wvol_filter *f, int levels, double eps, double range)
{
    return (18.0 * levels * f->length * eps + 6.0 * levels * f->defect) * range;
}

/* ---- 1D ----------------------------------------------------------------------------- */

/* The fast 3D engine along one axis equals the reference 1D formula of DESIGN.md 4, and
 * the reference reconstructs. */
static void dwt1_matches_formula_and_fast_path(void)
{
    enum { N = 24 };
    double x[N], ad[N], back[N], direct[N];
    for (int fi = 0; fi < wvol_filter_count(); fi++) {
        const wvol_filter *f = wvol_filter_at(fi);
        for (int i = 0; i < N; i++) x[i] = urand() - 0.5;
        wvol_dwt1(ad, x, N, f);
        for (int k = 0; k < N / 2; k++) {
            double a = 0, d = 0;
            for (int n = 0; n < f->length; n++) {
                a += f->h[n] * x[(2 * k + n) % N];
                d += f->g[n] * x[(2 * k + n) % N];
            }
            direct[k] = a, direct[N / 2 + k] = d;
        }
        double e1 = 0, e2 = 0;
        wvol_idwt1(back, ad, N, f);
        for (int i = 0; i < N; i++) {
            e1 = fmax(e1, fabs(ad[i] - direct[i]));
            e2 = fmax(e2, fabs(back[i] - x[i]));
        }
        CHECK(e1 < 1e-15, "%s dwt1 formula %g", f->name, e1);
        CHECK(e2 < 20 * f->length * DBL_EPSILON + 4 * f->defect, "%s idwt1 roundtrip %g", f->name, e2);
        for (int axis = 0; axis < 3; axis++) {
            double d64[N];
            size_t dims[3] = {1, 1, 1};
            dims[axis] = N;
            memcpy(d64, x, sizeof x);
            CHECK(wvol_dwt3_inplace_f64(d64, dims[0], dims[1], dims[2], f, 1, NULL) == WVOL_OK, "f64 1D");
            double e = 0;
            for (int i = 0; i < N; i++) e = fmax(e, fabs(d64[i] - ad[i]));
            /* same sums, different association order: a few ulps times L */
            CHECK(e < 4 * f->length * DBL_EPSILON, "%s axis %d fast vs reference %g", f->name, axis, e);
        }
    }
}

/* ---- 3D round trips ------------------------------------------------------------------ */

static void perfect_reconstruction_all_families(void)
{
    static const size_t sizes[][3] = {{17, 13, 7}, {31, 1, 5}, {16, 8, 4}, {1, 1, 19}, {6, 5, 1}};
    for (int si = 0; si < 5; si++) {
        wvol_volume *v = random_volume(sizes[si][0], sizes[si][1], sizes[si][2], -1.0, 1.0);
        int M = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
        CHECK(M >= 1, "max levels %d", M);
        for (int fi = 0; fi < wvol_filter_count(); fi++) {
            const wvol_filter *f = wvol_filter_at(fi);
            for (int lev = 1; lev <= M; lev++)
                for (int prec = 0; prec < 2; prec++) {
                    wvol_coeffs *c = NULL;
                    wvol_volume *r = NULL;
                    wvol_error err;
                    int ok = wvol_dwt3_ex(&c, v, f, lev, WVOL_PAD_EDGE, prec, &err) == WVOL_OK &&
                             wvol_idwt3_ex(&r, c, prec, &err) == WVOL_OK;
                    CHECK(ok, "%s %d levels: %s", f->name, lev, err.message);
                    if (ok) {
                        /* range 2. The f64 path still rounds twice to float32 (stored
                         * coefficients, output samples): 16 float32 epsilons of the range covers
                         * that rounding spread by the synthesis filters (measured: 1 ulp), plus the
                         * double-precision arithmetic bound (which holds bl3's defect). */
                        double e = max_abs_diff(r->data, v->data, wvol_volume_count(v));
                        double tol = prec ? 16 * FLT_EPSILON * 2.0 + recon_bound(f, lev, DBL_EPSILON, 2.0)
                                          : recon_bound(f, lev, FLT_EPSILON, 2.0);
                        CHECK(e <= tol, "%s %zux%zux%zu %d levels %s: error %g > %g", f->name, v->nx, v->ny,
                              v->nz, lev, prec ? "f64" : "f32", e, tol);
                        CHECK(r->nx == v->nx && r->ny == v->ny && r->nz == v->nz, "cropped size");
                    }
                    wvol_coeffs_destroy(c);
                    wvol_volume_destroy(r);
                }
        }
        wvol_volume_destroy(v);
    }
}

/* In-place float64 round trip: error at double precision (bound with eps = 2^-52). */
static void inplace_f64_roundtrip_is_exact_to_double_rounding(void)
{
    enum { NX = 16, NY = 8, NZ = 8 };
    static double x[NX * NY * NZ], y[NX * NY * NZ];
    for (int fi = 0; fi < wvol_filter_count(); fi++) {
        const wvol_filter *f = wvol_filter_at(fi);
        for (int lev = 1; lev <= 3; lev++) {
            for (int i = 0; i < NX * NY * NZ; i++) x[i] = y[i] = urand() * 2 - 1;
            CHECK(wvol_dwt3_inplace_f64(y, NX, NY, NZ, f, lev, NULL) == WVOL_OK, "fwd");
            CHECK(wvol_idwt3_inplace_f64(y, NX, NY, NZ, f, lev, NULL) == WVOL_OK, "inv");
            double e = 0;
            for (int i = 0; i < NX * NY * NZ; i++) e = fmax(e, fabs(x[i] - y[i]));
            double tol = recon_bound(f, lev, DBL_EPSILON, 2.0);
            CHECK(e <= tol, "%s f64 %d levels: %g > %g", f->name, lev, e, tol);
        }
    }
}

/* Parseval: sum c^2 = sum x^2 (float64 path, f64 accumulation; no padding so the
 * transform is exactly orthonormal). Relative 1e-6 for float32-stored coefficients
 * (each c carries a relative rounding of 2^-24, squares 2^-23, and they average out);
 * plus the bl3 defect. */
static void parseval_holds(void)
{
    wvol_volume *v = random_volume(32, 16, 8, -3.0, 5.0);
    double sx = 0;
    for (size_t i = 0; i < wvol_volume_count(v); i++) sx += (double)v->data[i] * v->data[i];
    for (int fi = 0; fi < wvol_filter_count(); fi++) {
        const wvol_filter *f = wvol_filter_at(fi);
        for (int prec = 0; prec < 2; prec++) {
            wvol_coeffs *c = NULL;
            if (wvol_dwt3_ex(&c, v, f, 3, WVOL_PAD_EDGE, prec, NULL) != WVOL_OK) {
                CHECK(0, "%s transform", f->name);
                continue;
            }
            double sc = 0;
            for (size_t i = 0; i < c->px * c->py * c->pz; i++) sc += (double)c->data[i] * c->data[i];
            double tol = (prec ? 1e-6 : 1e-5 * f->length / 4.0 + 1e-6) + 20 * f->defect;
            CHECK(fabs(sc - sx) <= tol * sx, "%s %s Parseval: %.12g vs %.12g", f->name, prec ? "f64" : "f32", sc, sx);
            wvol_coeffs_destroy(c);
        }
    }
    wvol_volume_destroy(v);
}

/* Output does not depend on the thread count: each value is the same sum in the same order. */
static void thread_count_does_not_change_results(void)
{
    enum { NX = 64, NY = 32, NZ = 32 };
    size_t n = (size_t)NX * NY * NZ;
    float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
    int saved = omp_get_max_threads();
    for (size_t i = 0; i < n; i++) a[i] = b[i] = (float)urand();
    omp_set_num_threads(1);
    wvol_dwt3_inplace_f32(a, NX, NY, NZ, fixture_filter("coif1"), 3, NULL);
    omp_set_num_threads(3);
    wvol_dwt3_inplace_f32(b, NX, NY, NZ, fixture_filter("coif1"), 3, NULL);
    omp_set_num_threads(saved);
    CHECK(memcmp(a, b, n * sizeof *a) == 0, "1 thread vs 3 threads differ");
    free(a);
    free(b);
}

/* ---- stress ----------------------------------------------------------------------- */

static void constant_volume_has_no_details(void)
{
    wvol_volume *v;
    wvol_volume_create(&v, 16, 12, 9, NULL);
    for (size_t i = 0; i < wvol_volume_count(v); i++) v->data[i] = 3.25f;
    for (int fi = 0; fi < wvol_filter_count(); fi++) {
        const wvol_filter *f = wvol_filter_at(fi);
        wvol_coeffs *c = NULL;
        int lev = 2;
        CHECK(wvol_dwt3(&c, v, f, lev, NULL) == WVOL_OK, "%s", f->name);
        if (!c) continue;
        /* edge padding keeps the volume constant; low-pass = 3.25 * 2^(3*lev/2);
         * details: sum g = 0 exactly for published filters (to rounding), ~1e-10 for bl3 */
        double worst = 0, lowerr = 0, low = 3.25 * pow(2.0, 1.5 * lev);
        for (size_t i = 0; i < c->px * c->py * c->pz; i++) {
            int level, band;
            wvol_coeffs_locate(c, i, &level, &band, NULL, NULL, NULL);
            if (band == 0) lowerr = fmax(lowerr, fabs(c->data[i] - low));
            else worst = fmax(worst, fabs(c->data[i]));
        }
        double tol = recon_bound(f, lev, FLT_EPSILON, low) + 10 * low * f->defect;
        CHECK(worst <= tol, "%s constant: detail %g > %g", f->name, worst, tol);
        CHECK(lowerr <= tol, "%s constant: low-pass off by %g", f->name, lowerr);
        wvol_coeffs_destroy(c);
    }
    wvol_volume_destroy(v);
}

static void impulse_and_extreme_values(void)
{
    static const double scales[] = {1.0, 1e-30, 1e30};
    for (int s = 0; s < 3; s++)
        for (int fi = 0; fi < wvol_filter_count(); fi++) {
            const wvol_filter *f = wvol_filter_at(fi);
            wvol_volume *v, *r = NULL;
            wvol_coeffs *c = NULL;
            wvol_volume_create(&v, 16, 16, 8, NULL);
            v->data[5 + 16 * (9 + 16 * 3)] = (float)scales[s];
            CHECK(wvol_dwt3(&c, v, f, 3, NULL) == WVOL_OK && wvol_idwt3(&r, c, NULL) == WVOL_OK, "%s", f->name);
            if (r) {
                double e2 = 0;
                for (size_t i = 0; i < c->px * c->py * c->pz; i++) {
                    double q = c->data[i] / scales[s];
                    e2 += q * q;
                }
                /* energy of the impulse is 1 (in units of the scale), Parseval */
                CHECK(fabs(e2 - 1.0) < 1e-5 + 20 * f->defect, "%s impulse %g energy %g", f->name, scales[s], e2);
                double e = max_abs_diff(r->data, v->data, wvol_volume_count(v));
                CHECK(e <= recon_bound(f, 3, FLT_EPSILON, scales[s]), "%s impulse %g error %g", f->name, scales[s], e);
            }
            wvol_coeffs_destroy(c);
            wvol_volume_destroy(v);
            wvol_volume_destroy(r);
        }
}

/* Denormal inputs (float32 subnormals ~1e-40) stay finite; absolute error is a few
 * subnormal ulps (2^-149 ~ 1.4e-45) times the operation count; no flush-to-zero breaks it. */
static void denormals_roundtrip(void)
{
    wvol_volume *v = random_volume(8, 8, 8, 0.0, 1.0), *r = NULL;
    wvol_coeffs *c = NULL;
    for (size_t i = 0; i < wvol_volume_count(v); i++) v->data[i] *= 1e-39f;
    CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 2, NULL) == WVOL_OK && wvol_idwt3(&r, c, NULL) == WVOL_OK, "denormals");
    if (r) {
        double e = max_abs_diff(r->data, v->data, wvol_volume_count(v));
        CHECK(e <= 18.0 * 2 * 4 * 1.5e-45 * 64 + recon_bound(fixture_filter("db2"), 2, FLT_EPSILON, 1e-39), "denormal error %g", e);
        for (size_t i = 0; i < wvol_volume_count(r); i++) CHECK(isfinite(r->data[i]), "finite");
    }
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(r);
    wvol_volume_destroy(v);
}

static void nonfinite_input_refused_with_voxel(void)
{
    wvol_volume *v = random_volume(9, 8, 7, 0, 1);
    wvol_coeffs *c = NULL;
    wvol_error err;
    v->data[3 + 9 * (2 + 8 * 1)] = NAN;
    v->data[4 + 9 * (6 + 8 * 5)] = INFINITY;
    CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 1, &err) == WVOL_ERR_NONFINITE && !c, "NaN refused");
    CHECK(strstr(err.message, "i=3, j=2, k=1") != NULL && strstr(err.message, "NaN"), "names the voxel: %s", err.message);
    v->data[3 + 9 * (2 + 8 * 1)] = 0;
    CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 1, &err) == WVOL_ERR_NONFINITE, "Inf refused");
    CHECK(strstr(err.message, "i=4, j=6, k=5") != NULL && strstr(err.message, "Inf"), "names the voxel: %s", err.message);
    wvol_volume_destroy(v);
    /* finite input whose low-pass overflows float32: refused, not Inf coefficients */
    v = random_volume(8, 8, 8, 3e38, 3.4e38);
    c = NULL;
    CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 3, &err) == WVOL_ERR_NONFINITE && !c, "overflow refused");
    CHECK(strstr(err.message, "overflow") != NULL, "says overflow: %s", err.message);
    wvol_volume_destroy(v);
    /* the other entry points refuse NaN and Inf too: a coarse level reconstructed from an Inf
     * coefficient, the level-0 copy of a NaN volume, the in-place transform of NaN data */
    v = random_volume(16, 16, 8, 0, 1);
    c = NULL;
    CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 2, &err) == WVOL_OK, "%s", err.message);
    if (c) {
        wvol_volume *r = NULL;
        c->data[1] = INFINITY;
        CHECK(wvol_idwt3_level(&r, c, 1, &err) == WVOL_ERR_NONFINITE && !r && strstr(err.message, "Inf"),
              "idwt3_level of an Inf coefficient: %s", err.message);
        c->data[1] = NAN;
        CHECK(wvol_idwt3_level(&r, c, 2, &err) == WVOL_ERR_NONFINITE && !r && strstr(err.message, "NaN"),
              "idwt3_level of a NaN coefficient: %s", err.message);
        wvol_coeffs_destroy(c);
    }
    {
        wvol_volume *r = NULL;
        v->data[77] = NAN;
        CHECK(wvol_volume_level(&r, v, fixture_filter("db2"), 0, NULL, &err) == WVOL_ERR_NONFINITE && !r &&
                  strstr(err.message, "NaN"),
              "volume_level 0 of a NaN volume: %s", err.message);
        CHECK(wvol_volume_level(&r, v, fixture_filter("db2"), 1, NULL, &err) == WVOL_ERR_NONFINITE && !r,
              "volume_level 1 of a NaN volume: %s", err.message);
        CHECK(wvol_dwt3_inplace_f32(v->data, 16, 16, 8, fixture_filter("db2"), 1, &err) == WVOL_ERR_NONFINITE &&
                  strstr(err.message, "NaN or Inf") && isnan(v->data[77]) && v->data[0] == v->data[0],
              "in-place transform of NaN data: %s", err.message);
        v->data[77] = 0;
        /* geometry: a transform keeps it, so a bad one is refused as the loaders refuse it */
        v->spacing[1] = NAN;
        CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 1, &err) == WVOL_ERR_ARG && !c && strstr(err.message, "spacing"),
              "NaN spacing: %s", err.message);
        v->spacing[1] = 0;
        CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 1, &err) == WVOL_ERR_ARG && strstr(err.message, "spacing"),
              "zero spacing: %s", err.message);
        v->spacing[1] = -1;
        CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 1, &err) == WVOL_ERR_ARG && strstr(err.message, "spacing"),
              "negative spacing: %s", err.message);
        v->spacing[1] = 1;
        v->origin[2] = INFINITY;
        CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 1, &err) == WVOL_ERR_ARG && strstr(err.message, "origin"),
              "infinite origin: %s", err.message);
    }
    wvol_volume_destroy(v);
}

/* ---- layout ---------------------------------------------------------------------- */

static void max_levels_and_padding(void)
{
    CHECK(wvol_dwt_max_levels(17, 13, 7) == 2, "17x13x7");
    CHECK(wvol_dwt_max_levels(31, 1, 5) == 2, "31x1x5");
    CHECK(wvol_dwt_max_levels(256, 256, 256) == 8, "256^3");
    CHECK(wvol_dwt_max_levels(1, 1, 16) == 4, "1x1x16");
    CHECK(wvol_dwt_max_levels(1, 1, 1) == 0, "1^3");
    CHECK(wvol_dwt_padded_size(17, 2) == 20 && wvol_dwt_padded_size(1, 3) == 1 &&
              wvol_dwt_padded_size(16, 4) == 16, "padding");
}

static void index_and_locate_are_inverse(void)
{
    static const size_t sizes[][3] = {{17, 13, 7}, {31, 1, 5}, {16, 16, 16}};
    for (int si = 0; si < 3; si++) {
        wvol_volume *v = random_volume(sizes[si][0], sizes[si][1], sizes[si][2], 0, 1);
        wvol_coeffs *c = NULL;
        wvol_dwt3(&c, v, fixture_filter("haar"), 2, NULL);
        size_t n = c->px * c->py * c->pz, seen = 0;
        char *hit = calloc(n, 1);
        for (int m = 1; m <= c->levels; m++)
            for (int b = 0; b < 8; b++) {
                size_t e[3] = {c->px == 1 ? 1 : c->px >> m, c->py == 1 ? 1 : c->py >> m, c->pz == 1 ? 1 : c->pz >> m};
                for (size_t r = 0; r < e[2]; r++)
                    for (size_t q = 0; q < e[1]; q++)
                        for (size_t p = 0; p < e[0]; p++) {
                            size_t i = wvol_coeffs_index(c, m, b, p, q, r);
                            if (i == SIZE_MAX) continue;
                            int lm, lb;
                            size_t lp, lq, lr;
                            CHECK(i < n && !hit[i], "index %zu unique", i);
                            if (i >= n || hit[i]) continue;
                            hit[i] = 1, seen++;
                            wvol_coeffs_locate(c, i, &lm, &lb, &lp, &lq, &lr);
                            CHECK(lm == m && lb == b && lp == p && lq == q && lr == r, "locate(%zu): %d %d", i, lm, lb);
                        }
            }
        CHECK(seen == n, "%zu of %zu coefficients addressed", seen, n);
        /* Haar, level 1, band 1 (x high-pass) at (0,0,0) = (x1 - x0)... / 2^{3/2} in our sign convention:
         * g = (h1, -h0) = (1/sqrt2, -1/sqrt2) so d = (x0 - x1)/sqrt2 per axis pair */
        CHECK(wvol_coeffs_index(c, 1, 1, 0, 0, 0) == c->px / 2, "band 1 starts at px/2");
        CHECK(wvol_coeffs_index(c, 1, 0, 0, 0, 0) == SIZE_MAX, "band 0 only at the coarsest level");
        CHECK(wvol_coeffs_index(c, 3, 1, 0, 0, 0) == SIZE_MAX, "level beyond");
        CHECK(wvol_coeffs_index(c, 1, 1, c->px, 0, 0) == SIZE_MAX, "position beyond");
        if (c->py == 1) CHECK(wvol_coeffs_index(c, 1, 2, 0, 0, 0) == SIZE_MAX, "y high-pass on a 1-voxel axis");
        free(hit);
        wvol_coeffs_destroy(c);
        wvol_volume_destroy(v);
    }
}

/* ---- partial reconstruction ------------------------------------------------------- */

/* Coarser volume at level s = the low-pass cube of an s-level forward transform, scaled
 * by 2^{-3s/2}; s = 0 is the full reconstruction. */
static void level_reconstruction_matches_forward_lowpass(void)
{
    wvol_volume *v = random_volume(32, 16, 16, -1, 1);
    for (int fi = 0; fi < wvol_filter_count(); fi += 3) {
        const wvol_filter *f = wvol_filter_at(fi);
        wvol_coeffs *c = NULL;
        wvol_dwt3(&c, v, f, 3, NULL);
        for (int s = 0; s <= 3; s++) {
            wvol_volume *lv = NULL;
            CHECK(wvol_idwt3_level(&lv, c, s, NULL) == WVOL_OK, "%s level %d", f->name, s);
            if (!lv) continue;
            size_t ex = 32 >> s, ey = 16 >> s, ez = 16 >> s;
            CHECK(lv->nx == ex && lv->ny == ey && lv->nz == ez, "size at level %d", s);
            CHECK_NEAR(lv->spacing[0], ldexp(1.0, s), 0, "spacing");
            /* the first sample's centre in the first cell: the functions' centres (2^s - 1) c,
             * less the whole cells of the shift the samples are rolled by */
            const size_t q = wvol_level_shift(f, s);
            CHECK_NEAR(lv->origin[0], (ldexp(1.0, s) - 1) * f->center - ldexp(1.0, s) * (double)q, 1e-12, "origin");
            CHECK(lv->origin[0] >= 0 && lv->origin[0] < ldexp(1.0, s), "%s level %d: origin %g in the first cell",
                  f->name, s, lv->origin[0]);
            double worst = 0;
            if (s == 0) {
                worst = max_abs_diff(lv->data, v->data, wvol_volume_count(v)) - recon_bound(f, 3, FLT_EPSILON, 2.0);
            } else {
                double *ref = malloc(wvol_volume_count(v) * sizeof *ref);
                for (size_t i = 0; i < wvol_volume_count(v); i++) ref[i] = v->data[i];
                wvol_dwt3_inplace_f64(ref, 32, 16, 16, f, s, NULL);
                for (size_t k = 0; k < ez; k++)
                    for (size_t j = 0; j < ey; j++)
                        for (size_t i = 0; i < ex; i++) {
                            /* sample i is the level's coefficient i - q, read periodically */
                            const size_t I = (i + ex - q % ex) % ex, J = (j + ey - q % ey) % ey,
                                         K = (k + ez - q % ez) % ez;
                            double want = ref[I + 32 * (J + 16 * K)] * pow(2.0, -1.5 * s);
                            worst = fmax(worst, fabs(lv->data[i + ex * (j + ey * k)] - want) -
                                                    recon_bound(f, 3, FLT_EPSILON, 2.0));
                        }
                free(ref);
            }
            CHECK(worst <= 0, "%s level %d: exceeds the bound by %g", f->name, s, worst);
            wvol_volume_destroy(lv);
        }
        wvol_coeffs_destroy(c);
    }
    wvol_volume_destroy(v);
}

/* A brick equals the same box of the full reconstruction (brick: double arithmetic,
 * full: float32; both within the round-trip bound of the original). */
static void brick_equals_box_of_full(void)
{
    static const size_t sizes[][3] = {{17, 13, 7}, {31, 1, 5}, {32, 16, 8}};
    static const char *names[] = {"haar", "db2", "coif1", "db5", "coif3", "bl3"};
    for (int si = 0; si < 3; si++) {
        wvol_volume *v = random_volume(sizes[si][0], sizes[si][1], sizes[si][2], -1, 1);
        for (int fi = 0; fi < 6; fi++) {
            const wvol_filter *f = fixture_filter(names[fi]);
            int M = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
            wvol_coeffs *c = NULL;
            wvol_volume *full = NULL;
            wvol_dwt3(&c, v, f, M, NULL);
            wvol_idwt3(&full, c, NULL);
            for (int t = 0; t < 4; t++) {
                size_t lo[3], hi[3];
                for (int a = 0; a < 3; a++) {
                    size_t n = a == 0 ? v->nx : a == 1 ? v->ny : v->nz;
                    lo[a] = t == 0 ? 0 : (size_t)(urand() * n);
                    hi[a] = t == 0 ? n : lo[a] + 1 + (size_t)(urand() * (n - lo[a]));
                    if (hi[a] > n) hi[a] = n;
                }
                wvol_volume *b = NULL;
                CHECK(wvol_idwt3_brick(&b, c, lo, hi, NULL) == WVOL_OK, "%s brick", f->name);
                if (!b) continue;
                double worst = 0;
                for (size_t k = 0; k < b->nz; k++)
                    for (size_t j = 0; j < b->ny; j++)
                        for (size_t i = 0; i < b->nx; i++) {
                            size_t gi = i + lo[0] + v->nx * (j + lo[1] + v->ny * (k + lo[2]));
                            worst = fmax(worst, fabs(b->data[i + b->nx * (j + b->ny * k)] - full->data[gi]));
                        }
                double tol = 2 * recon_bound(f, M, FLT_EPSILON, 2.0);
                CHECK(worst <= tol, "%s %zux%zux%zu brick [%zu,%zu)x[%zu,%zu)x[%zu,%zu): %g > %g", f->name, v->nx,
                      v->ny, v->nz, lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], worst, tol);
                CHECK(b->origin[0] == (double)lo[0] && b->nx == hi[0] - lo[0], "brick geometry");
                wvol_volume_destroy(b);
            }
            wvol_coeffs_destroy(c);
            wvol_volume_destroy(full);
        }
        wvol_volume_destroy(v);
    }
}

/* A brick's samples do not depend on the box they are reconstructed in, bit for bit: the
 * bricked meshes and images rely on it where neighbouring bricks share a face. Boxes as
 * wide as the volume make every level's region a whole period (the synthesis then plans
 * the wrapped rows unwrapped), small ones do not; coefficients with most values zeroed
 * make some bands absent in some boxes. The 1030-sample rows take the x pass's plan from
 * the heap (more than its stack holds: 2 taps per output of db2 over more than 512 outputs)
 * in the whole box and in boxes of whole rows, from the stack in the narrower boxes. */
static void brick_samples_do_not_depend_on_the_box(void)
{
    static const size_t sizes[][3] = {{40, 24, 12}, {33, 17, 9}, {70, 9, 6}, {1030, 6, 4}};
    static const char *names[] = {"haar", "db2", "coif1", "bl3"};
    for (int si = 0; si < 4; si++) {
        wvol_volume *v = random_volume(sizes[si][0], sizes[si][1], sizes[si][2], -1, 1);
        const size_t n[3] = {v->nx, v->ny, v->nz}, all_lo[3] = {0, 0, 0};
        for (int fi = 0; fi < 4; fi++) {
            const wvol_filter *f = fixture_filter(names[fi]);
            int M = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
            wvol_coeffs *c = NULL;
            wvol_volume *whole = NULL;
            wvol_dwt3(&c, v, f, M, NULL);
            if (si > 0) /* sparse: 90% of the coefficients zeroed */
                for (size_t i = 0; i < c->px * c->py * c->pz; i++)
                    if (urand() < 0.9) c->data[i] = 0.0f;
            CHECK(wvol_idwt3_brick(&whole, c, all_lo, n, NULL) == WVOL_OK, "%s whole box", f->name);
            for (int t = 0; whole && t < 24; t++) {
                size_t lo[3], hi[3], diff = 0;
                for (int a = 0; a < 3; a++) {
                    lo[a] = (size_t)(urand() * n[a]);
                    hi[a] = t % 3 == 0 && a == 0 ? n[a] : lo[a] + 1 + (size_t)(urand() * (n[a] - lo[a]));
                    if (t % 3 == 0 && a == 0) lo[a] = t % 2;
                    if (hi[a] > n[a]) hi[a] = n[a];
                }
                wvol_volume *b = NULL;
                CHECK(wvol_idwt3_brick(&b, c, lo, hi, NULL) == WVOL_OK, "%s brick", f->name);
                if (!b) continue;
                for (size_t k = 0; k < b->nz; k++)
                    for (size_t j = 0; j < b->ny; j++)
                        for (size_t i = 0; i < b->nx; i++) {
                            float x = b->data[i + b->nx * (j + b->ny * k)];
                            float y = whole->data[i + lo[0] + n[0] * (j + lo[1] + n[1] * (k + lo[2]))];
                            diff += memcmp(&x, &y, sizeof x) != 0;
                        }
                CHECK(diff == 0, "%s %zux%zux%zu box [%zu,%zu)x[%zu,%zu)x[%zu,%zu): %zu samples differ from the "
                      "whole box's", f->name, n[0], n[1], n[2], lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], diff);
                wvol_volume_destroy(b);
            }
            wvol_volume_destroy(whole);
            wvol_coeffs_destroy(c);
        }
        wvol_volume_destroy(v);
    }
}

/* ---- bad arguments ----------------------------------------------------------------- */

static void bad_arguments_are_refused(void)
{
    wvol_volume *v = random_volume(16, 8, 4, 0, 1), *one = random_volume(1, 1, 1, 0, 1), *r = NULL;
    wvol_coeffs *c = NULL;
    wvol_error err;
    const wvol_filter *f = fixture_filter("db2");
    float buf[24 * 8 * 8];
    CHECK(wvol_dwt3(&c, v, f, 0, &err) == WVOL_ERR_ARG && !c, "levels 0");
    CHECK(wvol_dwt3(&c, v, f, 3, &err) == WVOL_ERR_ARG && !c, "levels 3 on a 4-thick volume");
    CHECK(strstr(err.message, "1..2") != NULL, "says the range: %s", err.message);
    CHECK(wvol_dwt3(&c, one, f, 1, &err) == WVOL_ERR_DIMS && !c, "1x1x1");
    CHECK(wvol_dwt3(&c, NULL, f, 1, &err) == WVOL_ERR_ARG, "NULL volume");
    CHECK(wvol_dwt3(&c, v, NULL, 1, &err) == WVOL_ERR_ARG, "NULL filter");
    CHECK(wvol_dwt3(NULL, v, f, 1, &err) == WVOL_ERR_ARG, "NULL out");
    CHECK(wvol_dwt3_pad(&c, v, f, 1, (wvol_pad_mode)7, &err) == WVOL_ERR_ARG, "pad mode");
    CHECK(wvol_dwt3_inplace_f32(buf, 24, 8, 8, f, 4, &err) == WVOL_ERR_DIMS, "24 not a multiple of 16");
    CHECK(wvol_dwt3_inplace_f32(NULL, 24, 8, 8, f, 1, &err) == WVOL_ERR_ARG, "NULL data");
    CHECK(wvol_dwt3_inplace_f32(buf, 24, 8, 8, f, 0, &err) == WVOL_ERR_ARG, "0 levels in place");
    CHECK(wvol_idwt3(&r, NULL, &err) == WVOL_ERR_ARG && !r, "NULL coeffs");
    CHECK(wvol_dwt3(&c, v, f, 2, &err) == WVOL_OK, "valid");
    CHECK(wvol_idwt3_level(&r, c, 3, &err) == WVOL_ERR_ARG && !r, "stop level beyond");
    CHECK(wvol_idwt3_level(&r, c, -1, &err) == WVOL_ERR_ARG && !r, "negative stop level");
    size_t lo[3] = {2, 0, 0}, hi[3] = {2, 8, 4}, hi2[3] = {17, 8, 4};
    CHECK(wvol_idwt3_brick(&r, c, lo, hi, &err) == WVOL_ERR_ARG && !r, "empty box");
    CHECK(wvol_idwt3_brick(&r, c, lo, hi2, &err) == WVOL_ERR_ARG && !r, "box outside");
    CHECK(wvol_idwt3_brick(&r, c, NULL, hi2, &err) == WVOL_ERR_ARG, "NULL box");
    c->levels = 5; /* inconsistent with the sizes */
    CHECK(wvol_idwt3(&r, c, &err) == WVOL_ERR_ARG && !r, "inconsistent coefficients: %s", err.message);
    c->levels = 2;
    wvol_coeffs *d = NULL;
    CHECK(wvol_coeffs_clone(&d, c, &err) == WVOL_OK && memcmp(d->data, c->data, c->px * c->py * c->pz * 4) == 0, "clone");
    wvol_coeffs_destroy(d);
    wvol_coeffs_destroy(c);
    wvol_coeffs_destroy(NULL);
    wvol_volume_destroy(v);
    wvol_volume_destroy(one);
}

#define TIMED(fn) do { double t0_ = omp_get_wtime(); fn(); if (getenv("WVOL_TEST_TIMING")) fprintf(stderr, "%-55s %.3f s\n", #fn, omp_get_wtime() - t0_); } while (0)

int main(void)
{
    TIMED(first_lookup_is_thread_safe);
    TIMED(filters_are_orthonormal_qmf);
    TIMED(dwt1_matches_formula_and_fast_path);
    TIMED(perfect_reconstruction_all_families);
    TIMED(inplace_f64_roundtrip_is_exact_to_double_rounding);
    TIMED(parseval_holds);
    TIMED(thread_count_does_not_change_results);
    TIMED(constant_volume_has_no_details);
    TIMED(impulse_and_extreme_values);
    TIMED(denormals_roundtrip);
    TIMED(nonfinite_input_refused_with_voxel);
    TIMED(max_levels_and_padding);
    TIMED(index_and_locate_are_inverse);
    TIMED(level_reconstruction_matches_forward_lowpass);
    TIMED(brick_equals_box_of_full);
    TIMED(brick_samples_do_not_depend_on_the_box);
    TIMED(bad_arguments_are_refused);
    return check_summary("test_wavelet");
}
