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
 * the bytes the source grants (split between `walkers` tiles walked at once), evened out so
 * that the image's tiles are alike (a tile's rays build each brick they need once,
 * ref_bricks.c: the larger the tile, the fewer bricks two tiles both build); 0 without a
 * grant. */
static int walk_tile(const wvol__source *s, const wvol_image *img, int walkers)
{
    int side, n, big = img->width > img->height ? img->width : img->height;
    if (!s->walk_bytes) return 0;
    side = (int)sqrt((double)s->walk_bytes / walkers /
                     (double)(sizeof(ray_state) + sizeof(int32_t) + 2 * sizeof(double)));
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

/* One walker's buffers for tiles of `rays` pixels over a grid of nb bricks: the rays' states
 * (on cache lines: a ray's state is taken from memory each time it enters a brick), the
 * bricks' list heads (all -1 between tiles) then the rays' links, each row's first ray, and
 * for threads sharing a tile each pixel's span (NULL for a walker alone). */
typedef struct tile_bufs {
    ray_state *rs;
    int32_t *lists, *row_first;
    double *span;
} tile_bufs;

static void tile_bufs_free(tile_bufs *t)
{
    free(t->rs);
    free(t->lists);
    free(t->row_first);
    free(t->span);
}

static int tile_bufs_alloc(tile_bufs *t, size_t rays, int side, size_t nb, int shared)
{
    t->rs = aligned_alloc(64, (rays * sizeof *t->rs + 63) / 64 * 64);
    t->lists = malloc((nb + rays) * sizeof *t->lists);
    t->row_first = malloc(((size_t)side + 1) * sizeof *t->row_first);
    t->span = shared ? malloc(2 * rays * sizeof *t->span) : NULL;
    if (!t->rs || !t->lists || !t->row_first || (shared && !t->span)) {
        tile_bufs_free(t);
        memset(t, 0, sizeof *t);
        return 0;
    }
    for (size_t b = 0; b < nb; b++) t->lists[b] = -1;
    return 1;
}

static size_t tile_bufs_bytes(size_t rays, int side, size_t nb, int shared)
{
    return rays * (sizeof(ray_state) + sizeof(int32_t) + (shared ? 2 * sizeof(double) : 0)) +
           ((size_t)side + 1) * sizeof(int32_t) + nb * sizeof(int32_t);
}

/* Tile ti's box in the image. */
static void tile_box(const wvol_image *img, const int *order, int tile, int tx, int ti, int *x0, int *y0, int *tw,
                     int *th)
{
    *x0 = (order[ti] % tx) * tile, *y0 = (order[ti] / tx) * tile;
    *tw = img->width - *x0 < tile ? img->width - *x0 : tile;
    *th = img->height - *y0 < tile ? img->height - *y0 : tile;
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
    int ntiles, tx, a, *order, nthreads, own;
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
    nthreads = wvol__threads(p.threads);
    own = s->ops->walk_bricks && nthreads > 1 && s->walk_own;
    p.tile = wvol__tile_side(&p, walk_tile(s, img, own ? nthreads : 1));
    ntiles = wvol__tiles(img->width, img->height, p.tile);
    tx = (img->width + p.tile - 1) / p.tile;
    order = wvol__tile_order(img->width, img->height, p.tile);
    tile_rays_n = (size_t)p.tile * (size_t)p.tile;
    memset(&bo, 0, sizeof bo);
    if (s->ops->walk_bricks && own) {
        /* the bricks are kept built (s->walk_own): each thread walks tiles of its own, alone,
         * with its own buffers and brick order (no lock, wait or ray crossing cores); tiles
         * dealt out one at a time, in Z order */
        status = !order ? wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory")
                        : wvol__brick_order_make(&bo, s, &k, err);
        if (status == WVOL_OK) {
#pragma omp parallel num_threads(nthreads)
            {
                tile_bufs t;
                brick_order mine;
                walk_sync alone = {1, 0, 0};
                void *tc = s->tctx[omp_get_thread_num()];
                wvol__counts c;
                wvol_status my_failed = WVOL_OK;
                int ok = tile_bufs_alloc(&t, tile_rays_n, p.tile, bo.n, 0);
                memset(&c, 0, sizeof c);
                if (ok && wvol__brick_order_walker(&mine, &bo) != WVOL_OK) {
                    tile_bufs_free(&t);
                    ok = 0;
                }
#pragma omp for schedule(dynamic, 1)
                for (int ti = 0; ti < ntiles; ti++) {
                    int x0, y0, tw, th;
                    if (!ok) continue;
                    tile_box(img, order, p.tile, tx, ti, &x0, &y0, &tw, &th);
                    wvol__render_tile_bricked(s, tc, &k, img, lo, hi, x0, y0, tw, th, &tfx, &p, dt, t.rs,
                                              t.row_first, t.span, &mine, t.lists, t.lists + bo.n, 0, 1, &alone);
                    tile_finish(&p, img, x0, y0, tw, t.rs, t.row_first[th], &c, &my_failed);
                }
                if (ok) {
                    tile_bufs_free(&t);
                    wvol__brick_order_walker_free(&mine);
                }
#pragma omp critical(wvol_render_counts)
                {
                    counts_add(&counts, &c);
                    if (!ok) status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for a tile's rays");
                    else if (my_failed != WVOL_OK) failed = my_failed;
                }
            }
        }
        counts.bytes = (size_t)nthreads * (tile_bufs_bytes(tile_rays_n, p.tile, bo.n, 0) +
                                           bo.n * (sizeof *bo.pending + sizeof *bo.ready)) +
                       bo.n * sizeof *bo.inward;
        wvol__brick_order_free(&bo);
    } else if (s->ops->walk_bricks) {
        /* the bricked walk: one tile at a time, its bricks shared by the threads */
        tile_bufs t;
        memset(&t, 0, sizeof t);
        status = !order ? wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory")
                        : wvol__brick_order_make(&bo, s, &k, err);
        if (status == WVOL_OK && !tile_bufs_alloc(&t, tile_rays_n, p.tile, bo.n, nthreads > 1))
            status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for a tile's rays");
        if (status == WVOL_OK) {
            /* one parallel region for all tiles, the threads kept in step by walk_sync, which
             * sleeps where OpenMP's barriers would spin */
            walk_sync w = {0, 0, 0};
#pragma omp parallel num_threads(nthreads)
            {
                const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
                void *tc = s->tctx[tid];
#pragma omp single
                w.n = nt; /* the barrier at its end publishes it */
                for (int ti = 0; ti < ntiles; ti++) {
                    int x0, y0, tw, th;
                    tile_box(img, order, p.tile, tx, ti, &x0, &y0, &tw, &th);
                    wvol__render_tile_bricked(s, tc, &k, img, lo, hi, x0, y0, tw, th, &tfx, &p, dt, t.rs, t.row_first,
                                              t.span, &bo, t.lists, t.lists + bo.n, tid, nt, &w);
                    if (tid == 0) tile_finish(&p, img, x0, y0, tw, t.rs, t.row_first[th], &counts, &failed);
                    wvol__walk_sync_wait(&w); /* rs and row_first read before the next tile's rays */
                }
            }
            tile_bufs_free(&t);
        }
        /* the walk's own: the tile's rays and lists, the order */
        counts.bytes = tile_bufs_bytes(tile_rays_n, p.tile, bo.n, nthreads > 1) +
                       bo.n * (sizeof *bo.inward + sizeof *bo.pending + sizeof *bo.ready);
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
                int x0, y0, tw, th, n;
                if (!rs) continue;
                tile_box(img, order, p.tile, tx, ti, &x0, &y0, &tw, &th);
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
    if (stats) stats->tiles_own = own;
    return wvol__image_check_range(img, err);
}
