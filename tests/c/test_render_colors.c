/* SPDX-License-Identifier: MIT */
/* The renderer's colour volume (wvol_render_params.colors): the segmentation's per-voxel colours
 * replace the transfer function's colour while kappa still comes from the TF (DESIGN.md
 * section 10, the paper's Fig. 7). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

/* A volume of constant value `val` and a colour volume painted by `paint`. */
static wvol_volume *constant_volume(size_t nx, size_t ny, size_t nz, float val)
{
    wvol_volume *v = NULL;
    size_t i, n = nx * ny * nz;
    if (wvol_volume_create(&v, nx, ny, nz, NULL) != WVOL_OK) return NULL;
    for (i = 0; i < n; i++) v->data[i] = val;
    return v;
}

/* White TF with kappa rising over [0, 1] (world units). */
static void white_tf(wvol_tf *tf)
{
    memset(tf, 0, sizeof *tf);
    tf->count = 2;
    tf->points[0] = (wvol_tf_point){0.0, {1, 1, 1}, 0.0};
    tf->points[1] = (wvol_tf_point){1.0, {1, 1, 1}, 0.2};
}

/* Renders v (white TF, colour volume rgb) through the camera `spec` into a new w x h image. */
static wvol_image *render_coloured(const wvol_volume *v, const float *rgb, const char *spec, int w, int h)
{
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_tf tf;
    wvol_error err;
    wvol_geometry_of_volume(&g, v);
    CHECK(wvol_camera_parse(&cam, spec, &g, w, h, &err) == WVOL_OK, "%s", err.message);
    if (wvol_image_create(&img, w, h, NULL) != WVOL_OK) return NULL;
    white_tf(&tf);
    wvol_render_params_default(&p);
    p.colors = rgb;
    p.colors_count = 3 * wvol_volume_count(v);
    CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    return img;
}

/* Emission is colour x kappa, so with one colour c everywhere the composited colour is
 * c (1 - T) = c A exactly in real arithmetic; accumulation is in double and the stored
 * channels are float, so each side carries at most one float rounding (< 1e-7 for values
 * <= 1): 1e-6 absolute. */
static void uniform_colour_scales_alpha(void)
{
    wvol_volume *v = constant_volume(12, 10, 9, 0.7f);
    float *rgb = malloc(3 * 12 * 10 * 9 * sizeof *rgb);
    const float c[3] = {0.2f, 0.5f, 0.9f};
    wvol_image *img;
    size_t i, n = 12 * 10 * 9;
    double worst = 0, amax = 0;
    if (!v || !rgb) return;
    for (i = 0; i < 3 * n; i++) rgb[i] = c[i % 3];
    img = render_coloured(v, rgb, "persp dir=1,0.6,0.3", 24, 20);
    if (!img) return;
    for (i = 0; i < (size_t)(24 * 20); i++) {
        int a;
        for (a = 0; a < 3; a++) worst = fmax(worst, fabs(img->rgba[4 * i + a] - c[a] * img->rgba[4 * i + 3]));
        amax = fmax(amax, img->rgba[4 * i + 3]);
    }
    CHECK(amax > 0.1, "the volume is visible (max alpha %g)", amax);
    CHECK(worst < 1e-6, "uniform colour: RGB = c * A (worst %g)", worst);
    wvol_image_destroy(img);
    wvol_volume_destroy(v);
    free(rgb);
}

/* Two classes side by side seen along z: each pixel (centred on a voxel column) takes its
 * own class's colour and nothing of the other's (nearest-voxel lookup, no blending). */
static void classes_keep_their_colours(void)
{
    const size_t nx = 16, ny = 8, nz = 6, n = nx * ny * nz;
    wvol_volume *v = constant_volume(nx, ny, nz, 1.0f);
    float *rgb = calloc(3 * n, sizeof *rgb);
    wvol_image *img;
    size_t i;
    int x, y, clean = 1;
    if (!v || !rgb) return;
    for (i = 0; i < n; i++) rgb[3 * i + (i % nx < nx / 2 ? 0 : 2)] = 1.0f; /* left red, right blue */
    img = render_coloured(v, rgb, "+z", (int)nx, (int)ny);
    if (!img) return;
    for (y = 0; y < (int)ny; y++)
        for (x = 0; x < (int)nx; x++) {
            const float *px = img->rgba + 4 * (x + (int)nx * y);
            int left = x < (int)nx / 2;
            float own = left ? px[0] : px[2], other = left ? px[2] : px[0];
            if (!(own > 0.1f && other == 0.0f && px[1] == 0.0f)) clean = 0;
        }
    CHECK(clean, "every pixel shows only its own class's colour");
    wvol_image_destroy(img);
    wvol_volume_destroy(v);
    free(rgb);
}

/* Wrong sizes, bad values, X-ray and the store methods are refused with a message. */
static void bad_colour_volumes_are_refused(void)
{
    wvol_volume *v = constant_volume(8, 8, 8, 0.5f);
    float *rgb = malloc(3 * 512 * sizeof *rgb);
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_tf tf;
    wvol_error err;
    wvol_store *st = NULL;
    size_t i;
    if (!v || !rgb) return;
    for (i = 0; i < 3 * 512; i++) rgb[i] = 0.5f;
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&cam, "+x", &g, 8, 8, NULL);
    wvol_image_create(&img, 8, 8, NULL);
    white_tf(&tf);
    wvol_render_params_default(&p);
    p.colors = rgb;
    p.colors_count = 3 * 511;
    CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "needs 1536"),
          "%s", err.message);
    p.colors_count = 3 * 512;
    rgb[700] = NAN;
    CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "voxel 233"),
          "%s", err.message);
    rgb[700] = -1.0f;
    CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG, "%s", err.message);
    rgb[700] = 0.5f;
    p.mode = WVOL_RENDER_MODE_XRAY;
    CHECK(wvol_render_reference(img, v, &cam, NULL, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "X-ray"),
          "%s", err.message);
    st = fixture_store(v, "haar", 2, 1.0, 0);
    CHECK(st != NULL, "haar store of the constant volume");
    CHECK(wvol_render_xray_axis(img, st, &cam, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED, "%s", err.message);
    p.mode = WVOL_RENDER_MODE_ABSORPTION;
    CHECK(wvol_render_spline(img, st, &cam, &tf, &p, NULL, &err) == WVOL_ERR_UNSUPPORTED &&
              strstr(err.message, "colour volume"),
          "%s", err.message);
    wvol_store_destroy(st);
    wvol_image_destroy(img);
    wvol_volume_destroy(v);
    free(rgb);
}

int main(void)
{
    uniform_colour_scales_alpha();
    classes_keep_their_colours();
    bad_colour_volumes_are_refused();
    return check_summary("test_render_colors");
}
