/* SPDX-License-Identifier: MIT
 * Tests of pre-integrated transfer functions (libwvol/src/render/preint.c): one segment's
 * integral against the converged per-step integral of the same linear scalar, and renders
 * with wvol_render_params.preintegrate against the converged reference. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "render/reference_internal.h"
#include "wvol/render.h"

/* A TF in world units with knots at 0.2, 0.3, 0.5, 0.8: transparent below 0.2, a steep ramp,
 * a plateau, a fall, a colour change at every knot. */
static void test_tf(wvol_tf *tf, double kscale)
{
    static const double pts[5][5] = {
        {0.2, 0.1, 0.2, 0.9, 0}, {0.3, 1.0, 0.5, 0.2, 4}, {0.5, 0.3, 1.0, 0.3, 4}, {0.8, 0.9, 0.9, 0.9, 1}, {0.9, 1, 0, 0, 0}};
    memset(tf, 0, sizeof *tf);
    tf->count = 5;
    for (int i = 0; i < 5; i++) {
        tf->points[i].value = pts[i][0];
        for (int c = 0; c < 3; c++) tf->points[i].rgb[c] = pts[i][1 + c];
        tf->points[i].opacity = pts[i][4] * kscale;
    }
}

/* The converged per-step integral of the segment: the scalar linear from a to b over len,
 * front-to-back compositing at the midpoints of n steps (alpha = 1 - exp(-kappa h), emission
 * colour times alpha), each step at most 1e-4 of optical depth long (2e5 to 4e6 steps), and
 * stopped once T < 1e-18 (what is left cannot show at the tolerance). Its error is the midpoint
 * rule's, O(h^2) relative on smooth parts and O(h) at the knots' kinks: below 1e-8 here. */
static void brute(const wvol_tf *tf, double a, double b, double len, double *T, double acc[3])
{
    double kmax = 0;
    long n;
    for (int i = 0; i < tf->count; i++) kmax = fmax(kmax, tf->points[i].opacity);
    n = (long)fmin(4e6, fmax(2e5, ceil(len * kmax / 1e-4)));
    double h = len / (double)n;
    for (long i = 0; i < n && *T > 1e-18; i++) {
        double u = ((double)i + 0.5) / (double)n, v = a + u * (b - a), rgb[3], k;
        wvol_tf_eval(tf, v, rgb, &k);
        double al = -expm1(-k * h);
        for (int c = 0; c < 3; c++) acc[c] += *T * al * rgb[c];
        *T *= 1 - al;
    }
}

static void one_segment(const wvol_tf *tf, double a, double b, double len, double tol, const char *what)
{
    tf_fast f;
    ray_acc r;
    double T = 1, acc[3] = {0, 0, 0};
    wvol__tf_fast_init(&f, tf);
    memset(&r, 0, sizeof r);
    r.T = 1;
    wvol__preint_segment(&f, a, b, len, 1.0, &r);
    brute(tf, a, b, len, &T, acc);
    CHECK(isfinite(r.T) && isfinite(r.acc[0]) && isfinite(r.acc[1]) && isfinite(r.acc[2]), "%s: not finite", what);
    CHECK(r.T >= 0 && r.T <= 1, "%s: T %g", what, r.T);
    CHECK_NEAR(r.T, T, tol, what);
    for (int c = 0; c < 3; c++) CHECK_NEAR(r.acc[c], acc[c], tol, what);
}

/* Very large kappa: the ray is opaque within a length ~1 / kappa of the start, where the
 * value has moved by (b - a) / (kappa len), so the emission is the colour at a (to that
 * relative amount: < 1e-6 here) and T is 0. The per-step brute force cannot resolve this. */
static void opaque_at_once(const wvol_tf *tf, double a, double b, double len, const char *what)
{
    tf_fast f;
    ray_acc r;
    double rgb[3];
    wvol__tf_fast_init(&f, tf);
    memset(&r, 0, sizeof r);
    r.T = 1;
    wvol__preint_segment(&f, a, b, len, 1.0, &r);
    wvol_tf_eval(tf, a, rgb, NULL);
    CHECK(r.T < 1e-300, "%s: T %g", what, r.T);
    for (int c = 0; c < 3; c++) CHECK_NEAR(r.acc[c], rgb[c], 1e-6, what);
}

/* Pre-integration equals the converged per-step integral for a linear scalar: within one TF
 * segment, across several knots rising and falling, from below the first point to above the
 * last, zero-length (in value and in length), very long (opaque), kappa 0 everywhere and very
 * large kappa. The tolerance 2e-7 (absolute, on T and colours <= 1) covers the brute force's
 * midpoint error (< 1e-8) and the mean transmittance's quadrature (~1e-9 relative); a piece
 * taken with the wrong segment's formula or a knot missed is off by 1e-3 or more. */
static void segment_equals_converged_integral(void)
{
    wvol_tf tf;
    const double tol = 2e-7;
    test_tf(&tf, 1.0);
    one_segment(&tf, 0.32, 0.45, 0.3, tol, "inside one segment");
    one_segment(&tf, 0.25, 0.27, 0.8, tol, "inside the steep ramp");
    one_segment(&tf, 0.1, 0.85, 0.5, tol, "rising across every knot");
    one_segment(&tf, 0.95, 0.05, 0.5, tol, "falling across every knot");
    one_segment(&tf, 0.28, 0.55, 0.2, tol, "two knots");
    one_segment(&tf, 0.3, 0.5, 0.4, tol, "knot to knot");
    one_segment(&tf, 0.4, 0.4, 0.7, tol, "constant value");
    one_segment(&tf, 0.4, 0.9, 0.0, 0.0, "zero length");
    one_segment(&tf, 0.1, 0.15, 0.5, 0.0, "transparent (below the first point)");
    one_segment(&tf, 0.15, 0.6, 40.0, tol, "very long");
    one_segment(&tf, 0.6, 0.15, 1e4, tol, "very long, falling");
    test_tf(&tf, 0.0);
    one_segment(&tf, 0.1, 0.9, 3.0, 0.0, "kappa 0");
    test_tf(&tf, 1e7);
    opaque_at_once(&tf, 0.25, 0.6, 1.0, "kappa 1e7");
    opaque_at_once(&tf, 0.6, 0.25, 1.0, "kappa 1e7, falling");
    test_tf(&tf, 1e300);
    opaque_at_once(&tf, 0.25, 0.9, 1e300, "kappa 1e300, length 1e300");
    {
        /* composing: two segments end to end equal the brute force over both */
        tf_fast f;
        ray_acc r;
        double T = 1, acc[3] = {0, 0, 0};
        test_tf(&tf, 1.0);
        wvol__tf_fast_init(&f, &tf);
        memset(&r, 0, sizeof r);
        r.T = 1;
        wvol__preint_segment(&f, 0.22, 0.7, 0.6, 1.0, &r);
        wvol__preint_segment(&f, 0.7, 0.35, 0.6, 1.0, &r);
        brute(&tf, 0.22, 0.7, 0.6, &T, acc);
        brute(&tf, 0.7, 0.35, 0.6, &T, acc);
        CHECK_NEAR(r.T, T, tol, "two segments");
        for (int c = 0; c < 3; c++) CHECK_NEAR(r.acc[c], acc[c], tol, "two segments");
        /* NaN in, no NaN out */
        wvol__preint_segment(&f, NAN, 0.4, 0.3, 1.0, &r);
        wvol__preint_segment(&f, 0.4, NAN, 0.3, 1.0, &r);
        wvol__preint_segment(&f, NAN, NAN, 0.3, 1.0, &r);
        CHECK(isfinite(r.T) && isfinite(r.acc[0]) && isfinite(r.acc[1]) && isfinite(r.acc[2]), "NaN value gave %g",
              r.T);
    }
}

/* A smooth volume (a Gaussian) and a steep TF: the TF, not the data, limits the step. The
 * pre-integrated image at step 2 must be at least as close to the converged reference as the
 * classic one at step 0.5 (measured: 6.0e-3 against 1.0e-2 here), and converge to it at a
 * small step. */
static double gauss_voxel(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double x = (i - (v->nx - 1) / 2.0) / (v->nx / 2.0), y = (j - (v->ny - 1) / 2.0) / (v->ny / 2.0),
           z = (k - (v->nz - 1) / 2.0) / (v->nz / 2.0);
    (void)ctx;
    return exp(-(x * x + 1.3 * y * y + 0.8 * z * z) / 0.3);
}

static double render_err(const wvol_volume *v, const wvol_camera *cam, const wvol_tf *tf, const wvol_image *ref,
                         double step, int preint, wvol_image *img)
{
    wvol_render_params p;
    wvol_error err;
    wvol_render_params_default(&p);
    p.step = step;
    p.preintegrate = preint;
    p.threads = 2;
    CHECK(wvol_render_reference(img, v, cam, tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    return wvol_image_rmse(img, ref, -1, 1);
}

static void preintegrated_render_beats_the_step(void)
{
    wvol_volume *v = fixture_volume(40, 36, 30, gauss_voxel, NULL);
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_error err;
    wvol_image *ref = NULL, *img = NULL;
    wvol_render_params p;
    const int W = 48, H = 40;
    double e_classic, e_pre, e_fine;
    if (!v) return;
    wvol_geometry_of_volume(&g, v);
    CHECK(wvol_camera_parse(&cam, "persp dir=1,0.7,0.4", &g, W, H, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_parse(&tf, "units diagonal\n0.5 1 0.5 0.2 0\n0.52 1 1 1 200\n0.6 0.3 0.5 1 300\n", "tf", &err) ==
              WVOL_OK,
          "%s", err.message);
    CHECK(wvol_image_create(&ref, W, H, &err) == WVOL_OK && wvol_image_create(&img, W, H, &err) == WVOL_OK, "%s",
          err.message);
    if (!ref || !img) return;
    wvol_render_params_default(&p);
    p.step = 0.01;
    p.threads = 2;
    CHECK(wvol_render_reference(ref, v, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    e_classic = render_err(v, &cam, &tf, ref, 0.5, 0, img);
    e_pre = render_err(v, &cam, &tf, ref, 2.0, 1, img);
    e_fine = render_err(v, &cam, &tf, ref, 0.05, 1, img);
    CHECK(e_pre <= e_classic, "pre-integrated at step 2: %.3g, classic at 0.5: %.3g", e_pre, e_classic);
    CHECK(e_fine < 2e-4, "pre-integrated at step 0.05: %.3g from the converged reference", e_fine);
    printf("steep TF on a Gaussian: classic step 0.5 %.3g, pre-integrated step 2 %.3g, step 0.05 %.3g\n", e_classic,
           e_pre, e_fine);
    {
        /* refused outside absorption mode, with a colour volume, by the spline method */
        p.preintegrate = 1;
        p.mode = WVOL_RENDER_MODE_XRAY;
        CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "needs mode absorption"), "X-ray took preintegrate: %s", err.message);
        p.mode = WVOL_RENDER_MODE_ABSORPTION_LINEAR;
        CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "needs mode absorption"), "absorption-linear took preintegrate: %s", err.message);
        p.mode = WVOL_RENDER_MODE_ABSORPTION;
        p.preintegrate = 2;
        CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "preintegrate 2 (0 or 1)"), "preintegrate 2 accepted: %s", err.message);
    }
    wvol_image_destroy(ref);
    wvol_image_destroy(img);
    wvol_volume_destroy(v);
}

int main(void)
{
    segment_equals_converged_integral();
    preintegrated_render_beats_the_step();
    return check_summary("test_render_preint");
}
