/* SPDX-License-Identifier: MIT
 * The tracer's tensor ranges of the finest cells (iso/trace_tensor.c): every class they give
 * holds for f^ sampled densely in the cell, and images traced with them equal the images traced
 * without them (the interval ranges alone): the same hits, depths within the root tolerance. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "check.h"
#include "fixtures.h"
#include "iso/iso_internal.h"
#include "wvol/iso.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol_synth.h"

static uint64_t rs = 0x9E3779B97F4A7C15ull;
#define rnd() fixture_urand(&rs)

/* On random 2-voxel cells (on the tracer's grid, and anywhere) the interval range cannot
 * decide, against iso levels just outside the sampled range of f^ (where a tighter range
 * decides) and inside it (where nothing may): a class 1 (0) needs every sample above (below)
 * iso. Returns how many classes the tensor range gave. */
static int classes_hold(const wvol_store *s, int cells, int q, const char *what)
{
    wvol__iso_boxk k;
    wvol__tensor_ws *w = calloc(1, sizeof *w);
    wvol_store_hits hl;
    wvol_store_info info;
    int b, decided = 0, tried = 0, wrong = 0;
    memset(&hl, 0, sizeof hl);
    wvol__iso_boxk_init(&k, s);
    wvol_store_get_info(s, &info);
    for (b = 0; b < cells && w; b++) {
        double lo[3], hi[3], vmin, vmax, fine[2], smin = INFINITY, smax = -INFINITY;
        int a, i, j, t;
        for (a = 0; a < 3; a++) {
            double side = b % 2 ? 2.0 : 0.5 + 1.5 * rnd();
            lo[a] = b % 2 ? 2.0 * floor(rnd() * ((double)info.nx - 3) / 2.0) : rnd() * ((double)info.nx - 1 - side);
            hi[a] = lo[a] + side;
        }
        CHECK(wvol_store_query_box(s, lo, hi, &hl, NULL) == WVOL_OK, "%s: query", what);
        wvol__iso_box_range_list(&k, hl.hits, hl.count, lo, hi, &vmin, &vmax, fine);
        /* f^ on a q^3 grid with the cell's faces and corners, jittered inside */
        for (i = 0; i < q * q * q; i++) {
            double x[3], f;
            for (a = 0, j = i; a < 3; a++, j /= q) {
                double u = (double)(j % q) / (q - 1);
                if (j % q && j % q != q - 1) u += (rnd() - 0.5) / (q - 1);
                x[a] = lo[a] + (hi[a] - lo[a]) * u;
            }
            f = wvol_store_eval(s, x, NULL);
            smin = fmin(smin, f);
            smax = fmax(smax, f);
        }
        for (t = 0; t < 6; t++) {
            /* above and below the samples by 2%, 10%, 40% of the interval range's slack there, and
             * inside them */
            static const double frac[3] = {0.02, 0.1, 0.4};
            double iso = t < 3 ? smax + frac[t] * (vmax - smax) : t < 5 ? smin - frac[t - 3] * (smin - vmin)
                                                                        : 0.5 * (smin + smax);
            int c;
            if (iso <= vmin || iso >= vmax) continue; /* the interval range decides: not tried */
            tried++;
            c = wvol__iso_box_class_tensor(&k, w, hl.hits, hl.count, lo, hi, fine, iso);
            if (c < 0) continue;
            decided++;
            if ((c == 1 && !(smin > iso)) || (c == 0 && !(smax < iso))) wrong++;
        }
    }
    printf("  %s: tensor classes on %d cells: %d tried, %d decided, %d contradicted by sampled f^\n", what, cells,
           tried, decided, wrong);
    CHECK(w != NULL, "%s: scratch", what);
    CHECK(wrong == 0, "%s: %d tensor classes contradicted by f^", what, wrong);
    if (w) free(w->order);
    free(w);
    wvol_store_hits_free(&hl);
    wvol__iso_boxk_free(&k);
    return decided;
}

/* An image traced with and without the tensor ranges, rays dense enough for them (zoomed): the
 * same hits pixel for pixel; depths within 2e-3 voxels (each within the root tolerance of 1e-3
 * voxels of its crossing, the runs differ; plus float depth rounding). Returns 1 where the
 * tensor ranges changed the trace's work (its cells or pieces), 0 where they did not. */
static int image_equal(const wvol_store *s, double iso, int width, int height, double zoom, const char *what)
{
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img = NULL;
    wvol_store_info info;
    wvol_iso_trace_params p;
    wvol_iso_trace_stats st0, st1;
    float *d0 = malloc((size_t)width * height * sizeof(float)), *d1 = malloc((size_t)width * height * sizeof(float));
    double dir[3] = {-0.5, 1, 0.3}, worst = 0;
    int i, differ = 0, hits = 0;
    wvol_store_get_info(s, &info);
    g.dims[0] = info.nx, g.dims[1] = info.ny, g.dims[2] = info.nz;
    for (int a = 0; a < 3; a++) g.spacing[a] = info.spacing[a], g.origin[a] = info.origin[a];
    wvol_camera_frame(&cam, &g, dir, WVOL_PROJECTION_PERSPECTIVE, width, height, 0, NULL);
    cam.fov_y /= zoom;
    wvol_image_create(&img, width, height, NULL);
    wvol_iso_trace_params_default(&p);
    p.threads = 2;
    wvol__trace_tensor_off = 1;
    CHECK(img && d0 && d1 && wvol_iso_raytrace(img, d0, NULL, s, &cam, iso, &p, &st0, NULL) == WVOL_OK,
          "%s: image without", what);
    wvol__trace_tensor_off = 0;
    CHECK(img && d0 && d1 && wvol_iso_raytrace(img, d1, NULL, s, &cam, iso, &p, &st1, NULL) == WVOL_OK,
          "%s: image with", what);
    for (i = 0; d0 && d1 && i < width * height; i++) {
        if (isfinite(d0[i]) != isfinite(d1[i])) differ++;
        else if (isfinite(d0[i])) {
            hits++;
            worst = fmax(worst, fabs((double)d0[i] - d1[i]) / info.spacing[0]);
        }
    }
    printf("  %s, %dx%d zoom %g: %d hits, %d differ, depth within %.2g voxels; undecided finest cells %zu -> %zu\n",
           what, width, height, zoom, hits, differ, worst, st0.cells_undecided, st1.cells_undecided);
    CHECK(hits > 0, "%s: the image hits the surface", what);
    CHECK(differ == 0, "%s: %d pixels differ in hit with the tensor ranges", what, differ);
    CHECK(worst <= 2e-3, "%s: depth differs by %g voxels with the tensor ranges", what, worst);
    wvol_image_destroy(img);
    free(d0);
    free(d1);
    return st0.cells != st1.cells || st0.pieces != st1.pieces;
}

int main(void)
{
    setvbuf(stdout, NULL, _IONBF, 0);
    static const struct {
        const char *kind, *f;
        size_t n;
        double keep, iso;
        int w, h;
    } cases[] = {
        {"skull", "db2", 40, 0.01, 400.0, 37, 29}, {"skull", "db2", 40, 0.05, 400.0, 31, 33},
        {"skull", "db2", 40, 0.2, 400.0, 27, 25},  {"skull", "haar", 40, 0.05, 400.0, 33, 27},
        {"gaussian", "db2", 32, 0.05, 0.5, 35, 23},
    };
    size_t i;
    int decided = 0;
    int changed = 0;
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        wvol_synth_params sp;
        wvol_volume *v = NULL;
        wvol_store *s;
        char what[96];
        wvol_synth_params_default(&sp);
        sp.dims[0] = sp.dims[1] = sp.dims[2] = cases[i].n;
        sp.seed = 5;
        if (wvol_synth_make(&v, NULL, cases[i].kind, &sp, NULL) != WVOL_OK) v = NULL;
        s = v ? fixture_store(v, cases[i].f, 3, cases[i].keep, 4) : NULL;
        snprintf(what, sizeof what, "%s %zu^3 %s L3 keep %g iso %g", cases[i].kind, cases[i].n, cases[i].f,
                 cases[i].keep, cases[i].iso);
        CHECK(s != NULL, "%s: store", what);
        if (s) {
            decided += classes_hold(s, 120, 7, what);
            /* zoom 3 and 5: 2.5-6 rays across a 2-voxel cell, where the tracer uses the ranges */
            changed += image_equal(s, cases[i].iso, cases[i].w, cases[i].h, i % 2 ? 3.0 : 5.0, what);
        }
        wvol_store_destroy(s);
        wvol_volume_destroy(v);
    }
    /* the checks above mean something only where the tensor ranges decide cells */
    CHECK(decided > 50, "the tensor ranges decided only %d random cells", decided);
    CHECK(changed >= 3, "the tensor ranges changed the work of only %d images", changed);
    return check_summary("test_iso_trace_tensor");
}
