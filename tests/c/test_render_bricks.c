/* SPDX-License-Identifier: MIT
 * Tests of the bricked renderer (libwvol/src/render/bricks.c): from a store it must give the
 * reference integrator's image of the store's dense reconstruction, for every mode, camera,
 * brick size and kept fraction, and skip bricks on their coefficient bound. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

/* A shell (value 1 for radius in [0.25, 0.4] of the half size, smooth edges) in a zero
 * background, plus a faint Gaussian blob: bricks far from both are empty. Not a cube, and
 * not a multiple of 2^levels along x, so padding and clipped edge bricks are exercised. */
static double phantom_voxel(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double x = (i - (v->nx - 1) / 2.0) / (v->nx / 2.0), y = (j - (v->ny - 1) / 2.0) / (v->ny / 2.0),
           z = (k - (v->nz - 1) / 2.0) / (v->nz / 2.0), r = sqrt(x * x + y * y + z * z);
    double shell = 0.5 * (tanh((r - 0.25) / 0.04) - tanh((r - 0.4) / 0.04));
    double blob = 0.3 * exp(-((x - 0.1) * (x - 0.1) + y * y + z * z) / 0.02);
    (void)ctx;
    return r > 0.5 ? 0.0 : shell + blob;
}

static wvol_volume *phantom(size_t nx, size_t ny, size_t nz) { return fixture_volume(nx, ny, nz, phantom_voxel, NULL); }

/* The phantom as a CT scanner gives it: noise everywhere (uniform, +-0.06 from a hash of the
 * voxel index, the air included, so the background's values straddle 0 and many bricks'
 * ranges reach the TF's ramp at 0.2 only through noise peaks), anisotropic voxels (slices 2.3
 * times the in-plane spacing, so rays along z take more steps per voxel than along x), and
 * a thin shell outside the object (a "table": one voxel thick at y = 0.8 of the half size). */
static double noisy_voxel(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    uint64_t h = (uint64_t)(i + v->nx * (j + v->ny * k)) * 0x9E3779B97F4A7C15ull;
    double y = (j - (v->ny - 1) / 2.0) / (v->ny / 2.0), table = fabs(y - 0.8) < 1.0 / v->ny ? 0.7 : 0.0;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 32;
    return phantom_voxel(v, i, j, k, ctx) + table + 0.12 * ((double)(h >> 11) / 9007199254740992.0 - 0.5);
}

static wvol_volume *noisy_phantom(size_t nx, size_t ny, size_t nz)
{
    const double sp[3] = {1.0, 1.0, 2.3};
    return fixture_with_spacing(fixture_volume(nx, ny, nz, noisy_voxel, NULL), sp);
}

/* Store of the kept coefficients (db2, 2 levels) and the dense reconstruction of the same
 * coefficients. */
static wvol_store *store_and_recon(const wvol_volume *v, double keep, wvol_volume **recon)
{
    wvol_compressed c;
    wvol_store *s;
    wvol_error err;
    *recon = NULL;
    CHECK(fixture_compress(&c, v, "db2", 2, keep, 0, 1) == 0, "keep %g", keep);
    if (!c.store) return NULL;
    CHECK(wvol_idwt3(recon, c.coeffs, &err) == WVOL_OK, "%s", err.message);
    s = c.store;
    c.store = NULL;
    wvol_compressed_free(&c);
    return s;
}

/* Images of W x H pixels with the transfer function TF; returns the bricks built (0 when the
 * case could not run). The default TF: kappa 0 below 0.2, so the background (and the ringing
 * of the compressed store around 0) is transparent and bricks there are empty. */
static int W = 40, H = 32;
#define TF_COLOURED "units diagonal\n0 0.2 0.3 0.9 0\n0.2 0.2 0.3 0.9 0\n1 1 0.8 0.5 30\n"
static const char *TF = TF_COLOURED;
static size_t one_case(const wvol_store *s, const wvol_volume *recon, const char *camspec, wvol_render_mode mode,
                       int shading, int brick, int threads, const float *colors, const char *what)
{
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_render_stats st;
    wvol_tf tf;
    wvol_error err;
    double e;
    memset(&st, 0, sizeof st);
    wvol_geometry_of_volume(&g, recon);
    CHECK(wvol_camera_parse(&cam, camspec, &g, W, H, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_parse(&tf, TF, "tf", &err) == WVOL_OK, "%s", err.message);
    wvol_render_params_default(&p);
    p.mode = mode;
    p.shading = shading;
    p.threads = threads;
    p.step = 0.4;
    if (colors) {
        p.colors = colors;
        p.colors_count = 3 * wvol_volume_count(recon);
    }
    CHECK(wvol_image_create(&a, W, H, &err) == WVOL_OK && wvol_image_create(&b, W, H, &err) == WVOL_OK, "%s",
          err.message);
    if (!a || !b) return 0;
    CHECK(wvol_render_reference(a, recon, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    p.bricks.brick = brick;
    CHECK(wvol_render_bricks(b, s, &cam, &tf, &p, &st, &err) == WVOL_OK, "%s: %s", what, err.message);
    /* Same samples, weights and compositing on two reconstructions of the same coefficients
     * that differ by float rounding (whole-volume and per-brick float synthesis, summed in
     * different orders: ~1e-7 relative), so the images differ by about that. 2e-5 leaves room
     * for the exp of opacities near 1 while a wrong brick, apron or offset gives 1e-3 or more. */
    e = wvol_image_rmse(b, a, -1, 1);
    CHECK(e < 2e-5, "%s: bricks against reference on the reconstruction: rel. RMSE %.3g", what, e);
    CHECK(st.bricks_built > 0 && st.bytes > 0, "%s: stats %zu bricks, %zu bytes", what, st.bricks_built, st.bytes);
    CHECK(st.brick == (brick > 0 ? brick : 32), "%s: brick side %d used", what, st.brick);
    /* X-ray skips a brick only when its bound is exactly [0, 0]: every coefficient whose
     * support reaches it is zero (the phantom's corners, beyond r = 0.5), which the bound
     * proves without the rounding pad of a nonzero neighbourhood */
    CHECK(st.bricks_bound_skipped > 0, "%s: no brick skipped on its bound (%zu built)", what, st.bricks_built);
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    return st.bricks_built;
}

static void bricks_equal_reference_on_the_reconstruction(void)
{
    wvol_volume *v = phantom(66, 60, 52), *recon = NULL;
    const double keeps[2] = {1.0, 0.05};
    float *colors;
    size_t nv, q;
    int i;
    if (!v) return;
    /* a colour volume of blocky classes: the nearest-voxel lookup must read the same voxel */
    nv = wvol_volume_count(v);
    colors = malloc(3 * nv * sizeof *colors);
    if (colors)
        for (q = 0; q < nv; q++) {
            size_t cls = ((q % 66) / 7 + (q / 66 % 60) / 5 + q / (66 * 60) / 6) % 3;
            colors[3 * q] = cls == 0 ? 1.0f : 0.1f;
            colors[3 * q + 1] = cls == 1 ? 1.0f : 0.2f;
            colors[3 * q + 2] = cls == 2 ? 1.0f : 0.3f;
        }
    for (i = 0; i < 2; i++) {
        wvol_store *s = store_and_recon(v, keeps[i], &recon);
        char what[96];
        if (!s || !recon) break;
        snprintf(what, sizeof what, "keep %g persp absorption B=16", keeps[i]);
        one_case(s, recon, "persp dir=1,0.7,0.4", WVOL_RENDER_MODE_ABSORPTION, 0, 16, 2, NULL, what);
        /* one colour: the blocked loop's shortcut, whose optical depth stays pending in the
         * ray's state until the ray ends; past the phantom the rays' last samples are
         * transparent, so nothing but the walk's end brings T and the colour up to date */
        TF = "units diagonal\n0 1 1 1 0\n0.2 1 1 1 0\n1 1 1 1 30\n";
        snprintf(what, sizeof what, "keep %g persp absorption one colour B=16", keeps[i]);
        one_case(s, recon, "persp dir=1,0.7,0.4", WVOL_RENDER_MODE_ABSORPTION, 0, 16, 2, NULL, what);
        TF = TF_COLOURED;
        if (i == 1) {
            /* bricks of 2: 33 x 30 x 26 = 25 740 of them, far more than a thread's cache slots
             * (a few); an X-ray view at 2 pixels per voxel meets every brick not proven zero,
             * in many tiles, so slots are evicted and reused: the image must not change */
            size_t built;
            snprintf(what, sizeof what, "keep %g oblique xray B=2 (evictions)", keeps[i]);
            W = 132, H = 120;
            built = one_case(s, recon, "ortho dir=0.2,0.1,-1 zoom=0.9", WVOL_RENDER_MODE_XRAY, 0, 2, 2, NULL, what);
            W = 40, H = 32;
            CHECK(built > 8192, "%s: %zu bricks built, no eviction exercised", what, built);
        }
        /* 0: the library chooses (32) */
        snprintf(what, sizeof what, "keep %g persp xray B=0 (chosen)", keeps[i]);
        one_case(s, recon, "persp dir=1,0.7,0.4", WVOL_RENDER_MODE_XRAY, 0, 0, 1, NULL, what);
        snprintf(what, sizeof what, "keep %g ortho +z absorption-linear B=8", keeps[i]);
        one_case(s, recon, "+z", WVOL_RENDER_MODE_ABSORPTION_LINEAR, 0, 8, 1, NULL, what);
        snprintf(what, sizeof what, "keep %g ortho oblique xray B=5", keeps[i]);
        one_case(s, recon, "ortho dir=-0.3,1,-0.6", WVOL_RENDER_MODE_XRAY, 0, 5, 2, NULL, what);
        snprintf(what, sizeof what, "keep %g persp inside, shaded B=16", keeps[i]);
        one_case(s, recon, "persp eye=30,28,25 center=60,40,40 fov=70", WVOL_RENDER_MODE_ABSORPTION, 1, 16, 1, NULL, what);
        if (colors) {
            snprintf(what, sizeof what, "keep %g persp, colour volume B=16", keeps[i]);
            one_case(s, recon, "persp dir=-1,0.5,0.8", WVOL_RENDER_MODE_ABSORPTION, 0, 16, 2, colors, what);
        }
        wvol_store_destroy(s);
        wvol_volume_destroy(recon);
        recon = NULL;
    }
    wvol_volume_destroy(recon);
    wvol_volume_destroy(v);
    free(colors);
}

/* A tile's rays walk the bricks front to back (render/ref_bricks.c), so one tile
 * holding the whole image builds each brick at most once, whatever the view and with two
 * threads sharing the tile: rays that enter the volume from every side, parallel rays with
 * negative direction components, rays starting inside it. A walk out of order would rebuild
 * bricks (the cache holds a few of them). The image is the same bit for bit with small tiles
 * and one thread: the same samples in the same order. */
static void walk_builds_each_brick_once(void)
{
    wvol_volume *v = phantom(66, 60, 52), *recon = NULL;
    wvol_store *s = v ? store_and_recon(v, 0.05, &recon) : NULL;
    const char *cams[4] = {"ortho dir=-0.3,1,-0.6", "persp dir=1,0.7,0.4", "persp dir=-0.6,-0.2,-1",
                           "persp eye=30,28,25 center=60,40,40 fov=70"};
    const size_t nbricks = 9 * 8 * 7; /* 66 x 60 x 52 voxels in bricks of 8 */
    wvol_geometry g;
    wvol_tf tf;
    wvol_error err;
    if (!s || !recon) goto done;
    wvol_geometry_of_volume(&g, recon);
    CHECK(wvol_tf_parse(&tf, "units diagonal\n0 1 1 1 0\n1 1 1 1 4\n", "tf", &err) == WVOL_OK, "%s", err.message);
    for (int c = 0; c < 4; c++) {
        wvol_camera cam;
        wvol_image *a = NULL, *b = NULL;
        wvol_render_params p;
        wvol_render_stats sa, sb;
        CHECK(wvol_camera_parse(&cam, cams[c], &g, 64, 56, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_image_create(&a, 64, 56, &err) == WVOL_OK && wvol_image_create(&b, 64, 56, &err) == WVOL_OK, "%s",
              err.message);
        if (!a || !b) break;
        wvol_render_params_default(&p);
        p.mode = WVOL_RENDER_MODE_ABSORPTION;
        p.bricks.brick = 8;
        p.threads = 2; /* the threads share the tile's bricks: still one build each */
        p.tile = 64;
        CHECK(wvol_render_bricks(a, s, &cam, &tf, &p, &sa, &err) == WVOL_OK, "%s: %s", cams[c], err.message);
        CHECK(sa.bricks_built > 0 && sa.bricks_built <= nbricks, "%s: one tile built %zu bricks of %zu", cams[c],
              sa.bricks_built, nbricks);
        p.tile = 8;
        p.threads = 1;
        CHECK(wvol_render_bricks(b, s, &cam, &tf, &p, &sb, &err) == WVOL_OK, "%s: %s", cams[c], err.message);
        CHECK(memcmp(a->rgba, b->rgba, 4 * sizeof(float) * 64 * 56) == 0, "%s: tiles of 64 and of 8 differ", cams[c]);
        CHECK(sb.samples == sa.samples, "%s: %zu samples against %zu", cams[c], sb.samples, sa.samples);
        wvol_image_destroy(a);
        wvol_image_destroy(b);
    }
done:
    wvol_store_destroy(s);
    wvol_volume_destroy(recon);
    wvol_volume_destroy(v);
}

/* A bricked brick reconstruction equals wvol_idwt3_brick on the dense coefficients, which
 * is checked against wvol_idwt3 by the wavelet tests; here the sparse gather must give the
 * same numbers where whole bands are absent (a single kept detail coefficient). */
static void single_coefficient_store(void)
{
    wvol_volume *v = NULL, *recon = NULL;
    const wvol_filter *f = NULL;
    wvol_coeffs *c = NULL;
    wvol_store *s = NULL;
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_error err;
    double e;
    CHECK(wvol_volume_create(&v, 32, 32, 32, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_filter_get(&f, "db2", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_dwt3(&c, v, f, 2, &err) == WVOL_OK, "%s", err.message);
    if (!c) return;
    c->data[20 + 32 * (5 + 32 * 9)] = 3.0f; /* level 1, band 1 (x high), position (4, 5, 9) */
    c->data[0] = 1.0f;                      /* and the low-pass corner */
    CHECK(wvol_store_build(&s, c, NULL, NULL, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_idwt3(&recon, c, &err) == WVOL_OK, "%s", err.message);
    wvol_geometry_of_volume(&g, recon);
    CHECK(wvol_camera_parse(&cam, "ortho dir=1,0.2,0.1", &g, 24, 24, &err) == WVOL_OK, "%s", err.message);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    p.threads = 1;
    CHECK(wvol_image_create(&a, 24, 24, &err) == WVOL_OK && wvol_image_create(&b, 24, 24, &err) == WVOL_OK, "%s",
          err.message);
    if (a && b && s && recon) {
        CHECK(wvol_render_reference(a, recon, &cam, NULL, &p, NULL, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_render_bricks(b, s, &cam, NULL, &p, NULL, &err) == WVOL_OK, "%s", err.message);
        e = wvol_image_rmse(b, a, -1, 1);
        CHECK(e < 2e-5, "single coefficient: rel. RMSE %.3g (tolerance as above)", e);
    }
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_store_destroy(s);
    wvol_volume_destroy(recon);
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
}

/* skip_tolerance: a brick whose contribution rate times the ray's length in it fits in what
 * is left of the tolerance is skipped, and the change to every pixel is bounded: alpha and
 * (colours <= 1) each channel by the optical depth skipped, X-ray by the integral bound
 * skipped; stats->skip_bound is the largest such depth and never exceeds the tolerance. Both
 * sources: bricks from a store, the reference on its dense reconstruction. The TF's kappa
 * is linear from 0 (no transparent band), so the store's ringing around 0 in the background
 * is a faint haze that tolerance can skip and exact skipping cannot. */
static void skip_tolerance_bounds_the_change_on(wvol_volume *v, const char *vname)
{
    wvol_volume *recon = NULL;
    wvol_store *s = store_and_recon(v, 0.1, &recon);
    const wvol_render_mode modes[3] = {WVOL_RENDER_MODE_ABSORPTION, WVOL_RENDER_MODE_ABSORPTION_LINEAR, WVOL_RENDER_MODE_XRAY};
    const double tols[2] = {1e-3, 2e-2};
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_error err;
    wvol_image *a = NULL, *b = NULL;
    size_t any_skipped = 0;
    if (!s || !recon) return;
    wvol_geometry_of_volume(&g, recon);
    CHECK(wvol_camera_parse(&cam, "persp dir=1,0.7,0.4", &g, W, H, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_parse(&tf, "units diagonal\n0 1 1 1 0\n1 1 1 1 8\n", "tf", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_image_create(&a, W, H, &err) == WVOL_OK && wvol_image_create(&b, W, H, &err) == WVOL_OK, "%s",
          err.message);
    for (int bricked = 0; bricked < 2 && a && b; bricked++)
        for (int m = 0; m < 3; m++)
            for (int t = 0; t < 2; t++) {
                wvol_render_params p;
                wvol_render_stats st;
                wvol_status sa, sb;
                double worst = 0, peak = 0;
                wvol_render_params_default(&p);
                p.mode = modes[m];
                if (bricked) p.bricks.brick = 8;
                else p.reference.brick = 4;
                if (bricked) sa = wvol_render_bricks(a, s, &cam, &tf, &p, NULL, &err);
                else sa = wvol_render_reference(a, recon, &cam, &tf, &p, NULL, &err);
                CHECK(sa == WVOL_OK, "%s", err.message);
                p.skip_tolerance = tols[t];
                memset(&st, 0, sizeof st);
                if (bricked) sb = wvol_render_bricks(b, s, &cam, &tf, &p, &st, &err);
                else sb = wvol_render_reference(b, recon, &cam, &tf, &p, &st, &err);
                CHECK(sb == WVOL_OK, "%s", err.message);
                if (sa != WVOL_OK || sb != WVOL_OK) continue;
                for (size_t i = 0; i < 4 * (size_t)W * H; i++) {
                    double d = fabs((double)a->rgba[i] - b->rgba[i]);
                    if (d > worst) worst = d;
                    if (fabs(a->rgba[i]) > peak) peak = fabs(a->rgba[i]);
                }
                /* the bound, plus the image's float rounding and early termination's
                 * threshold (a skipped run can move where a ray stops: < 1e-6 of it left) */
                CHECK(st.skip_bound <= tols[t] * (1 + 1e-12), "%s mode %d tol %g: skip bound %.3g over the tolerance",
                      bricked ? "bricks" : "reference", m, tols[t], st.skip_bound);
                CHECK(worst <= st.skip_bound + 1e-6 * (1 + peak) + p.termination,
                      "%s mode %d tol %g: a pixel changed by %.3g, the bound is %.3g", bricked ? "bricks" : "reference",
                      m, tols[t], worst, st.skip_bound);
                CHECK((st.skipped_tolerance > 0) == (st.skip_bound > 0), "%s mode %d: %zu runs skipped, bound %.3g",
                      bricked ? "bricks" : "reference", m, st.skipped_tolerance, st.skip_bound);
                any_skipped += st.skipped_tolerance;
            }
    /* the haze is there: the test exercised skipping, not only the bound's bookkeeping */
    CHECK(any_skipped > 0, "%s: no brick run was skipped under any tolerance", vname);
    {
        /* refused where there is no brick grid to skip by, and when not finite or negative */
        wvol_render_params p;
        wvol_render_params_default(&p);
        p.skip_tolerance = 1e-3;
        CHECK(wvol_render_spline(a, s, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED, "spline accepted a skip tolerance");
        p.reference.brick = 0;
        CHECK(wvol_render_reference(a, recon, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED,
              "reference without bricks accepted a skip tolerance");
        CHECK(strstr(err.message, "skip tolerance") != NULL, "message: %s", err.message);
        p.reference.brick = 8;
        p.skip_tolerance = -1e-3;
        CHECK(wvol_render_bricks(a, s, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "negative skip tolerance accepted");
        p.skip_tolerance = NAN;
        CHECK(wvol_render_reference(a, recon, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "NaN skip tolerance accepted");
    }
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_store_destroy(s);
    wvol_volume_destroy(recon);
    wvol_volume_destroy(v);
}

/* The skip tolerance's bound holds on the smooth phantom and on the noisy, anisotropic one,
 * whose bricks straddle the TF's zero range through noise alone. */
static void skip_tolerance_bounds_the_change(void)
{
    skip_tolerance_bounds_the_change_on(phantom(66, 60, 52), "phantom");
    skip_tolerance_bounds_the_change_on(noisy_phantom(66, 60, 40), "noisy anisotropic phantom");
}

/* Skipping inside a brick (wvol_render_params.bricks.skip_inside: sub-cells whose kappa is 0)
 * changes no pixel beyond rounding: on the noisy anisotropic phantom, with views along the
 * long axis, across it and oblique, a skipped sample would have composited as kappa 0, a
 * no-op. What differs is where the blocked loop's blocks of 8 start (runs are cut at the
 * sub-cells): each block's positions are rounded to float relative to its first one (within
 * 4e-6 voxel), which moves samples by that (measured: pixels within 2.4e-7, bound 1e-6), and
 * the one-colour path's float sum of kappa regroups (bound 2e-6, as its own test's).
 * It must skip something (fewer samples), or it tests nothing; a sub-cell marked zero that
 * is not (a voxel range one short, a sub-cell index off by one) changes pixels by 1e-3 or more. */
static void skipping_inside_bricks_changes_nothing(void)
{
    wvol_volume *v = noisy_phantom(70, 64, 40), *recon = NULL;
    wvol_store *s = v ? store_and_recon(v, 0.05, &recon) : NULL;
    const char *cams[4] = {"+z", "+x", "persp dir=1,0.7,0.4", "ortho dir=-0.3,1,-0.6"};
    const char *tfs[2] = {TF_COLOURED, "units diagonal\n0 1 1 1 0\n0.2 1 1 1 0\n1 1 1 1 30\n"};
    wvol_geometry g;
    wvol_error err;
    size_t fewer = 0;
    if (!s || !recon) goto done;
    wvol_geometry_of_volume(&g, recon);
    for (int c = 0; c < 4; c++)
        for (int m = 0; m < 3; m++) {
            wvol_camera cam;
            wvol_tf tf;
            wvol_image *a = NULL, *b = NULL;
            wvol_render_params p;
            wvol_render_stats sa, sb;
            double worst = 0;
            CHECK(wvol_camera_parse(&cam, cams[c], &g, 56, 48, &err) == WVOL_OK, "%s", err.message);
            CHECK(wvol_tf_parse(&tf, tfs[m == 1], "tf", &err) == WVOL_OK, "%s", err.message);
            CHECK(wvol_image_create(&a, 56, 48, &err) == WVOL_OK && wvol_image_create(&b, 56, 48, &err) == WVOL_OK,
                  "%s", err.message);
            if (!a || !b) break;
            wvol_render_params_default(&p);
            p.mode = m == 2 ? WVOL_RENDER_MODE_XRAY : WVOL_RENDER_MODE_ABSORPTION;
            p.bricks.brick = 16;
            p.step = 0.45;
            CHECK(wvol_render_bricks(a, s, &cam, &tf, &p, &sa, &err) == WVOL_OK, "%s: %s", cams[c], err.message);
            p.bricks.skip_inside = 0;
            CHECK(wvol_render_bricks(b, s, &cam, &tf, &p, &sb, &err) == WVOL_OK, "%s: %s", cams[c], err.message);
            for (size_t i = 0; i < 4 * 56 * 48; i++)
                if (fabs((double)a->rgba[i] - b->rgba[i]) > worst) worst = fabs((double)a->rgba[i] - b->rgba[i]);
            CHECK(worst <= (m == 1 ? 2e-6 : 1e-6), "%s %s: skipping inside bricks changed a pixel by %.3g", cams[c],
                  m == 2 ? "xray" : m == 1 ? "one colour" : "coloured", worst);
            CHECK(sa.samples <= sb.samples, "%s: %zu samples with, %zu without", cams[c], sa.samples, sb.samples);
            fewer += sa.samples < sb.samples;
            wvol_image_destroy(a);
            wvol_image_destroy(b);
        }
    CHECK(fewer >= 4, "skipping inside bricks saved samples in only %zu of 12 cases", fewer);
done:
    wvol_store_destroy(s);
    wvol_volume_destroy(recon);
    wvol_volume_destroy(v);
}

/* Bricks known to be empty without a build (on their coefficient bound, or on their voxels
 * once any tile built them) are passed through by the rays at once, at set-up and during the
 * walk, instead of waiting on the brick's list; later tiles skip them unbuilt. Neither may
 * change a pixel, nor lose a ray: on the noisy anisotropic phantom in bricks of 8 (many of
 * them empty: a TF whose threshold the noise reaches only here and there), with tiles of 8
 * pixels (many tiles, each learning from the earlier ones' builds) against one tile holding
 * the whole image, one and two threads, the images are the same bit for bit and take the same
 * samples, and both equal the reference on the reconstruction (the tolerance of one_case: a
 * brick wrongly passed through, or a ray pushed onto a brick already walked and so never
 * finished, changes pixels by 1e-3 or more). Cameras: along the long axis, oblique,
 * perspective from outside, and perspective from the plane of the volume's top face, whose
 * rays graze that face and its bricks' edges. Then a TF whose threshold lies just above the
 * reconstruction's largest value: every brick whose loose bound reaches the threshold is
 * built and found empty, so each may be built once in all (tiles of 8 built it once per tile
 * before its rate was kept), and the image is empty. */
static void known_empty_bricks_change_nothing(void)
{
    wvol_volume *v = noisy_phantom(70, 64, 40), *recon = NULL;
    wvol_store *s = v ? store_and_recon(v, 0.05, &recon) : NULL;
    const char *cams[4] = {"+z", "ortho dir=-0.3,1,-0.6", "persp dir=1,0.7,0.4",
                           "persp eye=-80,31.5,90.85 center=34.5,31.5,90.85 fov=50"};
    const size_t nbricks = 9 * 8 * 5; /* 70 x 64 x 40 voxels in bricks of 8 */
    wvol_geometry g;
    wvol_error err;
    double vmin, vmax;
    char tfs[2][160];
    if (!s || !recon) goto done;
    wvol_geometry_of_volume(&g, recon);
    wvol_volume_range(recon, &vmin, &vmax, NULL);
    snprintf(tfs[0], sizeof tfs[0], "units diagonal\n0.3 1 0.8 0.6 0\n1 1 1 1 20\n");
    snprintf(tfs[1], sizeof tfs[1], "units diagonal\n%.17g 1 1 1 0\n%.17g 1 1 1 20\n", vmax + 1e-3 * (vmax - vmin),
             vmax + 1.0);
    for (int t = 0; t < 2; t++)
        for (int c = 0; c < 4; c++) {
            wvol_camera cam;
            wvol_tf tf;
            wvol_image *a = NULL, *b = NULL, *r = NULL;
            wvol_render_params p;
            wvol_render_stats sa, sb;
            CHECK(wvol_camera_parse(&cam, cams[c], &g, 48, 40, &err) == WVOL_OK, "%s", err.message);
            CHECK(wvol_tf_parse(&tf, tfs[t], "tf", &err) == WVOL_OK, "%s", err.message);
            CHECK(wvol_image_create(&a, 48, 40, &err) == WVOL_OK && wvol_image_create(&b, 48, 40, &err) == WVOL_OK &&
                      wvol_image_create(&r, 48, 40, &err) == WVOL_OK,
                  "%s", err.message);
            if (!a || !b || !r) break;
            wvol_render_params_default(&p);
            p.mode = WVOL_RENDER_MODE_ABSORPTION;
            p.step = 0.45;
            CHECK(wvol_render_reference(r, recon, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
            p.bricks.brick = 8;
            p.tile = 48;
            p.threads = 2;
            CHECK(wvol_render_bricks(a, s, &cam, &tf, &p, &sa, &err) == WVOL_OK, "%s: %s", cams[c], err.message);
            p.tile = 8;
            p.threads = t ? 2 : 1;
            CHECK(wvol_render_bricks(b, s, &cam, &tf, &p, &sb, &err) == WVOL_OK, "%s: %s", cams[c], err.message);
            CHECK(memcmp(a->rgba, b->rgba, 4 * sizeof(float) * 48 * 40) == 0, "%s tf %d: tiles of 48 and of 8 differ",
                  cams[c], t);
            CHECK(sb.samples == sa.samples, "%s tf %d: %zu samples against %zu", cams[c], t, sb.samples, sa.samples);
            CHECK(wvol_image_rmse(b, r, -1, 1) < 2e-5, "%s tf %d: bricks against reference on the reconstruction: "
                  "rel. RMSE %.3g", cams[c], t, wvol_image_rmse(b, r, -1, 1));
            if (t == 0) {
                double alpha = 0;
                for (size_t i = 3; i < 4 * 48 * 40; i += 4) alpha += a->rgba[i];
                CHECK(alpha > 1, "%s: the image is empty (alpha sum %.3g): nothing tested", cams[c], alpha);
            } else {
                for (size_t i = 0; i < 4 * 48 * 40; i++)
                    if (b->rgba[i] != 0.0f) {
                        CHECK(0, "%s: a pixel above the data's largest value: %g", cams[c], b->rgba[i]);
                        break;
                    }
                CHECK(sb.bricks_built > 0, "%s: no brick built: the bound proves every brick empty, nothing tested",
                      cams[c]);
                CHECK(sb.bricks_built <= nbricks, "%s: %zu builds of %zu bricks, all empty: one rebuilt", cams[c],
                      sb.bricks_built, nbricks);
            }
            wvol_image_destroy(a);
            wvol_image_destroy(b);
            wvol_image_destroy(r);
        }
done:
    wvol_store_destroy(s);
    wvol_volume_destroy(recon);
    wvol_volume_destroy(v);
}

/* Shading from the low-pass model (gradient_levels) changes the shading only: the samples,
 * so alpha, are the same bit for bit, the colour changes (the noisy phantom's gradient is
 * smoothed), and is within the colour the unshaded image bounds (shade <= 1). Refused where
 * the store has fewer levels, by the dense reference and by the spline method. */
static void lowpass_gradient_changes_only_the_shading(void)
{
    wvol_volume *v = noisy_phantom(48, 44, 30), *recon = NULL;
    wvol_store *s = v ? store_and_recon(v, 0.2, &recon) : NULL;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_error err;
    wvol_image *a = NULL, *b = NULL, *u = NULL;
    wvol_render_params p;
    double dcol = 0, dalpha = 0, over = 0;
    if (!s || !recon) goto done;
    wvol_geometry_of_volume(&g, recon);
    CHECK(wvol_camera_parse(&cam, "persp dir=1,0.7,0.4", &g, 40, 32, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_parse(&tf, TF_COLOURED, "tf", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_image_create(&a, 40, 32, &err) == WVOL_OK && wvol_image_create(&b, 40, 32, &err) == WVOL_OK &&
              wvol_image_create(&u, 40, 32, &err) == WVOL_OK,
          "%s", err.message);
    if (!a || !b || !u) goto done;
    wvol_render_params_default(&p);
    p.bricks.brick = 16;
    CHECK(wvol_render_bricks(u, s, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    p.shading = 1;
    CHECK(wvol_render_bricks(a, s, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    p.gradient_levels = 2;
    CHECK(wvol_render_bricks(b, s, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    for (size_t i = 0; i < 4 * 40 * 32; i++) {
        double d = fabs((double)a->rgba[i] - b->rgba[i]);
        if (i % 4 == 3) dalpha = fmax(dalpha, d);
        else {
            dcol = fmax(dcol, d);
            over = fmax(over, b->rgba[i] - u->rgba[i]);
        }
    }
    CHECK(dalpha == 0, "gradient_levels changed alpha by %.3g", dalpha);
    CHECK(dcol > 1e-3, "gradient_levels changed no colour (%.3g): the low-pass gradient was not used", dcol);
    CHECK(over <= 1e-6, "a shaded colour exceeds the unshaded one by %.3g", over);
    p.gradient_levels = 3; /* the store has 2 levels */
    CHECK(wvol_render_bricks(b, s, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "gradient_levels 3 of 2 accepted");
    p.gradient_levels = 1;
    CHECK(wvol_render_reference(b, recon, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED,
          "the dense reference accepted gradient_levels");
    CHECK(wvol_render_spline(b, s, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED, "spline accepted gradient_levels");
done:
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_image_destroy(u);
    wvol_store_destroy(s);
    wvol_volume_destroy(recon);
    wvol_volume_destroy(v);
}

/* On a constant volume the X-ray skip bound is tight: a skipped run of length len in a
 * brick of value c takes exactly c len off the integral, the rate times the length the
 * bookkeeping charges. So the largest change over the image equals stats->skip_bound (to
 * the float image's rounding): an accounting that charged less than it skipped, or a skip
 * that did not charge, fails here even where the general bound above is loose. */
static double constant_voxel(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)v, (void)i, (void)j, (void)k, (void)ctx;
    return 0.01;
}

static void skip_bookkeeping_is_exact_on_a_constant(void)
{
    wvol_volume *v = fixture_volume(24, 20, 28, constant_voxel, NULL);
    wvol_geometry g;
    wvol_camera cam;
    wvol_error err;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_render_stats st;
    double worst = 0;
    if (!v) return;
    wvol_geometry_of_volume(&g, v);
    CHECK(wvol_camera_parse(&cam, "ortho dir=1,0.3,0.2", &g, 24, 24, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_image_create(&a, 24, 24, &err) == WVOL_OK && wvol_image_create(&b, 24, 24, &err) == WVOL_OK, "%s",
          err.message);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    p.reference.brick = 8;
    if (a && b) {
        CHECK(wvol_render_reference(a, v, &cam, NULL, &p, NULL, &err) == WVOL_OK, "%s", err.message);
        p.skip_tolerance = 0.2; /* about two bricks' worth (0.01 x 8 voxels each) */
        memset(&st, 0, sizeof st);
        CHECK(wvol_render_reference(b, v, &cam, NULL, &p, &st, &err) == WVOL_OK, "%s", err.message);
        for (size_t i = 0; i < 4 * 24 * 24; i++)
            if (fabs((double)a->rgba[i] - b->rgba[i]) > worst) worst = fabs((double)a->rgba[i] - b->rgba[i]);
        CHECK(st.skip_bound > 0.05 && st.skip_bound <= 0.2, "constant: skip bound %.3g", st.skip_bound);
        /* float image of integrals ~0.3: 1e-6 is a few ulps */
        CHECK(fabs(worst - st.skip_bound) < 1e-6, "constant: largest change %.9g, skip bound %.9g", worst,
              st.skip_bound);
    }
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_volume_destroy(v);
}

int main(void)
{
    bricks_equal_reference_on_the_reconstruction();
    single_coefficient_store();
    walk_builds_each_brick_once();
    skip_tolerance_bounds_the_change();
    skipping_inside_bricks_changes_nothing();
    known_empty_bricks_change_nothing();
    lowpass_gradient_changes_only_the_shading();
    skip_bookkeeping_is_exact_on_a_constant();
    return check_summary("test_render_bricks");
}
