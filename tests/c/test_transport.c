/* SPDX-License-Identifier: MIT */
/* Transport module: Haar tree round trips, the reduction against form factors and 4D Monte Carlo,
 * the oracle's soundness, energy, quadrature convergence, degenerate geometry, refused input. */
#define _GNU_SOURCE
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "fixtures.h"
#include "transport/transport_internal.h"
#include "wvol/image.h"
#include "wvol/transport.h"

static const wvol_transport_quad floor_sq = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}};      /* normal +z */
static const wvol_transport_quad ceiling_sq = {{{0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}}};    /* z = 1, -z */
static const wvol_transport_quad wall_sq = {{{0, 0, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}}};       /* x = 0, +x */

/* Howell's catalogue C-11 (parallel directly opposed rectangles a x b at distance c) and C-14
 * (perpendicular rectangles with a common edge of length l, other sides h and w). */
static double ff_parallel(double a, double b, double c)
{
    double X = a / c, Y = b / c, x1 = sqrt(1 + X * X), y1 = sqrt(1 + Y * Y);
    return 2 / (M_PI * X * Y) *
           (log(x1 * y1 / sqrt(1 + X * X + Y * Y)) + X * y1 * atan(X / y1) + Y * x1 * atan(Y / x1) - X * atan(X) -
            Y * atan(Y));
}

static double ff_perpendicular(double l, double h, double w)
{
    double H = h / l, W = w / l, H2 = H * H, W2 = W * W, r = sqrt(H2 + W2);
    double lg = log((1 + W2) * (1 + H2) / (1 + W2 + H2)) + W2 * log(W2 * (1 + W2 + H2) / ((1 + W2) * (W2 + H2))) +
                H2 * log(H2 * (1 + H2 + W2) / ((1 + H2) * (H2 + W2)));
    return (W * atan(1 / W) + H * atan(1 / H) - r * atan(1 / r) + 0.25 * lg) / (M_PI * W);
}

static wvol_transport_tree *constant_tree(int levels, float value)
{
    size_t nc = wvol_transport_cells_count(levels);
    float *cells = malloc(3 * nc * sizeof *cells);
    wvol_transport_tree *t = NULL;
    for (size_t i = 0; i < 3 * nc; i++) cells[i] = value;
    wvol_transport_tree_from_cells(&t, cells, levels, 0, NULL);
    free(cells);
    return t;
}

static void haar_round_trip_is_exact_on_piecewise_constant_fields(void)
{
    uint64_t st = 7;
    int L = 3;
    size_t nc = wvol_transport_cells_count(L);
    float *a = malloc(3 * nc * sizeof *a), *b = malloc(3 * nc * sizeof *b);
    wvol_transport_tree *t = NULL;
    double maxerr = 0, amax = 0;
    /* random piecewise-constant field, half the 2x2x2x2 blocks constant so some nodes vanish */
    for (size_t i = 0; i < 3 * nc; i++) a[i] = (float)fixture_urand(&st);
    for (size_t i = 0; i < nc; i++) {
        int n = 1 << L, m[4];
        size_t r = i;
        for (int k = 0; k < 4; k++) m[k] = (int)(r % (size_t)n), r /= (size_t)n;
        if ((m[0] >> 1) % 2 == 0) { /* copy the block's first cell */
            size_t base = (size_t)(m[0] & ~1) + n * ((size_t)(m[1] & ~1) + n * ((size_t)(m[2] & ~1) + n * (size_t)(m[3] & ~1)));
            for (int c = 0; c < 3; c++) a[3 * i + c] = a[3 * base + c];
        }
    }
    CHECK(wvol_transport_tree_from_cells(&t, a, L, 0, NULL) == WVOL_OK, "from_cells");
    CHECK(wvol_transport_tree_to_cells(b, 3 * nc, t, NULL) == WVOL_OK, "to_cells");
    for (size_t i = 0; i < 3 * nc; i++) {
        maxerr = fmax(maxerr, fabs(a[i] - b[i]));
        amax = fmax(amax, fabs(a[i]));
    }
    /* float32 butterflies, 2 x 4 stages per level, 3 levels: a few ulps of values <= 1 */
    CHECK(maxerr <= 1e-5 * amax, "round trip error %g", maxerr);
    CHECK(wvol_transport_tree_nodes(t) < 1 + 16 + 256, "constant blocks leave nodes out (%zu)", wvol_transport_tree_nodes(t));
    {
        double q[4] = {0.3, 0.55, 0.9, 0.1};
        int n = 1 << L, m[4];
        float rgb[3];
        for (int k = 0; k < 4; k++) m[k] = (int)(q[k] * n);
        size_t i = (size_t)m[0] + n * ((size_t)m[1] + n * ((size_t)m[2] + n * (size_t)m[3]));
        CHECK(wvol_transport_tree_eval(t, q, rgb, NULL) == WVOL_OK, "eval");
        CHECK_NEAR(rgb[1], a[3 * i + 1], 1e-5, "point value = cell value");
    }
    {
        size_t before = wvol_transport_tree_coefficients(t), kept = 0;
        CHECK(wvol_transport_tree_compress(t, 0.05, &kept, NULL) == WVOL_OK, "compress");
        CHECK(kept <= (size_t)ceil(0.05 * (double)before) + 3 && kept > 0, "kept %zu of %zu", kept, before);
    }
    wvol_transport_tree_destroy(t);
    free(a);
    free(b);
}

static int emitter_fn(void *user, const double q[4], float rgb[3])
{
    /* piecewise constant on the level-2 cells: 1 + the cell's parity in k, times (1, 2, 3) */
    int odd = ((int)(q[2] * 4) + (int)(q[0] * 4)) & 1;
    (void)user;
    for (int c = 0; c < 3; c++) rgb[c] = (float)((1 + odd) * (c + 1));
    return 0;
}

static void projection_of_an_emitter_is_exact(void)
{
    wvol_transport_tree *t = NULL;
    size_t nc = wvol_transport_cells_count(2);
    float *cells = malloc(3 * nc * sizeof *cells);
    double p[3], worst = 0;
    CHECK(wvol_transport_project(&t, 2, emitter_fn, NULL, 2, 0, NULL) == WVOL_OK, "project");
    wvol_transport_tree_to_cells(cells, 3 * nc, t, NULL);
    for (size_t i = 0; i < nc; i++) {
        int m0 = (int)(i % 4), m2 = (int)(i / 16 % 4);
        for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(cells[3 * i + c] - (1 + ((m0 + m2) & 1)) * (c + 1)));
    }
    CHECK(worst <= 1e-5, "projected cells off by %g", worst);
    wvol_transport_tree_power(p, t, &floor_sq, NULL);
    /* mean radiance 1.5 (c + 1) over [0,1]^4, 4 A b0 */
    CHECK_NEAR(p[2], 4 * 1.5 * 3, 1e-5, "power of the projected emitter");
    wvol_transport_tree_destroy(t);
    free(cells);
    /* a constant emitter L = 1 kept constant outside the disc emits pi A L (the disc's area pi/4, x 4) */
    t = constant_tree(2, 1.0f);
    CHECK(wvol_transport_tree_power_emitted(p, t, &floor_sq, NULL) == WVOL_OK, "emitted power");
    CHECK_NEAR(p[0], M_PI, 1e-4, "constant emitter's power (disc shares from 256 exact strips per cell)");
    wvol_transport_tree_destroy(t);
}

static double root_power(const wvol_transport_tree *t, const wvol_transport_quad *q)
{
    double p[3];
    wvol_transport_tree_power(p, t, q, NULL);
    return p[0];
}

/* constant radiance L from the source: received power = L pi A_s F_sd (the Nusselt analog) */
static void constant_radiance_gives_the_form_factor(void)
{
    wvol_transport_params p;
    wvol_transport_tree *src = constant_tree(1, 1.0f), *dst = NULL;
    wvol_transport_stats st;
    double got, want;
    wvol_transport_params_default(&p);
    p.levels = 3;
    p.quadrature = WVOL_TRANSPORT_QUADRATURE_STRATIFIED;
    p.samples = 256;
    CHECK(wvol_transport_run(&dst, src, &floor_sq, &ceiling_sq, &p, &st, NULL) == WVOL_OK, "run parallel");
    got = root_power(dst, &ceiling_sq);
    want = M_PI * ff_parallel(1, 1, 1);
    /* 256 jittered points per finest coefficient, whose integrand jumps along the source's
     * projected edges and the disc: measured 1.4e-4 at 512 points, 1e-3 at 64 (perpendicular
     * case, levels 3); 1e-3 */
    CHECK(fabs(got - want) <= 1e-3 * want, "parallel squares: power %.6f, pi F = %.6f", got, want);
    CHECK(st.oracle_exact > 0 && st.oracle_zero > 0, "oracle used (%zu exact, %zu zero)", st.oracle_exact,
          st.oracle_zero);
    wvol_transport_tree_destroy(dst);
    CHECK(wvol_transport_run(&dst, src, &floor_sq, &wall_sq, &p, &st, NULL) == WVOL_OK, "run perpendicular");
    got = root_power(dst, &wall_sq);
    want = M_PI * ff_perpendicular(1, 1, 1);
    CHECK(fabs(got - want) <= 1e-3 * want, "perpendicular squares: power %.6f, pi F = %.6f", got, want);
    wvol_transport_tree_destroy(dst);
    wvol_transport_tree_destroy(src);
}

/* the 2D reduction against a direct 4D Monte Carlo integration of eq. 18 */
static void reduction_matches_4d_monte_carlo(void)
{
    wvol__tgeom g;
    wvol_transport_params p;
    wvol_transport_index j = {1, {0, 1, 1, 0}}, k = {1, {0, 0, 0, 0}};
    wvol_transport_quad tilted = {{{0.2, -0.3, 0.8}, {0.2, 0.9, 1.2}, {1.4, 0.9, 1.2}, {1.4, -0.3, 0.8}}};
    uint64_t st = 11;
    long hits = 0, N = 400000;
    double hk = 0.5, hj = 0.5, T2, T4, se;
    wvol_transport_params_default(&p);
    p.quadrature = WVOL_TRANSPORT_QUADRATURE_STRATIFIED;
    p.samples = 1 << 18;
    wvol__tgeom_init(&g, &floor_sq, &tilted);
    T2 = 0;
    for (int i = 0; i < 16; i++) { /* the destination basis that receives most of j */
        wvol_transport_index kk = {1, {i & 1, i >> 1 & 1, i >> 2 & 1, i >> 3 & 1}};
        double t;
        p.samples = 1024;
        t = wvol__tc_eval(&g, &j, &kk, &p, NULL);
        if (t > T2) T2 = t, k = kk;
    }
    p.samples = 1 << 18;
    T2 = wvol__tc_eval(&g, &j, &k, &p, NULL);
    for (long i = 0; i < N; i++) {
        double q[4], wd[3], xd[3], xs[3], uv[2], kl[2], s, w[3];
        int in = 1;
        for (int a = 0; a < 4; a++) q[a] = (k.m[a] + fixture_urand(&st)) * hk;
        if (!wvol__tframe_dir(&g.d, q[2], q[3], wd)) continue;
        for (int c = 0; c < 3; c++) w[c] = -wd[c];
        if (wvol__dot3(w, g.s.n) <= 0) continue;
        wvol__tframe_point(&g.d, q[0], q[1], xd);
        s = (wvol__dot3(g.s.o, g.s.n) - wvol__dot3(xd, g.s.n)) / wvol__dot3(wd, g.s.n);
        if (s <= 0) continue;
        for (int c = 0; c < 3; c++) xs[c] = xd[c] + s * wd[c];
        wvol__tframe_param(&g.s, xs, uv);
        wvol__tframe_kl(&g.s, w, kl);
        double qs[4] = {uv[0], uv[1], kl[0], kl[1]};
        for (int a = 0; a < 4; a++) in &= qs[a] >= j.m[a] * hj && qs[a] < (j.m[a] + 1) * hj;
        hits += in;
    }
    T4 = pow(4, j.level + k.level) * pow(hk, 4) * hits / (double)N;
    se = pow(4, j.level + k.level) * pow(hk, 4) * sqrt(hits * (1 - hits / (double)N)) / N;
    CHECK(hits > 1000, "the pair interacts (%ld hits)", hits);
    /* 4 standard errors of the Monte Carlo estimate plus the 2D rule's ~1e-4 */
    CHECK(fabs(T2 - T4) <= 4 * se + 1e-4 * fabs(T4), "T 2D %.6f vs 4D MC %.6f (se %.2g)", T2, T4, se);
}

/* ZERO means the integral is 0; FULL means it is 4^(lj - lk); checked on random pairs */
static void oracle_is_conservative(void)
{
    wvol__tgeom g;
    wvol_transport_params p;
    wvol_transport_quad tilted = {{{-0.5, -0.2, 0.6}, {-0.5, 1.2, 0.6}, {1.5, 1.2, 1.0}, {1.5, -0.2, 1.0}}}; /* faces down */
    uint64_t st = 5;
    int zero = 0, full = 0, bad = 0;
    wvol_transport_params_default(&p);
    /* interior points only: the trapezoid's nodes on the cell's edges pick up the neighbour's
     * value there (a measure-zero set the oracle rightly ignores) */
    p.quadrature = WVOL_TRANSPORT_QUADRATURE_STRATIFIED;
    p.samples = 32 * 32;
    wvol__tgeom_init(&g, &floor_sq, &tilted);
    for (int it = 0; it < 3000; it++) {
        /* every other j the whole source: the pairs the FULL answer is made for */
        wvol_transport_index j = {it % 2 ? (int)(fixture_urand(&st) * 3) : 0, {0}},
                             k = {1 + (int)(fixture_urand(&st) * 3), {0}};
        wvol__oracle o;
        double T;
        for (int a = 0; a < 4; a++) {
            j.m[a] = (int)(fixture_urand(&st) * (1 << j.level));
            k.m[a] = (int)(fixture_urand(&st) * (1 << k.level));
        }
        o = wvol__tg_oracle(&g, &j, &k);
        if (o == WVOL__ORACLE_UNKNOWN) continue;
        T = wvol__tc_eval(&g, &j, &k, &p, NULL);
        if (o == WVOL__ORACLE_ZERO) zero++, bad += T != 0;
        if (o == WVOL__ORACLE_FULL) full++, bad += fabs(T - pow(4, j.level - k.level)) > 1e-9 * pow(4, j.level - k.level);
    }
    CHECK(zero > 100, "oracle rejected %d pairs", zero);
    CHECK(full > 0, "oracle found %d full pairs", full);
    CHECK(bad == 0, "%d oracle answers contradict the integral", bad);
}

/* all T_jk of a level for one source basis: RED falls as the samples grow, for every rule */
static double red_of(const double *a, const double *ref, int n)
{
    double num = 0, den = 0;
    for (int i = 0; i < n; i++) num += (a[i] - ref[i]) * (a[i] - ref[i]), den += ref[i] * ref[i];
    return sqrt(num / den);
}

static void red_falls_as_samples_grow(void)
{
    wvol__tgeom g;
    wvol_transport_params p;
    wvol_transport_index j = {1, {0, 0, 1, 1}};
    wvol_transport_scene sc;
    enum { K = 256 };
    static double ref[K], lo[K], hi[K];
    wvol_transport_scene_default(&sc);
    wvol__tgeom_init(&g, &sc.window, &sc.floor);
    wvol_transport_params_default(&p);
    p.quadrature = WVOL_TRANSPORT_QUADRATURE_STRATIFIED;
    p.samples = 256 * 256;
    for (int i = 0; i < K; i++) {
        wvol_transport_index k = {2, {i % 4, i / 4 % 4, i / 16 % 4, i / 64}};
        ref[i] = wvol__tc_eval(&g, &j, &k, &p, NULL);
    }
    for (int q = 0; q < WVOL_TRANSPORT_QUADRATURE_COUNT; q++) {
        double rl, rh;
        p.quadrature = (wvol_transport_quadrature)q;
        for (int i = 0; i < K; i++) {
            wvol_transport_index k = {2, {i % 4, i / 4 % 4, i / 16 % 4, i / 64}};
            p.samples = 16;
            lo[i] = wvol__tc_eval(&g, &j, &k, &p, NULL);
            p.samples = 1100;
            hi[i] = wvol__tc_eval(&g, &j, &k, &p, NULL);
        }
        rl = red_of(lo, ref, K);
        rh = red_of(hi, ref, K);
        /* 16 -> ~1000 samples: even O(N^-1/2) gives 8x; ask for 2x */
        CHECK(rh < 0.5 * rl, "%s: RED %.3g at 16 samples, %.3g at ~1000", wvol_transport_quadrature_name(p.quadrature),
              rl, rh);
    }
}

static void grazing_and_coplanar_geometry_stays_finite(void)
{
    wvol_transport_quad grazing = {{{0, 0, 1e-9}, {1, 0, 1e-9}, {1, 1, 2e-9}, {0, 1, 2e-9}}}; /* almost in the floor's plane */
    wvol_transport_quad coplanar = {{{1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}}};
    wvol_transport_quad coplanar_flip = {{{1, 0, 0}, {1, 1, 0}, {2, 1, 0}, {2, 0, 0}}};
    wvol_transport_quad crossing = {{{0.5, -0.5, -0.5}, {0.5, 1.5, -0.5}, {0.5, 1.5, 1.5}, {0.5, -0.5, 1.5}}};
    const wvol_transport_quad *dsts[4] = {&grazing, &coplanar, &coplanar_flip, &crossing};
    wvol_transport_params p;
    wvol_transport_tree *src = constant_tree(2, 1.0f);
    wvol_transport_params_default(&p);
    p.levels = 2;
    for (int d = 0; d < 4; d++)
        for (int q = 0; q < WVOL_TRANSPORT_QUADRATURE_COUNT; q++) {
            wvol_transport_tree *dst = NULL;
            wvol_error err;
            size_t nc = wvol_transport_cells_count(2);
            float *cells = malloc(3 * nc * sizeof *cells);
            int finite = 1;
            p.quadrature = (wvol_transport_quadrature)q;
            CHECK(wvol_transport_run(&dst, src, &floor_sq, dsts[d], &p, NULL, &err) == WVOL_OK, "case %d: %s", d,
                  err.message);
            if (dst) {
                wvol_transport_tree_to_cells(cells, 3 * nc, dst, NULL);
                for (size_t i = 0; i < 3 * nc; i++) finite &= isfinite(cells[i]) && cells[i] >= -1e-3f;
                CHECK(finite, "case %d quadrature %d: finite, non-negative cells", d, q);
                if (d == 1 || d == 2)
                    CHECK(wvol_transport_tree_coefficients(dst) == 0, "coplanar case %d: no light (%zu coefficients)",
                          d, wvol_transport_tree_coefficients(dst));
            }
            wvol_transport_tree_destroy(dst);
            free(cells);
        }
    wvol_transport_tree_destroy(src);
}

/* window lobe to a floor that catches nearly all of it; Lambert keeps albedo x power */
static void energy_is_conserved(void)
{
    wvol_transport_scene sc;
    wvol_transport_window w = {0};
    wvol_transport_tree *src = NULL, *inc = NULL, *refl = NULL, *big = NULL;
    wvol_transport_params p;
    wvol_transport_brdf lam = {WVOL_TRANSPORT_BRDF_LAMBERT, {0.5f, 0.5f, 0.5f}, {0, 0, 0}, 0};
    wvol_transport_quad wide = {{{-40, -40, 0.999}, {40, -40, 0.999}, {40, 40, 0.999}, {-40, 40, 0.999}}};
    double ps[3], pi[3], pr[3], pw[3];
    wvol_transport_scene_default(&sc);
    wvol_transport_params_default(&p);
    p.levels = 2;
    p.quadrature = WVOL_TRANSPORT_QUADRATURE_HAMMERSLEY;
    p.samples = 64;
    CHECK(wvol_transport_window_synthetic(&w, 32, NULL) == WVOL_OK, "window");
    CHECK(wvol_transport_scene_source(&src, &sc, &w, 2, NULL) == WVOL_OK, "source");
    CHECK(wvol_transport_run(&inc, src, &sc.window, &sc.floor, &p, NULL, NULL) == WVOL_OK, "transport");
    /* a floor 1e-3 below the window and 80 wide sees all directions but those within
     * atan(1e-3 / 39.5) of grazing: it receives the emitted power (4 A b0 over the disc) */
    CHECK(wvol_transport_run(&big, src, &sc.window, &wide, &p, NULL, NULL) == WVOL_OK, "transport wide");
    /* emitted power: the lobe over the disc only (the tree extends it outside) */
    CHECK(wvol_transport_tree_power_emitted(ps, src, &sc.window, NULL) == WVOL_OK, "emitted power");
    wvol_transport_tree_power(pi, inc, &sc.floor, NULL);
    wvol_transport_tree_power(pw, big, &wide, NULL);
    for (int c = 0; c < 3; c++) {
        CHECK(pi[c] > 0 && pi[c] <= ps[c] * 1.01, "channel %d: floor gets %g of %g emitted", c, pi[c], ps[c]);
        /* the 64-point rule on the rim cells, where the integrand jumps at the disc: 2% */
        CHECK(fabs(pw[c] - ps[c]) <= 0.02 * ps[c], "channel %d: wide floor gets %g of %g emitted", c, pw[c], ps[c]);
    }
    CHECK(wvol_transport_reflect(&refl, inc, &lam, NULL, NULL, 0, NULL) == WVOL_OK, "reflect");
    wvol_transport_tree_power(pr, refl, &sc.floor, NULL);
    for (int c = 0; c < 3; c++)
        /* Lambert: out = albedo x in, up to the 4-point Gauss rule on the disc's rim cells (< 1%) */
        CHECK(fabs(pr[c] - 0.5 * pi[c]) <= 0.01 * pi[c], "channel %d: reflected %g, half of %g", c, pr[c], pi[c]);
    wvol_transport_tree_destroy(refl);
    refl = NULL;
    CHECK(wvol_transport_reflect(&refl, inc, &sc.glossy, NULL, NULL, 0, NULL) == WVOL_OK, "reflect glossy");
    wvol_transport_tree_power(pr, refl, &sc.floor, NULL);
    for (int c = 0; c < 3; c++)
        CHECK(pr[c] > 0 && pr[c] <= 0.76 * pi[c] * 1.02, "channel %d: Phong reflects %g of %g (kd + ks = 0.75)", c,
              pr[c], pi[c]);
    wvol_transport_tree_destroy(src);
    wvol_transport_tree_destroy(inc);
    wvol_transport_tree_destroy(refl);
    wvol_transport_tree_destroy(big);
    wvol_transport_window_free(&w);
}

/* threads split the source's subtrees: the same count gives the same bits, another count the
 * same values up to float32 sums */
static void threads_change_only_rounding(void)
{
    wvol_transport_scene sc;
    wvol_transport_window w = {0};
    wvol_transport_tree *src = NULL, *a = NULL, *b = NULL, *c = NULL;
    wvol_transport_params p;
    size_t nc = wvol_transport_cells_count(2);
    float *ca = malloc(3 * nc * sizeof *ca), *cb = malloc(3 * nc * sizeof *cb), *cc = malloc(3 * nc * sizeof *cc);
    double worst = 0, top = 0;
    wvol_transport_scene_default(&sc);
    wvol_transport_params_default(&p);
    p.levels = 2;
    wvol_transport_window_synthetic(&w, 16, NULL);
    wvol_transport_scene_source(&src, &sc, &w, 2, NULL);
    p.threads = 1;
    CHECK(wvol_transport_run(&a, src, &sc.window, &sc.floor, &p, NULL, NULL) == WVOL_OK, "1 thread");
    p.threads = 2;
    CHECK(wvol_transport_run(&b, src, &sc.window, &sc.floor, &p, NULL, NULL) == WVOL_OK, "2 threads");
    CHECK(wvol_transport_run(&c, src, &sc.window, &sc.floor, &p, NULL, NULL) == WVOL_OK, "2 threads again");
    if (a && b && c) {
        wvol_transport_tree_to_cells(ca, 3 * nc, a, NULL);
        wvol_transport_tree_to_cells(cb, 3 * nc, b, NULL);
        wvol_transport_tree_to_cells(cc, 3 * nc, c, NULL);
        for (size_t i = 0; i < 3 * nc; i++) worst = fmax(worst, fabs(ca[i] - cb[i])), top = fmax(top, fabs(ca[i]));
        CHECK(worst <= 1e-5 * top, "1 vs 2 threads differ by %g of %g", worst, top);
        CHECK(!memcmp(cb, cc, 3 * nc * sizeof *cb), "2 threads twice: the same bits");
    }
    wvol_transport_tree_destroy(src);
    wvol_transport_tree_destroy(a);
    wvol_transport_tree_destroy(b);
    wvol_transport_tree_destroy(c);
    wvol_transport_window_free(&w);
    free(ca);
    free(cb);
    free(cc);
}

/* light from one direction cell: a Phong lobe peaks at the mirror cell (k, l) -> (1 - k, 1 - l) */
static void phong_peaks_at_the_mirror_direction(void)
{
    enum { L = 3, N = 8 };
    size_t nc = wvol_transport_cells_count(L);
    float *cells = calloc(3 * nc, sizeof *cells), *out = malloc(3 * nc * sizeof *out);
    wvol_transport_tree *inc = NULL, *refl = NULL;
    wvol_transport_brdf ph = {WVOL_TRANSPORT_BRDF_PHONG, {0, 0, 0}, {1, 1, 1}, 60};
    int S = 2 + N * 5, best = -1; /* (mk, ml) = (2, 5): inside the disc */
    float bv = -1;
    for (int P = 0; P < N * N; P++)
        for (int c = 0; c < 3; c++) cells[3 * ((size_t)P + (size_t)N * N * S) + c] = 1;
    CHECK(wvol_transport_tree_from_cells(&inc, cells, L, 0, NULL) == WVOL_OK, "incident");
    CHECK(wvol_transport_reflect(&refl, inc, &ph, NULL, NULL, 0, NULL) == WVOL_OK, "reflect");
    wvol_transport_tree_to_cells(out, 3 * nc, refl, NULL);
    for (int R = 0; R < N * N; R++)
        if (out[3 * ((size_t)N * N * R) + 1] > bv) bv = out[3 * ((size_t)N * N * R) + 1], best = R;
    CHECK(best == (N - 1 - 2) + N * (N - 1 - 5), "peak at cell %d, mirror is %d", best, (N - 1 - 2) + N * (N - 1 - 5));
    wvol_transport_tree_destroy(inc);
    wvol_transport_tree_destroy(refl);
    free(cells);
    free(out);
}

static int mentions(const wvol_error *e, const char *word) { return strstr(e->message, word) != NULL; }

static void bad_input_is_refused(void)
{
    wvol_error e;
    wvol_transport_quad q = floor_sq;
    wvol_transport_window w;
    wvol_transport_tree *t = NULL;
    float cells[3 * 16];
    char dir[] = "/tmp/wvol_test_transport_XXXXXX", path[128];
    q.p[3][0] = q.p[0][0], q.p[3][1] = q.p[0][1]; /* p3 = p0 */
    CHECK(wvol_transport_quad_check(&q, &e) == WVOL_ERR_ARG && mentions(&e, "degenerate"), "degenerate: %s", e.message);
    q = floor_sq;
    q.p[2][2] = 0.3;
    CHECK(wvol_transport_quad_check(&q, &e) == WVOL_ERR_ARG && mentions(&e, "non-planar"), "non-planar: %s", e.message);
    q = floor_sq;
    q.p[2][0] = 1.4;
    CHECK(wvol_transport_quad_check(&q, &e) == WVOL_ERR_ARG && mentions(&e, "parallelogram"), "trapezium: %s",
          e.message);
    q = floor_sq;
    q.p[1][1] = NAN;
    CHECK(wvol_transport_quad_check(&q, &e) == WVOL_ERR_NONFINITE, "NaN vertex: %s", e.message);
    for (int i = 0; i < 48; i++) cells[i] = 1;
    cells[7] = NAN;
    CHECK(wvol_transport_tree_from_cells(&t, cells, 1, 0, &e) == WVOL_ERR_NONFINITE && !t, "NaN cell: %s", e.message);
    CHECK(wvol_transport_tree_create(&t, 9, &e) == WVOL_ERR_ARG && mentions(&e, "levels"), "levels: %s", e.message);
    CHECK(wvol_transport_window_read_png(&w, "/nonexistent/window.png", &e) == WVOL_ERR_IO && mentions(&e, "window.png"),
          "missing PNG: %s", e.message);
    if (mkdtemp(dir)) {
        float grey[16] = {0};
        FILE *f;
        snprintf(path, sizeof path, "%s/grey.png", dir);
        CHECK(wvol_png_write(path, 4, 4, 1, grey, NULL) == WVOL_OK, "write grey");
        CHECK(wvol_transport_window_read_png(&w, path, &e) == WVOL_ERR_FORMAT && mentions(&e, "RGB"), "grey PNG: %s",
              e.message);
        unlink(path);
        {
            /* an RGB window read back: the writer's sRGB 8-bit encoding decoded again, so each
             * value is within half an 8-bit step of the written one in sRGB terms */
            float rgb[5 * 3 * 3];
            int bad = 0;
            for (int i = 0; i < 45; i++) rgb[i] = (float)(i % 7) / 6.0f * (float)(i % 3 + 1) / 3.0f;
            snprintf(path, sizeof path, "%s/rgb.png", dir);
            CHECK(wvol_png_write(path, 5, 3, 3, rgb, NULL) == WVOL_OK, "write rgb");
            CHECK(wvol_transport_window_read_png(&w, path, &e) == WVOL_OK && w.width == 5 && w.height == 3,
                  "RGB window: %s", e.message);
            for (int i = 0; w.rgb && i < 45; i++)
                if (fabs(wvol_linear_to_srgb(w.rgb[i]) - wvol_linear_to_srgb(rgb[i])) > 0.5 / 255 + 1e-6) bad++;
            CHECK(w.rgb && bad == 0, "RGB window values round-trip (%d off)", bad);
            wvol_transport_window_free(&w);
            unlink(path);
        }
        snprintf(path, sizeof path, "%s/junk.png", dir);
        f = fopen(path, "wb");
        if (f) fputs("not a png at all", f), fclose(f);
        CHECK(wvol_transport_window_read_png(&w, path, &e) == WVOL_ERR_FORMAT && strstr(e.message, "junk.png"),
              "junk PNG: %s", e.message);
        unlink(path);
        CHECK(wvol_transport_window_read_png(&w, path, &e) == WVOL_ERR_IO && strstr(e.message, "junk.png"),
              "missing PNG: %s", e.message);
        rmdir(dir);
    }
    {
        wvol_transport_params p;
        wvol_transport_index j = {0, {0, 0, 0, 0}}, k = {1, {2, 0, 0, 0}};
        double T;
        wvol_transport_params_default(&p);
        CHECK(wvol_transport_coefficient(&T, &floor_sq, &ceiling_sq, &j, &k, &p, &e) == WVOL_ERR_ARG &&
                  mentions(&e, "m[0]"),
              "bad index: %s", e.message);
        p.samples = 0;
        k.m[0] = 0;
        CHECK(wvol_transport_coefficient(&T, &floor_sq, &ceiling_sq, &j, &k, &p, &e) == WVOL_ERR_ARG &&
                  mentions(&e, "samples"),
              "bad samples: %s", e.message);
        p.samples = 16;
        p.use_oracle = 9;
        CHECK(wvol_transport_coefficient(&T, &floor_sq, &ceiling_sq, &j, &k, &p, &e) == WVOL_ERR_ARG &&
                  mentions(&e, "use_oracle 9"),
              "use_oracle 9: %s", e.message);
    }
}

int main(void)
{
    haar_round_trip_is_exact_on_piecewise_constant_fields();
    projection_of_an_emitter_is_exact();
    constant_radiance_gives_the_form_factor();
    reduction_matches_4d_monte_carlo();
    oracle_is_conservative();
    red_falls_as_samples_grow();
    grazing_and_coplanar_geometry_stays_finite();
    energy_is_conserved();
    phong_peaks_at_the_mirror_direction();
    threads_change_only_rounding();
    bad_input_is_refused();
    return check_summary("test_transport");
}
