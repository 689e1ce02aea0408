/* SPDX-License-Identifier: MIT */
/* Tests of the X-ray splat fast path (libwvol/src/render/xray_splat.c) against the exact
 * spline-projected integrator on the same store: oblique orthographic views, every band and
 * level (random volumes), functions the box clips and periodic images (odd sizes, padded
 * grids), anisotropic spacing, Haar's discontinuous boxes; and its refusals. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

typedef struct field {
    uint64_t seed;
    double noise;   /* share of uniform noise on top of a smooth blob */
} field;

static double blob_and_noise(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    field *f = (field *)ctx;
    double x = (i - (v->nx - 1) / 2.0) / (v->nx / 5.0), y = (j - (v->ny - 1) / 2.0) / (v->ny / 4.0),
           z = (k - (v->nz - 1) / 2.0) / (v->nz / 6.0);
    return exp(-0.5 * (x * x + y * y + z * z)) + f->noise * (fixture_urand(&f->seed) - 0.5);
}

/* Both paths use the store's splines; coarse ones (J = 3) keep the exact path quick. */
static wvol_store *store_of(const wvol_volume *v, const char *family, int levels, double keep)
{
    wvol_store *s = fixture_store(v, family, levels, keep, 3);
    CHECK(s != NULL, "store of %s", family);
    return s;
}

/* Relative RMSE of splat against spline (X-ray, channel 0), and the largest pixel error
 * relative to the image's peak; alpha must agree exactly. */
static void compare(const wvol_store *s, const wvol_volume *v, const char *camspec, int w, int h, double tol_rmse,
                    double tol_max, const char *what)
{
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_render_stats st;
    wvol_error err;
    double rel, mx = 0, peak = 0;
    size_t i, alpha_diff = 0;
    wvol_geometry_of_volume(&g, v);
    CHECK(wvol_camera_parse(&cam, camspec, &g, w, h, &err) == WVOL_OK, "%s", err.message);
    wvol_image_create(&a, w, h, NULL);
    wvol_image_create(&b, w, h, NULL);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    CHECK(wvol_render_spline(a, s, &cam, NULL, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_render_xray_splat(b, s, &cam, &p, &st, &err) == WVOL_OK, "%s", err.message);
    for (i = 0; i < (size_t)w * h; i++) {
        peak = fmax(peak, fabs(a->rgba[4 * i]));
        if (a->rgba[4 * i + 3] != b->rgba[4 * i + 3]) alpha_diff++;
    }
    for (i = 0; i < (size_t)w * h; i++) mx = fmax(mx, fabs(a->rgba[4 * i] - b->rgba[4 * i]) / peak);
    rel = wvol_image_rmse(b, a, 0, 1);
    printf("splat vs spline, %s, %s: relative RMSE %.3g, max %.3g of the peak %.4g (%zu function images, %zu "
           "pixel visits)\n",
           what, camspec, rel, mx, peak, st.functions, st.samples);
    CHECK(rel < tol_rmse, "%s %s: splat vs spline relative RMSE %g (allowed %g)", what, camspec, rel, tol_rmse);
    CHECK(mx < tol_max, "%s %s: splat vs spline max error %g of the peak (allowed %g)", what, camspec, mx, tol_max);
    CHECK(alpha_diff == 0, "%s %s: %zu pixels differ in alpha (which rays meet the box)", what, camspec, alpha_diff);
    CHECK(st.rays_hit > 0 && st.functions > 0, "%s: stats not filled", what);
    wvol_image_destroy(a);
    wvol_image_destroy(b);
}

static void splat_matches_the_spline_integrator(void)
{
    struct {
        const char *family;
        size_t nx, ny, nz;
        int levels;
        double keep, noise, sp[3];
        int ncam;   /* Haar: the oblique views only (see below) */
        double tol_rmse, tol_max;
    } cases[] = {
        {"db2", 16, 16, 16, 2, 1.0, 0.3, {1, 1, 1}, 3, 3e-3, 2.5e-2},
        {"db2", 20, 13, 17, 2, 0.3, 0.3, {1, 1, 1}, 3, 3e-3, 2.5e-2}, /* padded grid: periodic images, clipping */
        {"haar", 16, 12, 16, 3, 1.0, 0.3, {1, 1, 1}, 2, 8e-3, 5e-2},
        {"coif1", 16, 16, 16, 2, 0.5, 0.3, {0.8, 1.0, 1.5}, 3, 8e-3, 5e-2},
        {"db4", 16, 16, 16, 1, 1.0, 0.3, {1, 1, 1}, 3, 8e-3, 5e-2},
    };
    /* Tolerances: the tables' interpolation error, measured on these cases with J = 3 splines
     * (relative RMSE 4e-4..2e-3 for db2, up to 4.4e-3 for coif1 and db4, whose longer
     * supports get proportionally coarser grids; the largest pixel error 5-8 times the RMSE),
     * with a margin of about 1.5-2. Small volumes are the hard case: most functions are
     * clipped by the box, and the 3D table is coarser than the 2D one. Haar's
     * boxes project to footprints with jumps, which bilinear interpolation smears over one
     * table step: oblique views 2-4e-3, but a view along an axis puts whole pixel columns on
     * the jumps (3e-2; the axis fast path serves that view exactly). */
    const char *cams[] = {"ortho dir=1,0.7,0.4", "ortho dir=-0.3,1,-0.8 zoom=1.6", "ortho dir=0,0,1"};
    size_t ci;
    int vi;
    for (ci = 0; ci < sizeof cases / sizeof cases[0]; ci++) {
        field f = {0x9e3779b97f4a7c15ull + ci, cases[ci].noise};
        wvol_volume *v = fixture_volume(cases[ci].nx, cases[ci].ny, cases[ci].nz, blob_and_noise, &f);
        wvol_store *s;
        char what[96];
        if (!v) continue;
        wvol_volume_set_geometry(v, cases[ci].sp, NULL, NULL);
        s = store_of(v, cases[ci].family, cases[ci].levels, cases[ci].keep);
        snprintf(what, sizeof what, "%s %zux%zux%zu keep %g", cases[ci].family, cases[ci].nx, cases[ci].ny,
                 cases[ci].nz, cases[ci].keep);
        for (vi = 0; s && vi < cases[ci].ncam; vi++)
            compare(s, v, cams[vi], 32, 24, cases[ci].tol_rmse, cases[ci].tol_max, what);
        wvol_store_destroy(s);
        wvol_volume_destroy(v);
    }
}

/* What the splat cannot do is refused with WVOL_ERR_UNSUPPORTED or WVOL_ERR_ARG and a message,
 * never rendered wrongly. */
static void splat_refuses_what_it_cannot_do(void)
{
    field f = {7, 0.0};
    wvol_volume *v = fixture_volume(16, 16, 16, blob_and_noise, &f), *flat = fixture_volume(16, 16, 1, blob_and_noise, &f);
    wvol_store *s = v ? store_of(v, "db2", 2, 1.0) : NULL, *sbl = v ? store_of(v, "bl3", 1, 1.0) : NULL,
               *sflat = flat ? store_of(flat, "db2", 2, 1.0) : NULL;
    wvol_geometry g;
    wvol_camera ortho, persp;
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_error err;
    float colors[3 * 16 * 16 * 16] = {0};
    if (!s || !sbl || !sflat) goto done;
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&ortho, "ortho dir=1,0.7,0.4", &g, 16, 16, NULL);
    wvol_camera_parse(&persp, "persp dir=1,0.7,0.4", &g, 16, 16, NULL);
    wvol_image_create(&img, 16, 16, NULL);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_ABSORPTION;
    CHECK(wvol_render_xray_splat(img, s, &ortho, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED && strstr(err.message, "X-ray"),
          "absorption accepted: %s", err.message);
    p.mode = WVOL_RENDER_MODE_XRAY;
    CHECK(wvol_render_xray_splat(img, s, &persp, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED &&
              strstr(err.message, "orthographic"),
          "perspective accepted: %s", err.message);
    CHECK(wvol_render_xray_splat(img, sbl, &ortho, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED && strstr(err.message, "taps"),
          "bl3 accepted: %s", err.message);
    CHECK(wvol_render_xray_splat(img, sflat, &ortho, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED &&
              strstr(err.message, "transformed"),
          "a volume of one slice accepted: %s", err.message);
    CHECK(wvol_render_xray_splat(img, NULL, &ortho, &p, NULL, &err) == WVOL_ERR_ARG, "no store accepted");
    p.skip_tolerance = 1e-3;
    CHECK(wvol_render_xray_splat(img, s, &ortho, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED &&
              strstr(err.message, "skip tolerance"), "a skip tolerance accepted: %s", err.message);
    p.skip_tolerance = 0;
    p.colors = colors;
    p.colors_count = sizeof colors / sizeof colors[0];
    CHECK(wvol_render_xray_splat(img, s, &ortho, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED &&
              strstr(err.message, "colour volume"), "a colour volume accepted: %s", err.message);
    p.colors = NULL;
    p.colors_count = 0;
    {
        wvol_image *small = NULL;
        wvol_image_create(&small, 8, 8, NULL);
        CHECK(wvol_render_xray_splat(small, s, &ortho, &p, NULL, &err) == WVOL_ERR_ARG, "an image of the wrong size accepted");
        wvol_image_destroy(small);
    }
    CHECK(wvol_render_xray_splat(img, s, &ortho, &p, NULL, &err) == WVOL_OK, "%s", err.message);
done:
    wvol_image_destroy(img);
    wvol_store_destroy(s);
    wvol_store_destroy(sbl);
    wvol_store_destroy(sflat);
    wvol_volume_destroy(v);
    wvol_volume_destroy(flat);
}

int main(void)
{
    splat_matches_the_spline_integrator();
    splat_refuses_what_it_cannot_do();
    return check_summary("test_render_splat");
}
