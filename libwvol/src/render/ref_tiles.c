/* SPDX-License-Identifier: MIT
 * Reference integrator (paper eq 33): front-to-back compositing of samples taken at a
 * regular step along each ray, with step-corrected opacity alpha = 1 - exp(-kappa dt)
 * (or the linearised kappa dt in absorption-linear mode), early ray termination and
 * skipping over a min/max brick grid (bricks that add nothing, and within
 * params->skip_tolerance those that add little: ref_walk.c, ray_skip). Samples are trilinear
 * interpolation of the voxels, or f^ through the spline tables (the converged reference
 * of the spline model): a source (render_internal.h) says which.
 * This file: the tile loop, the render's set-up and its counters. The rest: ref_view.c
 * (trilinear views, the dense source), ref_tables.c (the transfer-function and exponential
 * tables), ref_samples.h (the sample loops), ref_walk.c (the ray walk), ref_bricks.c (the
 * brick schedule of a bricked source).
 * Based on: Levoy 1988 (ray casting); Max 1995 (optical models); DESIGN.md section 8. */
#include "reference_internal.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

/* The rays of one tile (n of them, in rs) of a dense source: one after the other. */
static void render_tile(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                        ray_state *rs, int n)
{
    for (int i = 0; i < n; i++) {
        while (wvol__ray_advance_any(s, tc, tfx, p, dt, &rs[i])) continue;
        wvol__ray_last(s, tc, tfx, p, dt, &rs[i]);
        acc_settle(tfx, &rs[i].r);
    }
}

/* The bricked walk's tile side: the largest square whose rays (states, list links, spans) fit
 * the bytes the source grants, evened out so that the image's tiles are alike (a tile's rays
 * build each brick they need once, ref_bricks.c: the larger the tile, the fewer
 * bricks two tiles both build); 0 without a grant. */
static int walk_tile(const wvol__source *s, const wvol_image *img)
{
    int side, n, big = img->width > img->height ? img->width : img->height;
    if (!s->walk_bytes) return 0;
    side = (int)sqrt((double)s->walk_bytes / (double)(sizeof(ray_state) + sizeof(int32_t) + 2 * sizeof(double)));
    if (side < 16) side = 16;
    if (side >= big) return big;
    n = (big + side - 1) / side;
    return (big + n - 1) / n;
}

/* A tile's rays (those that meet the volume) into rs; returns their count. */
static int tile_rays(const wvol__source *s, const wvol__cam *k, const wvol_image *img, const double lo[3],
                     const double hi[3], double dt, int x0, int y0, int tw, int th, ray_state *rs)
{
    int n = 0;
    for (int y = y0; y < y0 + th; y++)
        for (int x = x0; x < x0 + tw; x++)
            if (pixel_ray(s, k, img, lo, hi, dt, x, y, &rs[n])) rs[n++].pixel = (x - x0) + tw * (y - y0);
    return n;
}

/* A walked tile's pixels, and its rays' counts added to c; a failed fetch's status to *failed. */
static void tile_finish(const wvol_render_params *p, wvol_image *img, int x0, int y0, int tw, const ray_state *rs,
                        int n, wvol__counts *c, wvol_status *failed)
{
    for (int i = 0; i < n; i++) {
        const ray_state *st = &rs[i];
        c->rays_hit++;
        wvol__ray_pixel(p, st, img->rgba + 4 * ((size_t)(x0 + st->pixel % tw) + (size_t)img->width * (size_t)(y0 + st->pixel / tw)));
        c->samples += st->nsamp;
        c->skipped += st->nskip;
        c->skipped_tolerance += st->nskip_tol;
        if (st->skipped > c->skip_bound) c->skip_bound = st->skipped;
        c->terminated += (size_t)st->done;
        c->clamped += (size_t)st->r.nclamp;
        if (st->failed != WVOL_OK) *failed = st->failed;
    }
}

static void counts_add(wvol__counts *to, const wvol__counts *c)
{
    to->rays_hit += c->rays_hit;
    to->samples += c->samples;
    to->skipped += c->skipped;
    to->skipped_tolerance += c->skipped_tolerance;
    to->terminated += c->terminated;
    to->clamped += c->clamped;
    if (c->skip_bound > to->skip_bound) to->skip_bound = c->skip_bound;
}

wvol_status wvol__render_sampled(wvol_image *img, wvol__source *s, const wvol_camera *cam, const wvol_tf *tf_in,
                          const wvol_render_params *pin, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_geometry g;
    wvol_tf tf;
    tf_fast tfx;
    wvol__cam k;
    double lo[3], hi[3], dt, t_start, c_start;
    int ntiles, tx, a, *order, nthreads;
    size_t tile_rays_n;
    brick_order bo;
    wvol__counts counts;
    wvol_status status = WVOL_OK, failed = WVOL_OK;

    memset(&counts, 0, sizeof counts);
    wvol__params(&p, pin);
    WVOL_FORWARD(wvol__render_check(img, cam, tf_in, &p, err));
    WVOL_FORWARD(wvol__check_colors(&p, s->n, 1, err));
    WVOL_FORWARD(wvol__check_skip(&p, s->B > 0, err));
    WVOL_RETURN_IF(p.gradient_levels > 0 && !s->ops->lowpass_gradient, err, WVOL_ERR_UNSUPPORTED,
                   "render: gradient_levels needs the wavelet model of a store (method bricks)");
    for (a = 0; a < 3; a++) {
        g.dims[a] = s->n[a];
        g.spacing[a] = s->spacing[a];
        g.origin[a] = s->origin[a];
        WVOL_RETURN_IF(!(s->spacing[a] > 0) || !isfinite(s->spacing[a]) || !isfinite(s->origin[a]), err, WVOL_ERR_ARG,
                       "render: spacing and origin must be finite, spacing > 0");
    }
    if (p.mode != WVOL_RENDER_MODE_XRAY) wvol__tf_world(&tf, tf_in, &g);
    else memset(&tf, 0, sizeof tf);
    wvol__tf_fast_init(&tfx, &tf);
    s->B_inv = s->B > 0 && !(s->B & (s->B - 1)) ? 1.0 / s->B : 0.0;
    wvol_geometry_bounds(&g, lo, hi);
    dt = p.step * fmin(s->spacing[0], fmin(s->spacing[1], s->spacing[2]));
    s->dt_inv = 1.0 / dt;
    t_start = wvol__now();
    c_start = wvol__cpu_now();
    if (s->ops->prepare) WVOL_FORWARD(s->ops->prepare(s, &tf, &p, err));
    wvol__cam_init(&k, cam);
    p.tile = wvol__tile_side(&p, walk_tile(s, img));
    ntiles = wvol__tiles(img->width, img->height, p.tile);
    tx = (img->width + p.tile - 1) / p.tile;
    order = wvol__tile_order(img->width, img->height, p.tile);
    nthreads = wvol__threads(p.threads);
    tile_rays_n = (size_t)p.tile * (size_t)p.tile;
    memset(&bo, 0, sizeof bo);
    if (s->ops->walk_bricks) {
        /* the bricked walk: one tile at a time, its bricks shared by the threads */
        /* on cache lines: a ray's state is taken from memory each time it enters a brick */
        ray_state *rs = aligned_alloc(64, (tile_rays_n * sizeof *rs + 63) / 64 * 64);
        int32_t *lists = NULL; /* the bricks' list heads, then the rays' links */
        int32_t *row_first = malloc(((size_t)p.tile + 1) * sizeof *row_first);
        double *span = malloc(2 * tile_rays_n * sizeof *span);
        status = !order || !rs || !row_first || !span
                     ? wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for a tile's rays")
                               : wvol__brick_order_make(&bo, s, &k, err);
        if (status == WVOL_OK) {
            lists = malloc((bo.n + tile_rays_n) * sizeof *lists);
            if (!lists) status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for a tile's rays");
            else
                for (size_t b = 0; b < bo.n; b++) lists[b] = -1;
        }
        if (status == WVOL_OK) {
            /* one parallel region for all tiles, the threads kept in step by walk_sync, which
             * sleeps where OpenMP's barriers would spin */
            walk_sync w = {0, 0, 0};
#pragma omp parallel num_threads(nthreads)
            {
                const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
#pragma omp single
                w.n = nt; /* the barrier at its end publishes it */
                for (int ti = 0; ti < ntiles; ti++) {
                    int x0 = (order[ti] % tx) * p.tile, y0 = (order[ti] / tx) * p.tile;
                    int tw = img->width - x0 < p.tile ? img->width - x0 : p.tile;
                    int th = img->height - y0 < p.tile ? img->height - y0 : p.tile;
                    wvol__render_tile_bricked(s, &k, img, lo, hi, x0, y0, tw, th, &tfx, &p, dt, rs, row_first, span,
                                              &bo, lists, lists + bo.n, tid, nt, &w);
                    if (tid == 0) tile_finish(&p, img, x0, y0, tw, rs, row_first[th], &counts, &failed);
                    wvol__walk_sync_wait(&w); /* rs and row_first read before the next tile's rays */
                }
            }
        }
        /* the walk's own: the tile's rays and lists, the order */
        counts.bytes = tile_rays_n * (sizeof *rs + sizeof *lists + 2 * sizeof *span) + ((size_t)p.tile + 1) * sizeof *row_first +
                       bo.n * (sizeof *lists + sizeof *bo.inward + sizeof *bo.pending + sizeof *bo.ready);
        free(rs);
        free(lists);
        free(row_first);
        free(span);
        wvol__brick_order_free(&bo);
    } else if (!order) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory");
    } else {
        /* rays walked one by one: tiles over the threads, in chunks of 4 Z-ordered tiles (2 x
         * 2); each thread's tile of ray states allocated once (a buffer above malloc's mmap
         * threshold comes back as fresh pages for the kernel to zero) */
#pragma omp parallel num_threads(nthreads)
        {
            ray_state *rs = malloc(tile_rays_n * sizeof *rs);
            void *tc = s->tctx ? s->tctx[omp_get_thread_num()] : NULL;
            wvol__counts mine;
            wvol_status my_failed = rs ? WVOL_OK : WVOL_ERR_NOMEM;
            memset(&mine, 0, sizeof mine);
#pragma omp for schedule(dynamic, 4)
            for (int ti = 0; ti < ntiles; ti++) {
                int x0 = (order[ti] % tx) * p.tile, y0 = (order[ti] / tx) * p.tile, n;
                int tw = img->width - x0 < p.tile ? img->width - x0 : p.tile;
                int th = img->height - y0 < p.tile ? img->height - y0 : p.tile;
                if (!rs) continue;
                n = tile_rays(s, &k, img, lo, hi, dt, x0, y0, tw, th, rs);
                render_tile(s, tc, &tfx, &p, dt, rs, n);
                tile_finish(&p, img, x0, y0, tw, rs, n, &mine, &my_failed);
            }
#pragma omp critical(wvol_render_counts)
            {
                counts_add(&counts, &mine);
                if (my_failed != WVOL_OK) failed = my_failed;
            }
            free(rs);
        }
    }
    free(order);
    if (status != WVOL_OK) return status;
    WVOL_RETURN_IF(failed != WVOL_OK, err, failed, "render: out of memory (a brick could not be reconstructed, or a tile's rays)");
    wvol__stats_fill(stats, img, t_start, c_start, &counts);
    return wvol__image_check_range(img, err);
}
