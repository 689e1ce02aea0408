/* SPDX-License-Identifier: MIT
 * Shared render plumbing: parameter defaults, argument checks, shading, image error. */
#include "render_internal.h"

#include <math.h>
#include <string.h>
#include <stdlib.h>

void wvol_render_params_default(wvol_render_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->mode = WVOL_RENDER_MODE_ABSORPTION;
    p->method = WVOL_RENDER_METHOD_AUTO;
    p->step = 0.5;
    p->termination = 1e-6;
    p->shading = 0;
    p->ambient = 0.3;
    p->threads = 0;
    p->tile = 0;
    p->reference.brick = 8;
    p->bricks.brick = WVOL__BRICKS_BRICK_DEFAULT;
    p->bricks.skip_inside = 1;
    p->spline.gauss_nodes = 5;
    p->colors = NULL;
    p->colors_count = 0;
    p->skip_tolerance = 0.0;
}

void wvol__params(wvol_render_params *out, const wvol_render_params *in)
{
    if (in) *out = *in;
    else wvol_render_params_default(out);
}

wvol_status wvol__render_step_check(double step, const char *what, wvol_error *err)
{
    /* from 1e-4 voxels on: a ray's sample count (at most the grid's diagonal over the step)
     * stays within an int, and finer steps change no image by more than their rounding */
    WVOL_RETURN_IF(!(step >= 1e-4) || !isfinite(step), err, WVOL_ERR_ARG,
                   "%s: step %g voxels (must be a finite number >= 1e-4)", what, step);
    return WVOL_OK;
}

wvol_status wvol__render_check(const wvol_image *img, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *p, wvol_error *err)
{
    WVOL_RETURN_IF(!img || !img->rgba, err, WVOL_ERR_ARG, "render: no output image");
    WVOL_FORWARD(wvol_camera_check(cam, err));
    WVOL_RETURN_IF(img->width != cam->width || img->height != cam->height, err, WVOL_ERR_ARG,
                   "render: image is %dx%d but the camera is %dx%d", img->width, img->height, cam->width, cam->height);
    WVOL_RETURN_IF(p->mode != WVOL_RENDER_MODE_XRAY && p->mode != WVOL_RENDER_MODE_ABSORPTION && p->mode != WVOL_RENDER_MODE_ABSORPTION_LINEAR,
                   err, WVOL_ERR_ARG, "render: unknown mode %d", (int)p->mode);
    if (p->mode != WVOL_RENDER_MODE_XRAY) {
        WVOL_RETURN_IF(!tf, err, WVOL_ERR_ARG, "render: absorption modes need a transfer function");
        WVOL_FORWARD(wvol_tf_check(tf, err));
    }
    WVOL_FORWARD(wvol__render_step_check(p->step, "render", err));
    WVOL_RETURN_IF(!(p->termination >= 0 && p->termination < 1), err, WVOL_ERR_ARG,
                   "render: termination threshold %g (must be in [0, 1))", p->termination);
    WVOL_RETURN_IF(!(p->ambient >= 0 && p->ambient <= 1), err, WVOL_ERR_ARG, "render: ambient %g (must be in [0, 1])",
                   p->ambient);
    WVOL_RETURN_IF(p->shading != 0 && p->shading != 1, err, WVOL_ERR_ARG, "render: shading %d (0 or 1)", p->shading);
    WVOL_RETURN_IF(p->tile < 0 || p->tile > 4096, err, WVOL_ERR_ARG, "render: tile %d (0 for the default, or 1..4096)",
                   p->tile);
    WVOL_RETURN_IF(p->reference.brick < 0 || p->reference.brick > 4096, err, WVOL_ERR_ARG,
                   "render: reference brick %d (0..4096)", p->reference.brick);
    WVOL_RETURN_IF(p->bricks.brick == 1 || p->bricks.brick < 0 || p->bricks.brick > 4096, err, WVOL_ERR_ARG,
                   "render: brick %d (bricks: 2..4096, or 0 for the default)", p->bricks.brick);
    WVOL_RETURN_IF(p->bricks.skip_inside != 0 && p->bricks.skip_inside != 1, err, WVOL_ERR_ARG,
                   "render: bricks.skip_inside %d (0 or 1)", p->bricks.skip_inside);
    WVOL_FORWARD(wvol__threads_check(p->threads, "render", err));
    WVOL_RETURN_IF(!(p->skip_tolerance >= 0) || !isfinite(p->skip_tolerance), err, WVOL_ERR_ARG,
                   "render: skip tolerance %g (must be finite and >= 0)", p->skip_tolerance);
    WVOL_RETURN_IF(p->preintegrate != 0 && p->preintegrate != 1, err, WVOL_ERR_ARG,
                   "render: preintegrate %d (0 or 1)", p->preintegrate);
    WVOL_RETURN_IF(p->preintegrate && p->mode != WVOL_RENDER_MODE_ABSORPTION, err, WVOL_ERR_ARG,
                   "render: pre-integration needs mode absorption (X-ray is linear in the value already; "
                   "absorption-linear is the paper's per-step linearisation)");
    WVOL_RETURN_IF(p->preintegrate && p->colors, err, WVOL_ERR_UNSUPPORTED,
                   "render: pre-integration takes its colour from the transfer function, not a colour volume");
    WVOL_RETURN_IF(p->gradient_levels < 0 || p->gradient_levels > 32, err, WVOL_ERR_ARG,
                   "render: gradient_levels %d (0: the samples' gradient; 1..the store's levels)", p->gradient_levels);
    WVOL_RETURN_IF(p->spline.gauss_nodes < 1 || p->spline.gauss_nodes > 10, err, WVOL_ERR_ARG,
                   "render: gauss_nodes %d (1..10)", p->spline.gauss_nodes);
    return WVOL_OK;
}

void wvol__stats_fill(wvol_render_stats *stats, const wvol_image *img, double t_start, double c_start,
                      const wvol__counts *c)
{
    if (!stats) return;
    memset(stats, 0, sizeof *stats);
    stats->seconds = wvol__now() - t_start;
    stats->cpu_seconds = wvol__cpu_now() - c_start;
    stats->rays = (size_t)img->width * (size_t)img->height;
    stats->rays_hit = c->rays_hit;
    stats->samples = c->samples;
    stats->pieces = c->pieces;
    stats->functions = c->functions;
    stats->skipped = c->skipped;
    stats->skipped_tolerance = c->skipped_tolerance;
    stats->skip_bound = c->skip_bound;
    stats->terminated = c->terminated;
    stats->clamped = c->clamped;
    stats->bytes = c->bytes;
}

wvol_status wvol__image_check_range(const wvol_image *img, wvol_error *err)
{
    size_t i, n = (size_t)img->width * (size_t)img->height * 4;
    for (i = 0; i < n && isfinite(img->rgba[i]); i++) {}
    if (i == n) return WVOL_OK;
    return wvol_error_set(err, WVOL_ERR_NONFINITE,
                          "render: pixel (%zu, %zu) is %s: the result leaves float32's range (|x| <= 3.4e38): "
                          "an X-ray integral beyond it, or values near +-3.4e38 whose differences overflow; "
                          "scale the volume down",
                          (i / 4) % (size_t)img->width, (i / 4) / (size_t)img->width,
                          isnan(img->rgba[i]) ? "NaN" : "Inf");
}

wvol_status wvol__check_skip(const wvol_render_params *p, int supported, wvol_error *err)
{
    WVOL_RETURN_IF(p->skip_tolerance > 0 && !supported, err, WVOL_ERR_UNSUPPORTED,
                   "render: a skip tolerance needs a brick grid to skip by (methods reference with brick > 0, "
                   "or bricks)");
    return WVOL_OK;
}

wvol_status wvol__check_colors(const wvol_render_params *p, const size_t n[3], int supported, wvol_error *err)
{
    size_t want, i;
    if (!p->colors) return WVOL_OK;
    WVOL_RETURN_IF(!supported, err, WVOL_ERR_UNSUPPORTED,
                   "render: a colour volume needs method reference or reference-fhat (this method has no voxels to "
                   "look colours up in)");
    WVOL_RETURN_IF(p->mode == WVOL_RENDER_MODE_XRAY, err, WVOL_ERR_ARG,
                   "render: a colour volume needs an absorption mode (X-ray has no colour)");
    want = n[0] * n[1];
    WVOL_RETURN_IF(n[0] && want / n[0] != n[1], err, WVOL_ERR_ARG, "render: volume too large for a colour volume");
    WVOL_RETURN_IF(n[2] && (want * n[2]) / n[2] != want, err, WVOL_ERR_ARG, "render: volume too large for a colour volume");
    want *= n[2];
    WVOL_RETURN_IF(want > ((size_t)-1) / 3, err, WVOL_ERR_ARG, "render: volume too large for a colour volume");
    WVOL_RETURN_IF(p->colors_count != 3 * want, err, WVOL_ERR_ARG,
                   "render: colour volume has %zu floats, the %zux%zux%zu volume needs %zu (3 per voxel)", p->colors_count,
                   n[0], n[1], n[2], 3 * want);
    for (i = 0; i < p->colors_count; i++)
        WVOL_RETURN_IF(!(p->colors[i] >= 0) || !isfinite(p->colors[i]), err, WVOL_ERR_ARG,
                       "render: colour volume value %g at voxel %zu channel %zu (must be finite and >= 0)",
                       (double)p->colors[i], i / 3, i % 3);
    return WVOL_OK;
}

int wvol__tile_side(const wvol_render_params *p, int preferred)
{
    return p->tile > 0 ? p->tile : preferred > 0 ? preferred : 16;
}

int wvol__tiles(int width, int height, int tile)
{
    return ((width + tile - 1) / tile) * ((height + tile - 1) / tile);
}

int *wvol__tile_order(int width, int height, int tile)
{
    int tx = (width + tile - 1) / tile, ty = (height + tile - 1) / tile, side = 1, n = 0;
    int *order = malloc((size_t)tx * (size_t)ty * sizeof *order + sizeof *order);
    if (!order) return NULL;
    while (side < tx || side < ty) side *= 2;
    for (long code = 0; code < (long)side * side; code++) {
        int x = 0, y = 0;
        for (int b = 0; b < 16; b++) { /* de-interleave the bits */
            x |= (int)((code >> (2 * b)) & 1) << b;
            y |= (int)((code >> (2 * b + 1)) & 1) << b;
        }
        if (x < tx && y < ty) order[n++] = x + tx * y;
    }
    return order;
}

double wvol__shade(const double grad[3], const double dir[3], double ambient)
{
    double n = sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2]), d;
    if (!(n > 0)) return 1.0; /* no gradient: unshaded (any magnitude: the direction is what counts) */
    d = fabs(grad[0] * dir[0] + grad[1] * dir[1] + grad[2] * dir[2]) / n;
    return ambient + (1.0 - ambient) * d;
}

double wvol_image_rmse(const wvol_image *a, const wvol_image *b, int channel, int relative)
{
    size_t n, i, cnt = 0;
    double s = 0, mx = 0;
    int c;
    if (!a || !b || a->width != b->width || a->height != b->height) return NAN;
    n = (size_t)a->width * (size_t)a->height;
    for (i = 0; i < n; i++)
        for (c = 0; c < 4; c++) {
            double d;
            if (channel >= 0 && c != channel) continue;
            d = (double)a->rgba[4 * i + c] - (double)b->rgba[4 * i + c];
            s += d * d;
            cnt++;
            if (fabs(b->rgba[4 * i + c]) > mx) mx = fabs(b->rgba[4 * i + c]);
        }
    s = sqrt(s / (double)(cnt ? cnt : 1));
    return relative ? (mx > 0 ? s / mx : s) : s;
}
