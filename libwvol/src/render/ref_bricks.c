/* SPDX-License-Identifier: MIT
 * The reference integrator's brick schedule for a bricked source (wvol__source_ops
 * walk_bricks): a tile's rays walk its bricks together, front to back, each brick taken once
 * every brick a ray could come from is walked (brick_order), so the tile builds each brick
 * it needs once; the threads share the tile, or each walks tiles of its own where the bricks
 * are kept built (ref_tiles.c, wvol__source.walk_own). */
#define _POSIX_C_SOURCE 200809L /* nanosleep, sched_yield (idle_wait) */
#include "reference_internal.h"

#include <omp.h>
#include <sched.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Whether d (-1 or +1) is an outward step from brick coordinate c along axis a: away from the
 * eye's brick (either way from it), or the direction's sign for parallel rays. */
static inline int outward_ok(const brick_order *bo, int a, long c, long d)
{
    if (bo->dir[a] == 2) return c == bo->eye[a] ? (d == 1 || d == -1) : d == (c > bo->eye[a] ? 1 : -1);
    return bo->dir[a] != 0 && d == bo->dir[a];
}

/* Whether brick `to` is an outward neighbour of brick `from` (coordinates): every axis the
 * same or one outward step, not all the same. */
static inline int outward_step(const brick_order *bo, const long from[3], const int32_t to[3])
{
    int moved = 0;
    for (int a = 0; a < 3; a++) {
        long d = (long)to[a] - from[a];
        if (!d) continue;
        if ((d != 1 && d != -1) || !outward_ok(bo, a, from[a], d)) return 0;
        moved = 1;
    }
    return moved;
}

static void brick_coords(const brick_order *bo, long b, long c[3])
{
    c[0] = b % bo->bn[0];
    c[1] = (b / bo->bn[0]) % bo->bn[1];
    c[2] = b / (bo->bn[0] * bo->bn[1]);
}

/* Runs BODY with nb set to each outward neighbour of brick b in the grid. */
#define FOR_OUTWARD(bo, b, BODY)                                                                           \
    do {                                                                                                   \
        long c_[3], n_[3];                                                                                 \
        brick_coords(bo, b, c_);                                                                           \
        for (long dz_ = -1; dz_ <= 1; dz_++)                                                               \
            for (long dy_ = -1; dy_ <= 1; dy_++)                                                           \
                for (long dx_ = -1; dx_ <= 1; dx_++) {                                                     \
                    const long d_[3] = {dx_, dy_, dz_};                                                    \
                    int ok_ = dx_ || dy_ || dz_;                                                           \
                    for (int a_ = 0; ok_ && a_ < 3; a_++) {                                                \
                        n_[a_] = c_[a_] + d_[a_];                                                          \
                        ok_ = n_[a_] >= 0 && n_[a_] < bo->bn[a_];                                          \
                        if (ok_ && d_[a_]) ok_ = outward_ok(bo, a_, c_[a_], d_[a_]);                       \
                    }                                                                                      \
                    if (ok_) {                                                                             \
                        const long nb = n_[0] + bo->bn[0] * (n_[1] + bo->bn[1] * n_[2]);                   \
                        BODY;                                                                              \
                    }                                                                                      \
                }                                                                                          \
    } while (0)

void wvol__brick_order_free(brick_order *bo)
{
    free(bo->inward);
    free(bo->pending);
    free(bo->ready);
}

wvol_status wvol__brick_order_make(brick_order *bo, const wvol__source *s, const wvol__cam *k, wvol_error *err)
{
    memset(bo, 0, sizeof *bo);
    bo->n = s->bn[0] * s->bn[1] * s->bn[2];
    WVOL_RETURN_IF(bo->n > UINT32_MAX, err, WVOL_ERR_NOMEM, "render: %zu bricks (at most 2^32: a larger brick side)",
                   bo->n);
    for (int a = 0; a < 3; a++) {
        bo->bn[a] = (long)s->bn[a];
        if (k->c.projection == WVOL_PROJECTION_PERSPECTIVE) { /* the eye's brick, as ray_enter finds it */
            double c = ((k->c.eye[a] - s->origin[a]) / s->spacing[a] + 0.5) / s->B;
            bo->eye[a] = c > 0 ? (c < (double)s->bn[a] ? (long)c : (long)s->bn[a] - 1) : 0;
            bo->dir[a] = 2;
        } else { /* every ray's index-space direction has the sign of fwd / spacing */
            bo->dir[a] = k->fwd[a] > 0 ? 1 : k->fwd[a] < 0 ? -1 : 0;
        }
    }
    bo->inward = calloc(bo->n, sizeof *bo->inward);
    bo->pending = malloc(bo->n * sizeof *bo->pending);
    bo->ready = malloc(bo->n * sizeof *bo->ready);
    if (!bo->inward || !bo->pending || !bo->ready) {
        wvol__brick_order_free(bo);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the brick order");
    }
    for (long b = 0; b < (long)bo->n; b++) FOR_OUTWARD(bo, b, bo->inward[nb]++);
    return WVOL_OK;
}

/* Ray i onto brick b's list (head: per brick, -1 when empty; next: per ray). shared: several
 * threads may push onto one list at once (a locked exchange); else the tile is the calling
 * thread's alone, and plain stores do (no locked instruction per ray and brick). */
static inline void list_push(int32_t *head, int32_t *next, long b, int32_t i, int shared)
{
    if (!shared) {
        next[i] = head[b];
        head[b] = i;
        return;
    }
    int32_t old = __atomic_load_n(&head[b], __ATOMIC_RELAXED);
    do {
        next[i] = old;
    } while (!__atomic_compare_exchange_n(&head[b], &old, i, 1, __ATOMIC_RELEASE, __ATOMIC_RELAXED));
}

/* Whether every ray skips brick b whole (its rate known to be 0 without building it). */
static inline int known_empty(const wvol__source *s, long b)
{
    return s->ops->known_rate && s->ops->known_rate(s, (size_t)b) == 0;
}

/* The rays on brick b's list take their runs in it (its view fetched once, then a cache hit
 * for each) and move to the list of the brick they enter next, an outward neighbour, which is
 * walked after b (render_tile_bricked). A ray whose next brick is known to be empty passes
 * through it at once (its run skipped, as its turn there would skip it) rather than wait on
 * its list: from a brick not yet walked, an outward neighbour is not yet walked either (it
 * counts the other among its pending inward neighbours), so the brick the ray is queued on
 * in the end is one still to come. A ray whose next brick is not an outward neighbour (which
 * the geometry rules out: brick_order) walks on at once: its fetch may build a brick again,
 * and its image is the same. */
static void walk_brick(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                       ray_state *rs, const brick_order *bo, int32_t *head, int32_t *next, long b, int shared)
{
    int32_t i = head[b];
    long bc[3];
    brick_coords(bo, b, bc);
    head[b] = -1;
    while (i >= 0) {
        const int32_t after = next[i];
        ray_state *st = &rs[i];
        long from[3] = {bc[0], bc[1], bc[2]}; /* the last brick of the ray's known not yet walked */
        if (after >= 0) { /* the list's next ray, from memory while this one walks: a tile's rays
                           * outgrow the caches, and a list visits them in no memory order */
            const char *q = (const char *)&rs[after];
            for (size_t o = 0; o < sizeof *st; o += 64) __builtin_prefetch(q + o, 1);
            __builtin_prefetch(&next[after]);
        }
        for (;;) {
            long nb;
            if (st->k < st->nfull) wvol__ray_advance_any(s, tc, tfx, p, dt, st);
            else wvol__ray_last(s, tc, tfx, p, dt, st);
            nb = wvol__ray_next_brick(s, st, dt);
            if (nb < 0) { /* the ray is done */
                acc_settle(tfx, &st->r);
                break;
            }
            if (outward_step(bo, from, st->bc)) {
                if (known_empty(s, nb)) { /* through it at once */
                    for (int a = 0; a < 3; a++) from[a] = st->bc[a];
                    continue;
                }
                list_push(head, next, nb, i, shared);
                break;
            }
        }
        i = after;
    }
}

/* A thread with no brick to take waits for another thread to finish one: a few pauses (a
 * brick's walk often ends within them), then it gives its core away, first by yielding and
 * then by sleeping 20 us at a time. On a machine with more threads than free cores the
 * thread it waits for may not be running: spinning then burns the core that thread needs
 * (the CPU time of a two-thread frame doubled under load), while a sleep of 20 us is short
 * beside a brick's walk (~1 ms on the benchmark). */
static void idle_wait(unsigned n)
{
    if (n < 64) {
#if defined(__SSE2__)
        _mm_pause();
#endif
    } else if (n < 96) {
        sched_yield();
    } else {
        const struct timespec ts = {0, 20000};
        nanosleep(&ts, NULL);
    }
}

/* Whether pixel (x, y) lies in the rectangle r of wvol__cam_box_pixels. */
static inline int in_box(const int r[4], int x, int y)
{
    return x >= r[0] && x < r[2] && y >= r[1] && y < r[3];
}

/* Ray i of a tile (pixel `pixel`, its ray o + t d over [t0, t1]) set up in rs and put on the
 * list of the first brick it takes samples in: the bricks known to be empty before it are
 * passed through at once (no brick is walked yet, so any may take it); a ray with no such
 * brick is done. */
static inline void ray_enlist(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p,
                              double dt, const double o[3], const double d[3], double t0, double t1, int pixel,
                              ray_state *rs, int32_t i, int32_t *head, int32_t *next, int shared)
{
    ray_state *st = &rs[i];
    long b;
    wvol__ray_begin(s, o, d, t0, t1, dt, st);
    st->pixel = pixel;
    b = wvol__ray_next_brick(s, st, dt);
    while (b >= 0 && known_empty(s, b)) {
        if (st->k < st->nfull) wvol__ray_advance_any(s, tc, tfx, p, dt, st);
        else wvol__ray_last(s, tc, tfx, p, dt, st);
        b = wvol__ray_next_brick(s, st, dt);
    }
    if (b >= 0) list_push(head, next, b, i, shared);
    else acc_settle(tfx, &st->r);
}

/* A barrier without long spins (reference_internal.h); n == 1 returns at once. */
void wvol__walk_sync_wait(walk_sync *w)
{
    if (w->n == 1) return;
    const int round = __atomic_load_n(&w->round, __ATOMIC_ACQUIRE);
    if (__atomic_add_fetch(&w->count, 1, __ATOMIC_ACQ_REL) == w->n) {
        __atomic_store_n(&w->count, 0, __ATOMIC_RELAXED);
        __atomic_store_n(&w->round, round + 1, __ATOMIC_RELEASE);
    } else {
        unsigned idle = 0;
        while (__atomic_load_n(&w->round, __ATOMIC_ACQUIRE) == round) idle_wait(idle++);
    }
}

wvol_status wvol__brick_order_walker(brick_order *w, const brick_order *bo)
{
    *w = *bo;
    w->pending = malloc(bo->n * sizeof *w->pending);
    w->ready = malloc(bo->n * sizeof *w->ready);
    if (w->pending && w->ready) return WVOL_OK;
    wvol__brick_order_walker_free(w);
    return WVOL_ERR_NOMEM;
}

void wvol__brick_order_walker_free(brick_order *w)
{
    free(w->pending);
    free(w->ready);
    w->pending = NULL;
    w->ready = NULL;
}

/* The next brick to walk from bo's ready stack into *b (-1: none ready now); 1 once every
 * brick is walked. shared: under the lock the threads of a shared tile take it by. */
static inline int take_ready(brick_order *bo, long *b, int shared)
{
    int finished = 0;
    *b = -1;
    if (shared) {
#pragma omp critical(wvol_walk_ready)
        {
            if (bo->nready) *b = (long)bo->ready[--bo->nready];
            else finished = bo->ndone == bo->n;
        }
    } else {
        if (bo->nready) *b = (long)bo->ready[--bo->nready];
        else finished = bo->ndone == bo->n;
    }
    return finished;
}

/* Brick b walked: its outward neighbours one inward neighbour nearer to ready. */
static inline void release_done(brick_order *bo, long b, int shared)
{
    if (shared) {
#pragma omp critical(wvol_walk_ready)
        {
            FOR_OUTWARD(bo, b, if (!--bo->pending[nb]) bo->ready[bo->nready++] = (uint32_t)nb);
            bo->ndone++;
        }
    } else {
        FOR_OUTWARD(bo, b, if (!--bo->pending[nb]) bo->ready[bo->nready++] = (uint32_t)nb);
        bo->ndone++;
    }
}

/* The rays of one tile of a bricked source, walked brick by brick front to back
 * (brick_order): each brick's list holds the rays whose next sample lies in it; the rays of
 * the brick at hand take their runs there and move to the list of the brick they enter next.
 * A brick is taken once its inward neighbours are walked (a count per brick; the bricks whose
 * count reaches 0 wait on a stack), so no ray can join its list afterwards: the tile builds
 * each brick its rays need once, and a thread's cache needs to hold one brick. With nt > 1
 * threads the tile is shared: a brick is walked, and built, by whichever thread takes it
 * (the stack taken and released under one lock, twice per brick; the lists pushed onto by
 * locked exchanges). With nt = 1 the tile is the calling thread's alone (one thread, or the
 * threads walking tiles of their own: ref_tiles.c), with no lock, wait or exchange. Each
 * ray's own samples are taken in its order, so the image is the ray-by-ray walk's, whatever
 * the thread count and the split. (A cache per thread walked in rounds, or rounds of bricks
 * with barriers, built more or waited more: bench/results/render-tuning.md.) */
void wvol__render_tile_bricked(const wvol__source *s, void *tc, const wvol__cam *k, wvol_image *img,
                               const double lo[3], const double hi[3], int x0, int y0, int tw, int th,
                               const tf_fast *tfx, const wvol_render_params *p, double dt, ray_state *rs,
                               int32_t *row_first, double *span, brick_order *bo, int32_t *head, int32_t *next,
                               int tid, int nt, walk_sync *w)
{
    const int shared = nt > 1;
    const int ya = y0 + (int)((long)th * tid / nt), yb = y0 + (int)((long)th * (tid + 1) / nt); /* my rows */
    int box[4]; /* the pixels whose rays may meet the volume: the others are misses untested */
    wvol__cam_box_pixels(k, lo, hi, box);
    if (tid == 0) {
        memcpy(bo->pending, bo->inward, bo->n * sizeof *bo->pending);
        bo->nready = bo->ndone = 0;
        for (size_t b = bo->n; b-- > 0;)
            if (!bo->inward[b]) bo->ready[bo->nready++] = (uint32_t)b;
    }
    if (!shared) {
        /* the tile's rays that meet the volume, in rs row by row, each onto its first brick's
         * list: one pass */
        int32_t i = 0;
        for (int y = y0; y < y0 + th; y++)
            for (int x = x0; x < x0 + tw; x++) {
                float *px = img->rgba + 4 * ((size_t)x + (size_t)img->width * (size_t)y);
                double o[3], d[3], t0, t1;
                px[0] = px[1] = px[2] = px[3] = 0.0f;
                if (!in_box(box, x, y) || !pixel_span(k, lo, hi, x, y, o, d, &t0, &t1)) continue;
                ray_enlist(s, tc, tfx, p, dt, o, d, t0, t1, (x - x0) + tw * (y - y0), rs, i++, head, next, 0);
            }
        row_first[th] = i;
    } else {
        /* the same, set up by the threads in two passes so that the rays lie packed (a state
         * per pixel would make the pages of the misses resident too): each row's count and
         * each pixel's span, then its rays from the row's first index on (the spans kept, so
         * the second pass takes only the hits' directions again) */
        for (int y = ya; y < yb; y++) {
            int32_t n = 0;
            double *sp = span + 2 * (size_t)tw * (size_t)(y - y0);
            for (int x = x0; x < x0 + tw; x++, sp += 2) {
                double o[3], d[3];
                if (in_box(box, x, y) && pixel_span(k, lo, hi, x, y, o, d, &sp[0], &sp[1])) n++;
                else sp[0] = sp[1] = 0.0; /* a miss: no span */
            }
            row_first[y - y0 + 1] = n;
        }
        wvol__walk_sync_wait(w);
        if (tid == 0) {
            row_first[0] = 0;
            for (int j = 0; j < th; j++) row_first[j + 1] += row_first[j];
        }
        wvol__walk_sync_wait(w);
        for (int y = ya; y < yb; y++) {
            int32_t i = row_first[y - y0];
            const double *sp = span + 2 * (size_t)tw * (size_t)(y - y0);
            for (int x = x0; x < x0 + tw; x++, sp += 2) {
                float *px = img->rgba + 4 * ((size_t)x + (size_t)img->width * (size_t)y);
                double o[3], d[3];
                px[0] = px[1] = px[2] = px[3] = 0.0f;
                if (!(sp[1] > sp[0])) continue;
                wvol__cam_ray(k, x + 0.5, y + 0.5, o, d); /* pixel_span's ray, its span kept */
                ray_enlist(s, tc, tfx, p, dt, o, d, sp[0], sp[1], (x - x0) + tw * (y - y0), rs, i++, head, next, 1);
            }
        }
    }
    wvol__walk_sync_wait(w);
    for (unsigned idle = 0;;) { /* idle: consecutive waits for a ready brick */
        long b;
        if (take_ready(bo, &b, shared)) break;
        if (b < 0) { /* the other threads hold the bricks that would free some (shared only:
                      * alone, a brick not walked always has a chain of ready ones to it) */
            idle_wait(idle++);
            continue;
        }
        idle = 0;
        if (head[b] >= 0) walk_brick(s, tc, tfx, p, dt, rs, bo, head, next, b, shared);
        release_done(bo, b, shared);
    }
    /* every brick walked, so every ray done: the caller may read rs, and reset the order for
     * the next tile once no thread still looks at it */
    wvol__walk_sync_wait(w);
}
