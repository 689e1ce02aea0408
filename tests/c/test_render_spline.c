/* SPDX-License-Identifier: MIT */
/* Tests of the spline-projected integrator and the axis X-ray fast path (libwvol/src/render)
 * against exact sums, against each other, and against the converged reference of the same
 * spline model (f^ sampled through the spline tables at a very small step). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

static wvol_volume *gaussian(size_t n)
{
    wvol_volume *v = NULL;
    size_t i, j, k;
    if (wvol_volume_create(&v, n, n, n, NULL) != WVOL_OK) return NULL;
    for (k = 0; k < n; k++)
        for (j = 0; j < n; j++)
            for (i = 0; i < n; i++) {
                double x = (i - (n - 1) / 2.0) / (n / 6.0), y = (j - (n - 1) / 2.0) / (n / 5.0),
                       z = (k - (n - 1) / 2.0) / (n / 7.0);
                v->data[i + n * (j + n * k)] = (float)exp(-0.5 * (x * x + y * y + z * z));
            }
    return v;
}

/* Transform, keep a fraction (1 = all), build the store (fixture_compress); the kept
 * coefficients (dropped ones zeroed) and the predicted RMSE on request. */
static wvol_store *make_store(const wvol_volume *v, const char *family, int levels, double keep, int J,
                              wvol_coeffs **coeffs_out, double *pred_rmse)
{
    wvol_compressed c;
    wvol_store *s;
    CHECK(fixture_compress(&c, v, family, levels, keep, J, 1) == 0, "%s levels %d keep %g", family, levels, keep);
    if (!c.store) return NULL;
    if (pred_rmse) *pred_rmse = c.report.predicted_rmse;
    if (coeffs_out) {
        *coeffs_out = c.coeffs;
        c.coeffs = NULL;
    }
    s = c.store;
    c.store = NULL;
    wvol_compressed_free(&c);
    return s;
}

static int image_finite(const wvol_image *img)
{
    size_t i, n = (size_t)img->width * img->height * 4;
    for (i = 0; i < n; i++)
        if (!isfinite(img->rgba[i])) return 0;
    return 1;
}

/* Haar: f^ is the voxel boxes, so an X-ray along an axis is the exact voxel sum x spacing. */
static void haar_xray_along_axis_is_the_voxel_sum(void)
{
    wvol_volume *v = gaussian(16);
    wvol_store *s;
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_error err;
    double sp[3] = {0.5, 0.5, 1.5}, org[3] = {1, 2, 3}, me = 0, mf = 0;
    size_t i, j, k;
    if (!v) return;
    wvol_volume_set_geometry(v, sp, org, NULL);
    s = make_store(v, "haar", 2, 1.0, 1, NULL, NULL);
    if (!s) return;
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&cam, "+z", &g, 16, 16, NULL);
    wvol_image_create(&a, 16, 16, NULL);
    wvol_image_create(&b, 16, 16, NULL);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    CHECK(wvol_render_spline(a, s, &cam, NULL, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_render_xray_axis(b, s, &cam, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    for (j = 0; j < 16; j++)
        for (i = 0; i < 16; i++) {
            double sum = 0;
            size_t px = 4 * (i + 16 * (15 - j));
            for (k = 0; k < 16; k++) sum += v->data[i + 16 * (j + 16 * k)];
            sum *= 1.5;
            me = fmax(me, fabs(a->rgba[px] - sum) / sum);
            mf = fmax(mf, fabs(b->rgba[px] - sum) / sum);
        }
    CHECK(me < 1e-5, "Haar spline X-ray vs voxel sum: max relative error %g", me);
    CHECK(mf < 1e-5, "Haar axis fast path vs voxel sum: max relative error %g", mf);
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

/* db2: the spline-projected X-ray along each axis equals the 2D fast path. */
static void db2_xray_along_axis_equals_the_2d_fast_path(void)
{
    wvol_volume *v = gaussian(16);
    wvol_store *s[2];
    wvol_geometry g;
    const char *views[3] = {"+z", "-x", "+y"};
    double keeps[2] = {1.0, 0.1};
    int vi, ki;
    if (!v) return;
    wvol_geometry_of_volume(&g, v);
    for (ki = 0; ki < 2; ki++) s[ki] = make_store(v, "db2", 2, keeps[ki], 4, NULL, NULL);
    for (ki = 0; ki < 2; ki++)
        for (vi = 0; vi < 3; vi++) {
            wvol_camera cam;
            wvol_image *a = NULL, *b = NULL;
            wvol_render_params p;
            wvol_error err;
            wvol_render_stats sa, sb;
            double rel;
            if (!s[ki]) continue;
            wvol_camera_parse(&cam, views[vi], &g, 21, 19, NULL); /* pixel centres off the voxel grid */
            wvol_image_create(&a, 21, 19, NULL);
            wvol_image_create(&b, 21, 19, NULL);
            wvol_render_params_default(&p);
            p.mode = WVOL_RENDER_MODE_XRAY;
            CHECK(wvol_render_spline(a, s[ki], &cam, NULL, &p, &sa, &err) == WVOL_OK, "%s", err.message);
            CHECK(wvol_render_xray_axis(b, s[ki], &cam, &p, &sb, &err) == WVOL_OK, "%s", err.message);
            rel = wvol_image_rmse(a, b, 0, 1);
            CHECK(rel < 1e-5, "db2 %s keep %g: spline vs 2D fast path relative RMSE %g", views[vi], keeps[ki], rel);
            /* the same rays cross the box (the default view frames it with a margin, so some miss) */
            CHECK(sb.rays_hit == sa.rays_hit && sb.rays_hit > 0 && sb.rays_hit < sb.rays,
                  "db2 %s: rays hitting the box, axis %zu vs spline %zu of %zu", views[vi], sb.rays_hit,
                  sa.rays_hit, sb.rays);
            wvol_image_destroy(a);
            wvol_image_destroy(b);
        }
    {
        wvol_camera cam;
        wvol_image *a = NULL;
        wvol_error err;
        wvol_render_params p;
        wvol_render_params_default(&p);
        p.mode = WVOL_RENDER_MODE_XRAY;
        wvol_camera_parse(&cam, "dir=1,1,0", &g, 8, 8, NULL);
        wvol_image_create(&a, 8, 8, NULL);
        CHECK(s[0] && wvol_render_xray_axis(a, s[0], &cam, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED &&
                  strstr(err.message, "along x, y or z"),
              "oblique view refused by the fast path: %s", err.message);
        wvol_image_destroy(a);
    }
    for (ki = 0; ki < 2; ki++) wvol_store_destroy(s[ki]);
    wvol_volume_destroy(v);
}

/* Spline-projected X-ray and absorption against the converged f^ reference (100%). */
static void spline_matches_the_converged_reference_of_the_model(void)
{
    wvol_volume *v = gaussian(16);
    wvol_coeffs *c = NULL;
    wvol_store *s;
    wvol_basis *b = NULL;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    int m;
    if (!v) return;
    s = make_store(v, "db2", 2, 1.0, 4, &c, NULL);
    if (!s || !c) return;
    CHECK(wvol_basis_create(&b, c->filter, 4, NULL) == WVOL_OK, "basis");
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&cam, "persp dir=1,0.6,0.3 zoom=1.3", &g, 16, 16, NULL);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    for (m = 0; m < 3; m++) {
        wvol_image *a = NULL, *r = NULL;
        wvol_render_params p;
        wvol_error err;
        double rel;
        wvol_image_create(&a, 16, 16, NULL);
        wvol_image_create(&r, 16, 16, NULL);
        wvol_render_params_default(&p);
        p.mode = m ? WVOL_RENDER_MODE_ABSORPTION : WVOL_RENDER_MODE_XRAY;
        p.shading = m == 2; /* the analytic gradient (eq 47) against wvol_fhat_eval's */
        p.spline.gauss_nodes = 8;
        p.termination = 0;
        CHECK(wvol_render_spline(a, s, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
        p.step = 0.02;
        CHECK(wvol_render_reference_fhat(r, c, b, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
        rel = wvol_image_rmse(a, r, -1, 1);
        printf("spline vs converged f^ reference, %s: relative RMSE %.3g\n",
               m == 2 ? "absorption, shaded" : m ? "absorption" : "xray", rel);
        CHECK(rel < 1e-3, "mode %d: relative RMSE %g", m, rel);
        CHECK(image_finite(a), "finite");
        wvol_image_destroy(a);
        wvol_image_destroy(r);
    }
    wvol_basis_destroy(b);
    wvol_coeffs_destroy(c);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

/* Image error against the 100% image grows as the kept fraction drops, with the volume error. */
static void error_grows_as_fewer_coefficients_are_kept(void)
{
    wvol_volume *v = gaussian(32);
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *full = NULL;
    wvol_tf tf;
    double keeps[4] = {1.0, 0.2, 0.05, 0.01}, prev_img = -1, prev_vol = -1;
    int ki, m;
    if (!v) return;
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&cam, "ortho dir=1,0.5,0.25", &g, 24, 24, NULL);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    for (m = 0; m < 2; m++) {
        prev_img = prev_vol = -1;
        for (ki = 0; ki < 4; ki++) {
            double pred = 0, e;
            wvol_store *s = make_store(v, "db2", 3, keeps[ki], 3, NULL, &pred);
            wvol_image *img = NULL;
            wvol_render_params p;
            wvol_error err;
            if (!s) continue;
            wvol_image_create(&img, 24, 24, NULL);
            wvol_render_params_default(&p);
            p.mode = m ? WVOL_RENDER_MODE_ABSORPTION : WVOL_RENDER_MODE_XRAY;
            CHECK(wvol_render_spline(img, s, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
            if (ki == 0) {
                full = img;
            } else {
                e = wvol_image_rmse(img, full, -1, 1);
                printf("mode %d keep %5.2f%%: image error %.3g, predicted volume RMSE %.3g\n", m, 100 * keeps[ki], e,
                       pred);
                CHECK(e > prev_img && pred > prev_vol, "monotone: image %g after %g, volume %g after %g", e, prev_img,
                      pred, prev_vol);
                prev_img = e;
                prev_vol = pred;
                wvol_image_destroy(img);
            }
            wvol_store_destroy(s);
        }
        wvol_image_destroy(full);
        full = NULL;
    }
    wvol_volume_destroy(v);
}

static void spline_degenerate_rays_give_no_nan(void)
{
    wvol_volume *v = gaussian(8), *e = NULL;
    wvol_store *s, *se;
    wvol_geometry g;
    wvol_tf tf, hot;
    const char *specs[] = {"+z",
                           "dir=1,1,1",
                           "ortho eye=-0.5,-0.5,40 center=-0.5,-0.5,0 up=0,1,0 height=1",
                           "ortho eye=-0.5,3,40 center=-0.5,3,0 up=0,1,0 height=2",
                           "persp eye=3.5,3.5,3.5 center=0,0,0 fov=120",
                           "persp eye=100,100,100 center=200,200,200 fov=10"};
    int si, m, t;
    if (!v) return;
    wvol_volume_create(&e, 8, 8, 8, NULL);
    s = make_store(v, "db2", 1, 1.0, 2, NULL, NULL);
    se = make_store(e, "db2", 1, 1.0, 2, NULL, NULL);
    wvol_geometry_of_volume(&g, v);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    wvol_tf_parse(&hot, "0 1 1 1 1e30\n1 1 1 1 1e300\n", "hot", NULL);
    for (si = 0; si < (int)(sizeof specs / sizeof *specs); si++)
        for (m = 0; m < 3; m++)
            for (t = 0; t < 2; t++) {
                wvol_camera cam;
                wvol_image *img = NULL;
                wvol_render_params p;
                wvol_error err;
                wvol_camera_parse(&cam, specs[si], &g, 12, 12, NULL);
                wvol_image_create(&img, 12, 12, NULL);
                wvol_render_params_default(&p);
                p.mode = (wvol_render_mode)m;
                p.shading = t;
                p.termination = t ? 0 : 1e-6;
                CHECK(wvol_render_spline(img, s, &cam, t ? &hot : &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
                CHECK(image_finite(img), "finite: camera '%s' mode %d tf %d", specs[si], m, t);
                CHECK(wvol_render_spline(img, se, &cam, t ? &hot : &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
                CHECK(image_finite(img), "finite for an empty volume: camera '%s' mode %d", specs[si], m);
                wvol_image_destroy(img);
            }
    wvol_store_destroy(s);
    wvol_store_destroy(se);
    wvol_volume_destroy(v);
    wvol_volume_destroy(e);
}

int main(void)
{
    haar_xray_along_axis_is_the_voxel_sum();
    db2_xray_along_axis_equals_the_2d_fast_path();
    spline_matches_the_converged_reference_of_the_model();
    error_grows_as_fewer_coefficients_are_kept();
    spline_degenerate_rays_give_no_nan();
    return check_summary("test_render_spline");
}
