/* SPDX-License-Identifier: MIT
 * The stained-glass window of Lewis & Fournier 2002, §7.3 (Figs. 12-13): a built-in synthetic
 * window, PNG windows, and the window's outgoing radiance (image times a cos^4 lobe about a
 * 45-degree peak) as a coefficient tree. */
#include "transport_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/quadrature.h"
#include "wvol/image.h"

void wvol_transport_window_free(wvol_transport_window *w)
{
    if (!w) return;
    free(w->rgb);
    w->rgb = NULL;
    w->width = w->height = 0;
}

wvol_status wvol_transport_window_synthetic(wvol_transport_window *w, int size, wvol_error *err)
{
    static const float pal[6][3] = {{0.05f, 0.12f, 0.70f}, {0.75f, 0.05f, 0.06f}, {0.06f, 0.55f, 0.18f},
                                    {0.85f, 0.55f, 0.05f}, {0.45f, 0.10f, 0.60f}, {0.10f, 0.50f, 0.65f}};
    double lead;
    WVOL_RETURN_IF(!w, err, WVOL_ERR_ARG, "window: NULL output");
    WVOL_RETURN_IF(size < 8 || size > 4096, err, WVOL_ERR_ARG, "window: size %d outside 8..4096", size);
    w->rgb = malloc((size_t)size * size * 3 * sizeof *w->rgb);
    WVOL_RETURN_IF(!w->rgb, err, WVOL_ERR_NOMEM, "window: out of memory for %dx%d", size, size);
    w->width = w->height = size;
    lead = 0.012;
    for (int y = 0; y < size; y++)
        for (int x = 0; x < size; x++) {
            double u = (x + 0.5) / size, v = (y + 0.5) / size, du = u - 0.5, dv = v - 0.5;
            double r = sqrt(du * du + dv * dv), ang = atan2(dv, du);
            int pu = (int)(u * 4), pv = (int)(v * 4);
            const float *c = pal[(pu * 3 + pv * 5 + (pu ^ pv)) % 6];
            float *o = w->rgb + 3 * ((size_t)y * size + x);
            float gold[3] = {0.95f, 0.80f, 0.25f};
            int is_lead = fabs(u * 4 - floor(u * 4 + 0.5)) < lead * 4 || fabs(v * 4 - floor(v * 4 + 0.5)) < lead * 4;
            if (r < 0.30) { /* the rose: gold centre, petals alternating ruby and blue */
                int petal = (int)floor((ang + M_PI) / (2 * M_PI) * 8);
                is_lead = fabs(r - 0.30) < lead || fabs(r - 0.12) < lead ||
                          (r > 0.12 && fabs(fmod(ang + M_PI + 2 * M_PI, M_PI / 4)) < lead / r);
                c = r < 0.12 ? gold : pal[petal % 2 ? 1 : 0];
            }
            for (int k = 0; k < 3; k++) o[k] = is_lead ? 0.02f : c[k];
        }
    return WVOL_OK;
}

wvol_status wvol_transport_window_read_png(wvol_transport_window *w, const char *path, wvol_error *err)
{
    int width, height, colour;
    float *rgb = NULL;
    WVOL_RETURN_IF(!w || !path, err, WVOL_ERR_ARG, "window: NULL argument");
    w->rgb = NULL;
    w->width = w->height = 0;
    WVOL_FORWARD(wvol_png_read_rgb(&rgb, &width, &height, &colour, path, err));
    if (!colour) {
        free(rgb);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: greyscale PNG; the window must be an RGB image", path);
    }
    if (width > 8192 || height > 8192) {
        free(rgb);
        return wvol_error_set(err, WVOL_ERR_DIMS, "%s: %dx%d outside 1..8192 per side", path, width, height);
    }
    w->rgb = rgb;
    w->width = width;
    w->height = height;
    return WVOL_OK;
}

void wvol_transport_scene_default(wvol_transport_scene *s)
{
    static const wvol_transport_quad window = {{{0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}}}; /* normal -z */
    static const wvol_transport_quad floor = {{{-0.5, -1, 0}, {2.5, -1, 0}, {2.5, 2, 0}, {-0.5, 2, 0}}}; /* +z */
    if (!s) return;
    memset(s, 0, sizeof *s);
    s->window = window;
    s->floor = floor;
    s->peak[0] = M_SQRT1_2;
    s->peak[2] = -M_SQRT1_2;
    s->lobe_exponent = 4;
    s->tiles = 4;
    s->diffuse.kind = WVOL_TRANSPORT_BRDF_PHONG;
    s->glossy.kind = WVOL_TRANSPORT_BRDF_PHONG;
    for (int c = 0; c < 3; c++) {
        s->diffuse.kd[c] = 0.7f, s->diffuse.ks[c] = 0.1f;
        s->glossy.kd[c] = 0.15f, s->glossy.ks[c] = 0.6f;
    }
    s->diffuse.exponent = 4;
    s->glossy.exponent = 40;
}

/* the lobe's mean over each direction cell; outside the unit disc the lobe takes its value at
 * the nearest rim direction (never transported; keeps the cell means smooth) */
static void lobe_means(double *out, const wvol__tframe *f, const double peak[3], double e, int levels)
{
    enum { G = 8 };
    double x[G], w[G];
    int n = 1 << levels;
    wvol__gauss_legendre(G, x, w);
    for (int D = 0; D < n * n; D++) {
        double acc = 0;
        for (int a = 0; a < G * G; a++) {
            double mx = 2 * ((D % n + x[a % G]) / n) - 1, my = 2 * ((D / n + x[a / G]) / n) - 1;
            double r = sqrt(mx * mx + my * my), mz = 0, d[3], c;
            if (r > 1) mx /= r, my /= r;
            else mz = sqrt(1 - r * r);
            for (int k = 0; k < 3; k++) d[k] = mx * f->t[k] + my * f->b[k] + mz * f->n[k];
            c = wvol__dot3(d, peak);
            acc += w[a % G] * w[a / G] * (c > 0 ? pow(c, e) : 0);
        }
        out[D] = acc;
    }
}

wvol_status wvol_transport_scene_source(wvol_transport_tree **out, const wvol_transport_scene *s,
                                        const wvol_transport_window *w, int levels, wvol_error *err)
{
    enum { SS = 8 };
    wvol__tframe f;
    int n = 1 << levels;
    double *lobe, pl;
    float *img, *cells;
    wvol_status st;
    WVOL_RETURN_IF(!out || !s || !w, err, WVOL_ERR_ARG, "window scene: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(!w->rgb || w->width < 1 || w->height < 1, err, WVOL_ERR_ARG, "window scene: empty window image");
    WVOL_RETURN_IF(levels < 1 || levels > WVOL_TRANSPORT_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "window scene: levels %d outside 1..%d", levels, WVOL_TRANSPORT_MAX_LEVELS);
    WVOL_FORWARD(wvol_transport_quad_check(&s->window, err));
    pl = sqrt(wvol__dot3(s->peak, s->peak));
    WVOL_RETURN_IF(!(pl > 0) || !isfinite(pl), err, WVOL_ERR_ARG, "window scene: the peak direction must be non-zero");
    WVOL_RETURN_IF(!(s->lobe_exponent >= 0) || !isfinite(s->lobe_exponent), err, WVOL_ERR_ARG,
                   "window scene: lobe exponent %g must be finite and >= 0", s->lobe_exponent);
    for (size_t i = 0; i < (size_t)w->width * w->height * 3; i++)
        WVOL_RETURN_IF(!isfinite(w->rgb[i]) || w->rgb[i] < 0, err, WVOL_ERR_NONFINITE,
                       "window scene: pixel %zu channel %zu is %g (finite and >= 0 needed)", i / 3, i % 3, w->rgb[i]);
    wvol__tframe_init(&f, &s->window);
    lobe = malloc((size_t)n * n * sizeof *lobe);
    img = calloc((size_t)n * n * 3, sizeof *img);
    cells = malloc(3 * wvol_transport_cells_count(levels) * sizeof *cells);
    if (!lobe || !img || !cells) {
        free(lobe), free(img), free(cells);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "window scene: out of memory");
    }
    {
        double pk[3] = {s->peak[0] / pl, s->peak[1] / pl, s->peak[2] / pl};
        lobe_means(lobe, &f, pk, s->lobe_exponent, levels);
    }
    /* position cells: u along the image's x, v up its rows (row 0 at v = 1), SS^2 nearest samples */
    for (int P = 0; P < n * n; P++)
        for (int a = 0; a < SS * SS; a++) {
            double u = ((P % n) + (a % SS + 0.5) / SS) / n, v = ((P / n) + (a / SS + 0.5) / SS) / n;
            int x = (int)(u * w->width), y = (int)((1 - v) * w->height);
            if (x >= w->width) x = w->width - 1;
            if (y >= w->height) y = w->height - 1;
            for (int c = 0; c < 3; c++) img[3 * P + c] += w->rgb[3 * ((size_t)y * w->width + x) + c] / (SS * SS);
        }
    for (int D = 0; D < n * n; D++)
        for (int P = 0; P < n * n; P++)
            for (int c = 0; c < 3; c++) cells[3 * ((size_t)P + (size_t)n * n * D) + c] = (float)(img[3 * P + c] * lobe[D]);
    st = wvol_transport_tree_from_cells(out, cells, levels, s->source_threshold, err);
    free(lobe), free(img), free(cells);
    return st;
}
