/* SPDX-License-Identifier: MIT */
/* Tests of the per-pixel error bound (render/bound.c): on every pixel, the image of all the
 * coefficients and the image of the kept ones (both from the exact spline integrator) differ
 * by at most the bound; the bound is tight where the dropped functions keep one sign along
 * the rays (shrunk by 2% it fails there), never NaN or negative, and bad calls are refused. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/progressive.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

static double noise_blob(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    uint64_t *st = (uint64_t *)ctx;
    double x = (double)i / (double)v->nx - 0.5, y = (double)j / (double)v->ny - 0.4, z = (double)k / (double)v->nz - 0.55;
    return exp(-8.0 * (x * x + y * y + z * z)) + 0.3 * fixture_urand(st);
}

static double positive(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)v, (void)i, (void)j, (void)k;
    return 0.2 + fixture_urand((uint64_t *)ctx);
}

/* The store of c's nonzero coefficients; majorant: |c| on the majorants of |B| (a residual). */
static wvol_store *store_of(const wvol_coeffs *c, int majorant)
{
    wvol_store *s = NULL;
    wvol_store_params p;
    wvol_error err;
    wvol_store_params_default(&p);
    p.majorant = majorant;
    if (wvol_store_build(&s, c, NULL, &p, &err) != WVOL_OK) fprintf(stderr, "store: %s\n", err.message);
    return s;
}

static wvol_image *render(const wvol_store *s, const wvol_camera *cam, const wvol_tf *tf, wvol_render_mode mode)
{
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_error err;
    wvol_render_params_default(&p);
    p.mode = mode;
    p.threads = 1;
    p.spline.gauss_nodes = 8;
    if (wvol_image_create(&img, cam->width, cam->height, &err) != WVOL_OK) return NULL;
    if (wvol_render_spline(img, s, cam, tf, &p, NULL, &err) != WVOL_OK) {
        fprintf(stderr, "render: %s\n", err.message);
        wvol_image_destroy(img);
        return NULL;
    }
    return img;
}

static wvol_image *bound_any(const wvol_store *res, double qe, int coarse, const wvol_camera *cam, const wvol_tf *tf,
                             wvol_render_mode mode, wvol_render_bound_stats *st)
{
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_error err;
    wvol_render_params_default(&p);
    p.mode = mode;
    if (wvol_image_create(&img, cam->width, cam->height, &err) != WVOL_OK) return NULL;
    if ((coarse ? wvol_render_bound_coarse : wvol_render_bound)(img, res, qe, cam, tf, &p, st, &err) != WVOL_OK) {
        fprintf(stderr, "bound: %s\n", err.message);
        wvol_image_destroy(img);
        return NULL;
    }
    return img;
}

static wvol_image *bound_of(const wvol_store *res, double qe, const wvol_camera *cam, const wvol_tf *tf,
                            wvol_render_mode mode, wvol_render_bound_stats *st)
{
    return bound_any(res, qe, 0, cam, tf, mode, st);
}

/* Pixels (and channels) where the coarse bound is below the exact one beyond rounding. */
static size_t coarse_below_exact(const wvol_image *exact, const wvol_image *coarse)
{
    size_t i, n = 4 * (size_t)exact->width * exact->height, bad = 0;
    for (i = 0; i < n; i++)
        if (coarse->rgba[i] < exact->rgba[i] * (1 - 1e-5)) bad++;
    return bad;
}

/* Largest (|a - b| - shrink * bound) over pixels and channels, the rounding of the float
 * images allowed (half an ulp of each: 2^-24 |a| + 2^-24 |b|) plus `quad`, the quadrature's
 * share in absorption (the spline integrator samples the exponential at Gauss nodes). > 0
 * means a violation. Also counts bad bound values. */
static double worst_excess(const wvol_image *a, const wvol_image *b, const wvol_image *bd, double shrink, double quad,
                           int channels, size_t *bad)
{
    double worst = -INFINITY;
    size_t i, n = (size_t)a->width * a->height;
    int ch;
    for (i = 0; i < n; i++)
        for (ch = 0; ch < channels; ch++) {
            double x = a->rgba[4 * i + ch], y = b->rgba[4 * i + ch], bb = bd->rgba[4 * i + ch];
            double allow = ldexp(fabs(x) + fabs(y), -24) + quad;
            if (!(bb >= 0) || !isfinite(bb)) (*bad)++;
            worst = fmax(worst, fabs(x - y) - shrink * bb - allow);
        }
    return worst;
}

static void camera(wvol_camera *cam, const wvol_store *s, const double dir[3], wvol_projection proj, int w, int h)
{
    wvol_store_info info;
    wvol_geometry g;
    int a;
    wvol_store_get_info(s, &info);
    for (a = 0; a < 3; a++) {
        g.dims[a] = a == 0 ? info.nx : a == 1 ? info.ny : info.nz;
        g.spacing[a] = info.spacing[a];
        g.origin[a] = info.origin[a];
    }
    CHECK(wvol_camera_frame(cam, &g, dir, proj, w, h, 0, NULL) == WVOL_OK, "camera");
}

/* Random stores: families, fractions, cameras, modes. */
static void bound_holds_on_every_pixel(void)
{
    static const char *families[] = {"haar", "db2", "coif1"};
    static const double fractions[] = {0.08, 0.3, 0.15};
    static const double dirs[][3] = {{0, 0, 1}, {1, 0.4, 0.7}, {-0.3, 1, -0.2}};
    uint64_t st = 0x9e3779b97f4a7c15ull;
    wvol_volume *v = fixture_volume(12, 10, 14, noise_blob, &st);
    wvol_tf tf;
    size_t fi, ki, di, bad = 0;
    CHECK(v != NULL, "volume");
    wvol_tf ramp;
    CHECK(wvol_tf_preset(&tf, "gaussian", 0.0, 1.3, NULL) == WVOL_OK, "tf");
    /* a CT-like ramp: transparent below 0.5, steep and coloured above */
    CHECK(wvol_tf_parse(&ramp, "0.5 0.2 0.1 0.05 0\n0.7 1 0.8 0.6 30\n1.3 1 1 1 40\n", "ramp", NULL) == WVOL_OK,
          "ramp tf");
    for (fi = 0; fi < 3; fi++) {
        ki = fi; /* one fraction per family keeps the test short */
        {
            wvol_compressed all, part;
            wvol_compress_params p;
            wvol_error err;
            wvol_compress_params_default(&p);
            p.wavelet = families[fi];
            p.levels = 2;
            CHECK(wvol_compress(&all, v, &p, &err) == WVOL_OK, "compress all");
            p.select.mode = WVOL_SELECT_FRACTION;
            p.select.fraction = fractions[ki];
            p.build_residual = 1;
            CHECK(wvol_compress(&part, v, &p, &err) == WVOL_OK, "compress %s", families[fi]);
            CHECK(part.residual != NULL, "residual store");
            for (di = 0; di < 3; di++) {
                int pr;
                for (pr = 0; pr < 2; pr++) {
                    wvol_camera cam;
                    wvol_render_mode mode = (di + (size_t)pr) % 2 ? WVOL_RENDER_MODE_ABSORPTION : WVOL_RENDER_MODE_XRAY;
                    wvol_image *ia, *ik, *ib;
                    wvol_render_bound_stats bs;
                    double ex;
                    camera(&cam, all.store, dirs[di], pr ? WVOL_PROJECTION_PERSPECTIVE : WVOL_PROJECTION_ORTHOGRAPHIC,
                           16, 14);
                    const wvol_tf *t = fi % 2 ? &ramp : &tf;
                    ia = render(all.store, &cam, t, mode);
                    ik = render(part.store, &cam, t, mode);
                    ib = bound_of(part.residual, 0, &cam, t, mode, &bs);
                    CHECK(ia && ik && ib, "images");
                    if (!ia || !ik || !ib) continue;
                    /* absorption: the integrator's quadrature of the exponential, measured
                     * below 1e-7 on these volumes against 10 nodes; 1e-6 allowed */
                    ex = worst_excess(ia, ik, ib, 1.0, mode == WVOL_RENDER_MODE_XRAY ? 0 : 1e-6,
                                      mode == WVOL_RENDER_MODE_XRAY ? 3 : 4, &bad);
                    CHECK(ex <= 0, "%s keep %g dir %zu %s %s: |I - I^| exceeds the bound by %g", families[fi],
                          fractions[ki], di, pr ? "persp" : "ortho", wvol_render_mode_name(mode), ex);
                    CHECK(bs.max > 0 && bs.mean > 0 && bs.mean <= bs.max, "stats %g %g", bs.mean, bs.max);
                    {
                        /* the coarse bound sits above the exact one on every pixel */
                        wvol_image *ic = bound_any(part.residual, 0, 1, &cam, t, mode, NULL);
                        CHECK(ic && coarse_below_exact(ib, ic) == 0, "%s dir %zu: coarse bound below the exact",
                              families[fi], di);
                        wvol_image_destroy(ic);
                    }
                    wvol_image_destroy(ia);
                    wvol_image_destroy(ik);
                    wvol_image_destroy(ib);
                }
            }
            wvol_compressed_free(&all);
            wvol_compressed_free(&part);
        }
    }
    CHECK(bad == 0, "%zu bound values NaN, infinite or negative", bad);
    wvol_volume_destroy(v);
}

/* Haar low-pass functions are boxes >= 0: with only positive ones dropped, the X-ray
 * difference equals the bound on every pixel, so 2% less must fail somewhere. */
static void bound_is_tight_for_one_signed_functions(void)
{
    uint64_t st = 12345;
    wvol_volume *v = fixture_volume(16, 16, 16, positive, &st);
    const wvol_filter *haar = fixture_filter("haar");
    wvol_coeffs *c = NULL, *kept = NULL, *res = NULL;
    wvol_store *sa, *sk, *sr;
    size_t i, n, bad = 0;
    int pr;
    CHECK(v && haar, "setup");
    CHECK(wvol_dwt3(&c, v, haar, 2, NULL) == WVOL_OK, "dwt");
    n = c->px * c->py * c->pz;
    for (i = 0; i < n; i++) {
        int level, band;
        size_t p, q, r;
        wvol_coeffs_locate(c, i, &level, &band, &p, &q, &r);
        if (band != 0) c->data[i] = 0; /* only the low-pass (positive) functions */
    }
    CHECK(wvol_coeffs_clone(&kept, c, NULL) == WVOL_OK && wvol_coeffs_clone(&res, c, NULL) == WVOL_OK, "clone");
    for (i = 0; i < n; i++) {
        if (c->data[i] == 0) continue;
        if (fixture_urand(&st) < 0.5) kept->data[i] = 0; /* dropped: in the residual */
        else res->data[i] = 0;
    }
    sa = store_of(c, 0);
    sk = store_of(kept, 0);
    sr = store_of(res, 1);
    CHECK(sa && sk && sr, "stores");
    for (pr = 0; pr < 2; pr++) {
        static const double dir[3] = {0.3, -0.5, 1.0};
        wvol_camera cam;
        wvol_image *ia, *ik, *ib;
        camera(&cam, sa, dir, pr ? WVOL_PROJECTION_PERSPECTIVE : WVOL_PROJECTION_ORTHOGRAPHIC, 24, 24);
        ia = render(sa, &cam, NULL, WVOL_RENDER_MODE_XRAY);
        ik = render(sk, &cam, NULL, WVOL_RENDER_MODE_XRAY);
        ib = bound_of(sr, 0, &cam, NULL, WVOL_RENDER_MODE_XRAY, NULL);
        CHECK(ia && ik && ib, "images");
        if (!ia || !ik || !ib) continue;
        CHECK(worst_excess(ia, ik, ib, 1.0, 0, 3, &bad) <= 0, "%s: the bound fails", pr ? "persp" : "ortho");
        CHECK(worst_excess(ia, ik, ib, 0.98, 0, 3, &bad) > 0, "%s: 0.98 x the bound still holds everywhere",
              pr ? "persp" : "ortho");
        wvol_image_destroy(ia);
        wvol_image_destroy(ik);
        wvol_image_destroy(ib);
    }
    CHECK(bad == 0, "%zu bad bound values", bad);
    wvol_store_destroy(sa);
    wvol_store_destroy(sk);
    wvol_store_destroy(sr);
    wvol_coeffs_destroy(c);
    wvol_coeffs_destroy(kept);
    wvol_coeffs_destroy(res);
    wvol_volume_destroy(v);
}

/* Every coefficient moved by up to e (a quantiser): the difference stays under the bound
 * from e alone (an empty residual). */
static void coefficient_error_bound_holds(void)
{
    static const char *families[] = {"haar", "db2"};
    uint64_t st = 777;
    wvol_volume *v = fixture_volume(12, 12, 12, noise_blob, &st);
    size_t fi, bad = 0;
    for (fi = 0; fi < 2; fi++) {
        wvol_coeffs *c = NULL, *q = NULL, *zero = NULL;
        wvol_store *sa, *sq, *sz;
        const double e = 0.01, dir[3] = {1, 0.2, 0.5};
        size_t i, n;
        wvol_camera cam;
        wvol_image *ia, *iq, *ib;
        wvol_render_bound_stats bs;
        CHECK(wvol_dwt3(&c, v, fixture_filter(families[fi]), 2, NULL) == WVOL_OK, "dwt");
        CHECK(wvol_coeffs_clone(&q, c, NULL) == WVOL_OK && wvol_coeffs_clone(&zero, c, NULL) == WVOL_OK, "clone");
        n = c->px * c->py * c->pz;
        for (i = 0; i < n; i++) {
            q->data[i] = (float)(c->data[i] + e * (2.0 * fixture_urand(&st) - 1.0));
            zero->data[i] = 0;
        }
        sa = store_of(c, 0);
        sq = store_of(q, 0);
        sz = store_of(zero, 1);
        CHECK(sa && sq && sz, "stores");
        camera(&cam, sa, dir, WVOL_PROJECTION_ORTHOGRAPHIC, 16, 16);
        ia = render(sa, &cam, NULL, WVOL_RENDER_MODE_XRAY);
        iq = render(sq, &cam, NULL, WVOL_RENDER_MODE_XRAY);
        /* the float rounding of c + noise adds up to half an ulp of each coefficient */
        ib = bound_of(sz, e * (1 + 1e-6), &cam, NULL, WVOL_RENDER_MODE_XRAY, &bs);
        CHECK(ia && iq && ib, "images");
        if (ia && iq && ib) {
            CHECK(worst_excess(ia, iq, ib, 1.0, 0, 3, &bad) <= 0, "%s: quantiser bound fails", families[fi]);
            CHECK(bs.coeff_error_density > 0, "stats: density %g", bs.coeff_error_density);
        }
        wvol_image_destroy(ia);
        wvol_image_destroy(iq);
        wvol_image_destroy(ib);
        wvol_store_destroy(sa);
        wvol_store_destroy(sq);
        wvol_store_destroy(sz);
        wvol_coeffs_destroy(c);
        wvol_coeffs_destroy(q);
        wvol_coeffs_destroy(zero);
    }
    CHECK(bad == 0, "%zu bad bound values", bad);
    wvol_volume_destroy(v);
}

static void bad_calls_are_refused(void)
{
    uint64_t st = 5;
    wvol_volume *v = fixture_volume(8, 8, 8, noise_blob, &st);
    wvol_compressed cc;
    wvol_compress_params cp;
    wvol_image *img = NULL;
    wvol_camera cam;
    wvol_render_params p;
    wvol_tf tf;
    wvol_error err;
    const double dir[3] = {0, 0, 1};
    wvol_compress_params_default(&cp);
    cp.levels = 2;
    cp.select.mode = WVOL_SELECT_FRACTION;
    cp.select.fraction = 0.2;
    cp.build_residual = 1;
    CHECK(v && wvol_compress(&cc, v, &cp, &err) == WVOL_OK && wvol_image_create(&img, 8, 8, NULL) == WVOL_OK, "setup");
    camera(&cam, cc.store, dir, WVOL_PROJECTION_ORTHOGRAPHIC, 8, 8);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    CHECK(wvol_render_bound(img, NULL, 0, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "NULL residual");
    CHECK(wvol_render_bound(img, cc.store, 0, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "not a majorant store");
    CHECK(strstr(err.message, "majorant") != NULL, "message names the majorant: %s", err.message);
    CHECK(wvol_render_bound(img, cc.residual, NAN, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "NaN error");
    CHECK(wvol_render_bound(img, cc.residual, -1, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "negative error");
    CHECK(wvol_render_bound(img, cc.residual, 0, &cam, &tf, &p, NULL, &err) == WVOL_OK, "a good call: %s", err.message);
    p.mode = WVOL_RENDER_MODE_ABSORPTION_LINEAR;
    CHECK(wvol_render_bound(img, cc.residual, 0, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED,
          "absorption-linear");
    p.mode = WVOL_RENDER_MODE_ABSORPTION;
    p.shading = 1;
    CHECK(wvol_render_bound(img, cc.residual, 0, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED, "shading");
    CHECK(strstr(err.message, "shading") != NULL, "message names shading: %s", err.message);
    wvol_image_destroy(img);
    wvol_compressed_free(&cc);
    wvol_volume_destroy(v);
}

/* The iterator's refusals: bad parameters, a wrong bound image, a pass after the last. */
static void progressive_refusals(void)
{
    uint64_t st = 9;
    wvol_volume *v = fixture_volume(8, 8, 8, noise_blob, &st);
    wvol_progressive *pr = NULL;
    wvol_progressive_params pp;
    wvol_progressive_pass pass;
    wvol_image *img = NULL, *small = NULL;
    wvol_camera cam;
    wvol_render_params rp;
    wvol_error err;
    wvol_store *s = fixture_store(v, "haar", 2, 1.0, 0);
    const double dir[3] = {0, 0, 1};
    int n = 0;
    CHECK(s != NULL, "store");
    camera(&cam, s, dir, WVOL_PROJECTION_ORTHOGRAPHIC, 8, 8);
    wvol_render_params_default(&rp);
    rp.mode = WVOL_RENDER_MODE_XRAY;
    wvol_progressive_params_default(&pp);
    pp.growth = 1.0;
    CHECK(wvol_progressive_begin(&pr, v, NULL, &pp, &err) == WVOL_ERR_ARG && !pr, "growth 1");
    wvol_progressive_params_default(&pp);
    pp.max_error = -1;
    CHECK(wvol_progressive_begin(&pr, v, NULL, &pp, &err) == WVOL_ERR_ARG && !pr, "negative target");
    pp.max_error = 1;
    pp.bound = WVOL_BOUND_NONE;
    CHECK(wvol_progressive_begin(&pr, v, NULL, &pp, &err) == WVOL_ERR_ARG && !pr, "target without bound");
    wvol_progressive_params_default(&pp);
    pp.growth = 64;
    CHECK(wvol_progressive_begin(&pr, v, NULL, &pp, &err) == WVOL_OK, "begin: %s", err.message);
    CHECK(wvol_image_create(&img, 8, 8, NULL) == WVOL_OK && wvol_image_create(&small, 4, 4, NULL) == WVOL_OK, "images");
    CHECK(wvol_progressive_next(pr, img, small, &cam, NULL, &rp, &pass, &err) == WVOL_ERR_ARG, "bound size");
    wvol_image_destroy(small);
    small = NULL;
    CHECK(wvol_image_create(&small, 8, 8, NULL) == WVOL_OK, "bound image");
    do {
        CHECK(wvol_progressive_next(pr, img, small, &cam, NULL, &rp, &pass, &err) == WVOL_OK, "pass: %s", err.message);
        n++;
    } while (!pass.last && n < 10);
    CHECK(pass.last && strcmp(pass.stop, "complete") == 0 && pass.bound_max == 0, "the last pass keeps all");
    CHECK(wvol_progressive_next(pr, img, small, &cam, NULL, &rp, &pass, &err) == WVOL_ERR_ARG, "after the last");
    CHECK(n >= 2, "%d passes", n);
    wvol_progressive_end(pr);
    wvol_image_destroy(img);
    wvol_image_destroy(small);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

int main(void)
{
    bound_holds_on_every_pixel();
    bound_is_tight_for_one_signed_functions();
    coefficient_error_bound_holds();
    bad_calls_are_refused();
    progressive_refusals();
    return check_summary("test_render_bound");
}
