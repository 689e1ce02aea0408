/* SPDX-License-Identifier: MIT
 * Pictures of a 4D radiance tree (Lewis & Fournier 2002, Figs. 14-16): the matrix of position
 * images, one per direction cell; the brightest one enlarged; and frames of a quad seen by a
 * perspective camera, each pixel sampling the reflected tree towards the eye ("4-D texture"). */
#include "transport_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/render.h"

static wvol_status tree_cells(float **cells, const wvol_transport_tree *t, wvol_error *err)
{
    size_t nc;
    wvol_status s;
    WVOL_RETURN_IF(!t, err, WVOL_ERR_ARG, "transport image: NULL tree");
    nc = wvol_transport_cells_count(t->levels);
    *cells = malloc(3 * nc * sizeof **cells);
    WVOL_RETURN_IF(!*cells, err, WVOL_ERR_NOMEM, "transport image: out of memory");
    s = wvol_transport_tree_to_cells(*cells, 3 * nc, t, err);
    if (s != WVOL_OK) {
        free(*cells);
        *cells = NULL;
    }
    return s;
}

/* draws direction cell D's position tile at (x0, y0): position (mu, mv) at column mu, row n-1-mv */
static void draw_tile(wvol_image *im, const float *cells, int n, int D, int x0, int y0, int px, double exposure)
{
    for (int P = 0; P < n * n; P++) {
        const float *c = cells + 3 * ((size_t)P + (size_t)n * n * D);
        int cx = x0 + (P % n) * px, cy = y0 + (n - 1 - P / n) * px;
        for (int y = cy; y < cy + px; y++)
            for (int x = cx; x < cx + px; x++) {
                float *o = im->rgba + 4 * ((size_t)y * im->width + x);
                for (int k = 0; k < 3; k++) o[k] = (float)(c[k] * exposure);
                o[3] = 1;
            }
    }
}

static wvol_status image_args(int px, double exposure, wvol_image **img, wvol_error *err)
{
    WVOL_RETURN_IF(!img, err, WVOL_ERR_ARG, "transport image: NULL output");
    *img = NULL;
    WVOL_RETURN_IF(px < 1 || px > 256, err, WVOL_ERR_ARG, "transport image: %d pixels per cell outside 1..256", px);
    WVOL_RETURN_IF(!(exposure > 0) || !isfinite(exposure), err, WVOL_ERR_ARG,
                   "transport image: exposure %g must be finite and > 0", exposure);
    return WVOL_OK;
}

wvol_status wvol_transport_grid_image(wvol_image **img, const wvol_transport_tree *t, int cell_px, double exposure,
                                      wvol_error *err)
{
    float *cells;
    int n, tile, side;
    WVOL_FORWARD(image_args(cell_px, exposure, img, err));
    WVOL_FORWARD(tree_cells(&cells, t, err));
    n = 1 << t->levels;
    tile = n * cell_px;
    side = n * tile + n - 1;
    if (side > 65536 || wvol_image_create(img, side, side, err) != WVOL_OK) {
        free(cells);
        return wvol_error_set(err, WVOL_ERR_DIMS, "transport image: %dx%d pixels is too large", side, side);
    }
    for (int D = 0; D < n * n; D++) draw_tile(*img, cells, n, D, (D % n) * (tile + 1), (D / n) * (tile + 1), cell_px, exposure);
    free(cells);
    return WVOL_OK;
}

wvol_status wvol_transport_detail_image(wvol_image **img, const wvol_transport_tree *t, int cell_px, double exposure,
                                        wvol_error *err)
{
    float *cells;
    int n, best = 0;
    double bsum = -1;
    wvol_status s;
    WVOL_FORWARD(image_args(cell_px, exposure, img, err));
    WVOL_FORWARD(tree_cells(&cells, t, err));
    n = 1 << t->levels;
    for (int D = 0; D < n * n; D++) {
        double sum = 0;
        for (int P = 0; P < n * n; P++)
            for (int k = 0; k < 3; k++) sum += cells[3 * ((size_t)P + (size_t)n * n * D) + k];
        if (sum > bsum) bsum = sum, best = D;
    }
    s = wvol_image_create(img, n * cell_px, n * cell_px, err);
    if (s == WVOL_OK) draw_tile(*img, cells, n, best, 0, 0, cell_px, exposure);
    free(cells);
    return s;
}

wvol_status wvol_transport_floor_image(wvol_image **img, const wvol_transport_tree *reflected,
                                       const wvol_transport_quad *floor, const double eye[3], const double center[3],
                                       double fov_y, int width, int height, double exposure, wvol_error *err)
{
    wvol_camera cam;
    wvol__tframe f;
    wvol_status s;
    double view[3];
    WVOL_RETURN_IF(!img || !reflected || !eye || !center, err, WVOL_ERR_ARG, "floor image: NULL argument");
    *img = NULL;
    WVOL_FORWARD(wvol_transport_quad_check(floor, err));
    WVOL_RETURN_IF(!(exposure > 0) || !isfinite(exposure), err, WVOL_ERR_ARG,
                   "floor image: exposure %g must be finite and > 0", exposure);
    memset(&cam, 0, sizeof cam);
    cam.projection = WVOL_PROJECTION_PERSPECTIVE;
    cam.width = width;
    cam.height = height;
    cam.fov_y = fov_y;
    for (int c = 0; c < 3; c++) cam.eye[c] = eye[c], cam.center[c] = center[c], view[c] = center[c] - eye[c];
    cam.up[2] = 1;
    if (fabs(view[2]) > 0.999 * sqrt(wvol__dot3(view, view))) cam.up[2] = 0, cam.up[1] = 1;
    WVOL_FORWARD(wvol_camera_check(&cam, err));
    wvol__tframe_init(&f, floor);
    WVOL_FORWARD(wvol_image_create(img, width, height, err));
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            double o[3], d[3], t, p[3], uv[2], w[3], kl[2];
            float *px = (*img)->rgba + 4 * ((size_t)y * width + x), rgb[3] = {0.02f, 0.02f, 0.025f};
            wvol_camera_ray(&cam, x + 0.5, y + 0.5, o, d);
            px[3] = 1;
            t = (wvol__dot3(f.o, f.n) - wvol__dot3(o, f.n)) / wvol__dot3(d, f.n);
            if (wvol__dot3(d, f.n) < 0 && t > 0) {
                for (int c = 0; c < 3; c++) p[c] = o[c] + t * d[c], w[c] = -d[c];
                wvol__tframe_param(&f, p, uv);
                if (uv[0] >= 0 && uv[0] <= 1 && uv[1] >= 0 && uv[1] <= 1) {
                    double q[4];
                    wvol__tframe_kl(&f, w, kl);
                    q[0] = uv[0], q[1] = uv[1], q[2] = fmin(fmax(kl[0], 0), 1), q[3] = fmin(fmax(kl[1], 0), 1);
                    s = wvol_transport_tree_eval(reflected, q, rgb, err);
                    if (s != WVOL_OK) {
                        wvol_image_destroy(*img);
                        *img = NULL;
                        return s;
                    }
                    for (int c = 0; c < 3; c++) rgb[c] = (float)(rgb[c] * exposure);
                }
            }
            for (int c = 0; c < 3; c++) px[c] = rgb[c];
        }
    return WVOL_OK;
}
