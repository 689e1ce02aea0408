/* SPDX-License-Identifier: MIT
 * The bricked renderer: the reference integrator (trilinear samples, front-to-back, early
 * termination; ref_tiles.c) reading its samples from bricks reconstructed on demand from a
 * store, never from the dense volume.
 *
 * - The store's block-sparse view of its kept coefficients (store/store_blocks.h).
 * - Bricks of B^3 voxel cells (render_internal.h): a brick's voxels b B - 1 .. (b + 1) B are
 *   reconstructed by a local inverse transform (wvol__idwt3_brick_src) that gathers its
 *   coefficients through the view and skips every band that is zero there.
 * - Before reconstructing, a brick's samples are bounded from the coefficients alone
 *   (wavelet/bounds.c, the bound the bricked isosurface uses); when the brick's rate on
 *   the bound (kappa 0 over it, or within the ray's skip tolerance) lets the ray skip it, it
 *   is not reconstructed. After reconstruction its actual min/max decide like the dense
 *   path's min/max grid, so skipping at tolerance 0 never changes the image.
 * - Threads share image tiles, whose rays walk the bricks in front-to-back order
 *   (ref_bricks.c), so a tile builds each brick it needs once; each thread keeps a few built
 *   bricks (least recently used evicted). Where a render context's cache holds the bricks
 *   (walk_own), each thread walks tiles of its own instead.
 * - A render context (wvol_render_context, context.c) keeps this file's state across frames
 *   (wvol__bricks): the block view and the bounds, the per-brick rates while the TF's kappa
 *   stays the same, and a cache of built bricks shared by the threads within a byte budget.
 *   Every decision (skip, build) depends on the brick, the TF and the ray only, never on what
 *   a cache holds, so a frame's image is the one-shot render's bit for bit.
 * Samples, weights and compositing are the reference's, so on the same voxels the image
 * is the reference's image to float rounding (tests/c/test_render_bricks.c). */
#include "render_internal.h"
#include "store/store_blocks.h"
#include "wavelet/wavelet_bricks.h"

#include <math.h>
#include <omp.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---- the source: bounds, per-thread brick caches ------------------------------------------ */

typedef struct brick_shared brick_shared;

typedef struct brick_src {
    wvol__coef_source cs;
    wvol__store_blocks *blocks;
    wvol__brick_bounds *bounds;   /* NULL: no bound (an untransformed axis) */
    const wvol_tf *tf;            /* world units */
    wvol_render_mode mode;
    size_t n[3], bn[3];
    int B;
    size_t slot_floats;
    int nthreads;
    int skip_inside;              /* wvol_render_params.bricks.skip_inside */
    int grad_drop;                /* wvol_render_params.gradient_levels when shading, else 0 */
    wvol__coef_source low;        /* cs without the details of levels 1..grad_drop */
    double *bound_rate;           /* per brick: wvol__brick_rate of its coefficient bound, < 0 not
                                     yet computed */
    double *voxel_rate;           /* per brick: wvol__brick_rate of its voxels' min/max once any
                                     thread built it (in this frame, or an earlier one of the
                                     context with the same kappa), < 0 not yet */
    float *vmin, *vmax;           /* per brick: its voxels' range once built (NaN: not yet); kept
                                     across TF changes, which recompute voxel_rate from them */
    wvol_tf tf_copy;              /* the TF (world units) the rates are for */
    int tf_known;                 /* tf_copy and mode hold a frame's TF */
    uint64_t tfgen;               /* bumped when the TF's kappa or the mode changes */
    brick_shared *shared;         /* the context's brick cache, or NULL (one-shot) */
    void **tctx;                  /* per thread: its brick_cache, kept across frames */
} brick_src;

/* A built brick kept by a render context across frames, shared by the threads. */
typedef struct shared_entry {
    long id;                      /* brick, or -1 */
    uint64_t frame;               /* the last frame it was taken or put in: a thread's slot refers
                                     only to entries of the current frame, which are not evicted */
    uint64_t tfgen;               /* the TF its rate and sub-cells are for */
    float *data, *gdata;          /* slot_floats each (gdata: grad_drop only) */
    wvol__view view, gview;
    double rate;
} shared_entry;

/* The context's cache: at most cap entries (the byte budget over a brick's bytes). A built
 * brick takes a free entry, else the least recently used one not taken in this frame; when every entry was taken in this frame it stays in the thread's own slot only, so
 * that a frame larger than the cache keeps the part it cached rather than cycling through it
 * (least-recently-used on a repeated sweep would evict each brick before its next use). */
struct brick_shared {
    omp_lock_t lock;
    size_t cap, used;
    shared_entry *ent;
    long *where;                  /* per brick: its entry, or -1 */
    uint64_t frame;
};

/* A thread's brick cache: a few slots (CACHE_SLOTS), found by a scan of their brick numbers,
 * the least recently used evicted. */
typedef struct brick_cache {
    const brick_src *src;
    size_t nslots, nused;
    long *id;                /* per slot: brick index or -1 */
    uint64_t *used;          /* per slot: last use */
    float **data;            /* per slot: slot_floats (NULL: given to the shared cache, allocated
                                again at the slot's next build) */
    float **gdata;           /* per slot: slot_floats of the low-pass field (grad_drop), or NULL */
    wvol__view *gview;       /* per slot: its view */
    double *rate;            /* per slot: wvol__brick_rate of its voxels' min/max */
    wvol__view *view;        /* per slot: the brick's view (its voxels' box, finished) */
    long *entry;             /* per slot: the shared entry it refers to, or -1 */
    const wvol__view **vp;   /* per slot: the view fetch gives (its own, or its entry's) */
    size_t reused;           /* bricks taken from the shared cache */
    float *plane;            /* sub_cells' scratch: plane_floats */
    uint64_t clock;
    wvol__brick_scratch scr;
    size_t built;
} brick_cache;

/* sub_cells' scratch: two planes of a brick's voxels (its range over a z interval of
 * slices) and two rows. */
static size_t plane_floats(const brick_src *src)
{
    const size_t side = (size_t)src->B + 2;
    return 2 * side * side + 2 * side;
}

static void cache_free(brick_cache *c)
{
    if (!c) return;
    for (size_t i = 0; c->data && i < c->nslots; i++) free(c->data[i]);
    for (size_t i = 0; c->gdata && i < c->nslots; i++) free(c->gdata[i]);
    free(c->id);
    free(c->used);
    free(c->entry);
    free(c->vp);
    free(c->data);
    free(c->gdata);
    free(c->gview);
    free(c->rate);
    free(c->view);
    free(c->plane);
    wvol__brick_scratch_free(&c->scr);
    free(c);
}

static brick_cache *cache_new(const brick_src *src, size_t slots)
{
    brick_cache *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->src = src;
    c->nslots = slots;
    c->id = malloc(slots * sizeof *c->id);
    c->used = calloc(slots, sizeof *c->used);
    c->entry = malloc(slots * sizeof *c->entry);
    c->vp = calloc(slots, sizeof *c->vp);
    c->data = calloc(slots, sizeof *c->data);
    c->rate = malloc(slots * sizeof *c->rate);
    c->view = malloc(slots * sizeof *c->view);
    c->plane = malloc(plane_floats(src) * sizeof *c->plane);
    if (src->grad_drop) {
        c->gdata = calloc(slots, sizeof *c->gdata);
        c->gview = malloc(slots * sizeof *c->gview);
    }
    if (!c->id || !c->used || !c->entry || !c->vp || !c->data || !c->rate || !c->view || !c->plane ||
        (src->grad_drop && (!c->gdata || !c->gview))) {
        cache_free(c);
        return NULL;
    }
    for (size_t i = 0; i < slots; i++) c->id[i] = c->entry[i] = -1;
    return c;
}

static size_t cache_bytes(const brick_cache *c)
{
    size_t slots = c->nslots;
    return sizeof *c + slots * ((c->src->grad_drop ? 2 : 1) * (c->src->slot_floats * sizeof(float) + sizeof(wvol__view)) +
                                sizeof(long) + sizeof(uint64_t) + sizeof(double)) +
           plane_floats(c->src) * sizeof(float) + wvol__brick_scratch_bytes(&c->scr);
}

static void brick_box(const brick_src *src, size_t b, long lo[3], long hi[3])
{
    size_t bi[3] = {b % src->bn[0], (b / src->bn[0]) % src->bn[1], b / (src->bn[0] * src->bn[1])};
    for (int a = 0; a < 3; a++) {
        long l = (long)bi[a] * src->B - 1, h = ((long)bi[a] + 1) * src->B;
        lo[a] = l < 0 ? 0 : l;
        hi[a] = h > (long)src->n[a] - 1 ? (long)src->n[a] - 1 : h;
    }
}

/* The smallest and largest of n floats, four lanes at a time (the voxels are finite: the
 * store holds finite coefficients). */
static void voxel_range(const float *d, size_t n, double *mn, double *mx)
{
    size_t i = 0;
    float lo = INFINITY, hi = -INFINITY;
#if defined(__SSE2__)
    if (n >= 4) {
        __m128 vl = _mm_loadu_ps(d), vh = vl;
        for (i = 4; i + 4 <= n; i += 4) {
            __m128 v = _mm_loadu_ps(d + i);
            vl = _mm_min_ps(vl, v);
            vh = _mm_max_ps(vh, v);
        }
        float l4[4], h4[4];
        _mm_storeu_ps(l4, vl);
        _mm_storeu_ps(h4, vh);
        for (int q = 0; q < 4; q++) {
            lo = l4[q] < lo ? l4[q] : lo;
            hi = h4[q] > hi ? h4[q] : hi;
        }
    }
#endif
    for (; i < n; i++) {
        lo = d[i] < lo ? d[i] : lo;
        hi = d[i] > hi ? d[i] : hi;
    }
    *mn = lo;
    *mx = hi;
}

/* Elementwise min and max of n floats of src into lo and hi (plain loops the compiler
 * vectorises: min and max are exact, so any order gives the same values). */
static void fold_minmax(float *restrict lo, float *restrict hi, const float *restrict src, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        lo[i] = src[i] < lo[i] ? src[i] : lo[i];
        hi[i] = src[i] > hi[i] ? src[i] : hi[i];
    }
}

/* lo and hi set to src and its copy. */
static void init_minmax(float *restrict lo, float *restrict hi, const float *restrict src, size_t n)
{
    memcpy(lo, src, n * sizeof *lo);
    memcpy(hi, src, n * sizeof *hi);
}

/* The brick's sub-cells whose kappa is 0 over their voxels' range (wvol__view.sub_zero): the
 * brick's cells cut into WVOL__SUB_N per axis (sub_S = ceil(B / N)), each sub-cell's voxels from one
 * before its first cell to its last cell's upper neighbour, clipped to the brick's voxels. A
 * sub-cell's voxels are a box, the product of one interval per axis, so its range is taken
 * axis by axis: per z interval, the elementwise range of its slices (a plane, whole slices at
 * a time), then per y interval of that plane the elementwise range of its rows, then per x
 * interval of each such row its range. The passes over slices and rows are long runs of
 * independent lanes (vectorised), and each voxel is read about (S + 2) / S times rather than
 * once per window of every axis. Min and max are exact, so the bits are those of the range
 * over each sub-cell's voxels taken in any order. Bricks of fewer than 2N cells per side have
 * none (their own rate decides at that grain). */
static void sub_cells(const brick_src *src, size_t b, wvol__view *v, float *plane)
{
    enum { N = WVOL__SUB_N };
    const int S = (src->B + N - 1) / N;
    size_t bi[3] = {b % src->bn[0], (b / src->bn[0]) % src->bn[1], b / (src->bn[0] * src->bn[1])};
    long m[3], wlo[3][N], whi[3][N];
    memset(v->sub_zero, 0, sizeof v->sub_zero);
    v->sub_any = 0;
    v->sub_S = 0;
    if (src->B < 2 * N) return;
    for (int a = 0; a < 3; a++) {
        long cells = (long)src->n[a] - (long)bi[a] * src->B;
        if (cells > src->B) cells = src->B;
        v->sub_org[a] = (long)bi[a] * src->B;
        m[a] = (cells + S - 1) / S;
        if (m[a] < 1 || m[a] > N) return; /* no cells (not a brick of the grid) */
        for (long c = 0; c < m[a]; c++) { /* sub-cell c's voxels on this axis, relative to the view */
            long lo = v->sub_org[a] + c * S - 1, hi = v->sub_org[a] + (c + 1) * S;
            if (lo < v->lo[a]) lo = v->lo[a];
            if (hi > v->hi[a]) hi = v->hi[a];
            wlo[a][c] = lo - v->off[a];
            whi[a][c] = hi - v->off[a];
        }
    }
    {
        /* the planes hold the rows wlo[1][0] .. whi[1][last] of a slice, whole rows */
        const size_t sy = v->sy, j0 = (size_t)wlo[1][0], rows = (size_t)(whi[1][m[1] - 1] - wlo[1][0] + 1);
        const size_t np = rows * sy;
        float *pmn = plane, *pmx = plane + np, *rmn = plane + 2 * np, *rmx = rmn + sy;
        for (long c2 = 0; c2 < m[2]; c2++) {
            const float *s0 = v->data + v->sz * (size_t)wlo[2][c2] + sy * j0;
            init_minmax(pmn, pmx, s0, np);
            for (long k = wlo[2][c2] + 1; k <= whi[2][c2]; k++) fold_minmax(pmn, pmx, v->data + v->sz * (size_t)k + sy * j0, np);
            for (long c1 = 0; c1 < m[1]; c1++) {
                const size_t r0 = (size_t)wlo[1][c1] - j0;
                memcpy(rmn, pmn + sy * r0, sy * sizeof *rmn);
                memcpy(rmx, pmx + sy * r0, sy * sizeof *rmx);
                for (size_t r = r0 + 1; r <= (size_t)whi[1][c1] - j0; r++) {
                    const float *qn = pmn + sy * r, *qx = pmx + sy * r;
                    for (size_t i = 0; i < sy; i++) {
                        rmn[i] = qn[i] < rmn[i] ? qn[i] : rmn[i];
                        rmx[i] = qx[i] > rmx[i] ? qx[i] : rmx[i];
                    }
                }
                for (long c0 = 0; c0 < m[0]; c0++) {
                    float lo = rmn[wlo[0][c0]], hi = rmx[wlo[0][c0]];
                    for (long i = wlo[0][c0] + 1; i <= whi[0][c0]; i++) {
                        lo = rmn[i] < lo ? rmn[i] : lo;
                        hi = rmx[i] > hi ? rmx[i] : hi;
                    }
                    if (wvol__brick_rate(src->tf, src->mode, lo, hi) == 0) {
                        const long bit = c0 + N * (c1 + N * c2);
                        v->sub_zero[bit >> 6] |= (uint64_t)1 << (bit & 63);
                        v->sub_any = 1;
                    }
                }
            }
        }
    }
    v->sub_S = S;
    v->sub_S_inv = (S & (S - 1)) == 0 ? 1.0 / S : 0.0;
}

/* The brick source's coefficients without the details of levels 1 .. grad_drop: the
 * low-pass approximation the shading's gradient is taken from (gradient_levels). */
static int gather_low(const void *ctx, float *dst, int m, int band, const ptrdiff_t lo[3], const ptrdiff_t n[3])
{
    const brick_src *src = ctx;
    if (band != 0 && m <= src->grad_drop) return 0; /* zero there: the synthesis skips the band */
    return src->cs.gather(src->cs.ctx, dst, m, band, lo, n);
}

/* Brick b's rate on its coefficient bound, computed once per brick (by whichever thread meets
 * it first; two threads may both compute it, with the same result); < 0 without bounds. */
static double bound_rate(const brick_src *src, size_t b)
{
    double known;
    if (!src->bounds) return -1.0;
#pragma omp atomic read
    known = src->bound_rate[b];
    if (known < 0) {
        long lo[3], hi[3];
        double bl, bh;
        brick_box(src, b, lo, hi);
        wvol__bounds_box(src->bounds, lo, hi, &bl, &bh);
        known = wvol__brick_rate(src->tf, src->mode, bl, bh);
#pragma omp atomic write
        src->bound_rate[b] = known;
    }
    return known;
}

/* The smallest rate of brick b known without building it: on its voxels once some thread
 * built it, else on its coefficient bound; -1 when neither is known. 0: fetch skips the
 * brick for every ray. */
static double known_rate(const wvol__source *s, size_t b)
{
    const brick_src *src = s->ctx;
    double r;
#pragma omp atomic read
    r = src->voxel_rate[b];
    if (r >= 0) return r;
    return bound_rate(src, b);
}

/* Slot `slot` of c emptied (its entry, if any, stays in the shared cache). */
static void slot_release(brick_cache *c, size_t slot)
{
    c->entry[slot] = -1;
    c->id[slot] = -1;
}

/* Brick b's sub-cells and rate from its voxels' range for the current TF, on view v. */
static double brick_tf_view(const brick_src *src, size_t b, wvol__view *v, float *plane)
{
    float lo, hi;
    double rate;
    /* atomic, as their writers are: another thread building the same brick may write them
     * (the same values) at the same time */
#pragma omp atomic read
    lo = src->vmin[b];
#pragma omp atomic read
    hi = src->vmax[b];
    rate = wvol__brick_rate(src->tf, src->mode, lo, hi);
    memset(v->sub_zero, 0, sizeof v->sub_zero);
    v->sub_any = 0;
    if (rate > 0 && src->skip_inside) sub_cells(src, b, v, plane); /* rate 0: skipped whole */
    return rate;
}

/* Brick b from the shared cache into slot `slot`: 1, or 0 when not cached. An
 * entry built for another TF gets its rate and sub-cells again (its voxels are the same). */
static int shared_take(brick_cache *c, size_t slot, size_t b)
{
    const brick_src *src = c->src;
    brick_shared *sh = src->shared;
    shared_entry *e;
    long ei;
    omp_set_lock(&sh->lock);
    ei = sh->where[b];
    if (ei < 0) {
        omp_unset_lock(&sh->lock);
        return 0;
    }
    e = &sh->ent[ei];
    e->frame = sh->frame;
    if (e->tfgen != src->tfgen) { /* the first taker in this frame: no other thread reads it yet */
        e->rate = brick_tf_view(src, b, &e->view, c->plane);
        e->tfgen = src->tfgen;
    }
    c->entry[slot] = ei;
    c->id[slot] = (long)b;
    c->rate[slot] = e->rate;
    c->vp[slot] = &e->view;
    c->reused++;
    omp_unset_lock(&sh->lock);
    return 1;
}

/* Brick b, just built into slot `slot`, offered to the shared cache: the slot's buffers go to
 * a free entry or to the least recently used one not taken in this frame (whose buffers the
 * slot takes for its next build), and the slot refers to the entry. Else it stays the slot's. */
static void shared_put(brick_cache *c, size_t slot, size_t b)
{
    const brick_src *src = c->src;
    brick_shared *sh = src->shared;
    shared_entry *e = NULL;
    float *t;
    omp_set_lock(&sh->lock);
    if (sh->where[b] < 0) {
        if (sh->used < sh->cap) {
            e = &sh->ent[sh->used++];
        } else {
            for (size_t i = 0; i < sh->cap; i++) {
                shared_entry *q = &sh->ent[i];
                if (q->frame < sh->frame && (!e || q->frame < e->frame)) e = q;
            }
            if (e && e->id >= 0) sh->where[e->id] = -1;
        }
    }
    if (e) {
        t = e->data, e->data = c->data[slot], c->data[slot] = t;
        e->view = c->view[slot];
        e->view.data = e->data;
        e->view.grad = NULL;
        if (src->grad_drop) {
            t = e->gdata, e->gdata = c->gdata[slot], c->gdata[slot] = t;
            e->gview = c->gview[slot];
            e->gview.data = e->gdata;
            e->view.grad = &e->gview;
        }
        e->id = (long)b;
        e->frame = sh->frame;
        e->tfgen = src->tfgen;
        e->rate = c->rate[slot];
        sh->where[b] = (long)(e - sh->ent);
        c->entry[slot] = sh->where[b];
        c->vp[slot] = &e->view;
    }
    omp_unset_lock(&sh->lock);
}

static wvol_status fetch(const wvol__source *s, void *tctx, size_t b, double allow, const wvol__view **view,
                         double *rate)
{
    brick_cache *c = tctx;
    const brick_src *src = c->src;
    size_t slot;
    long lo[3], hi[3];
    (void)s; /* the thread's cache knows its source */
    {
        /* skipped on the bound alone, else on the voxels' range once some thread built the
         * brick (in this tile, an earlier one, or an earlier frame of the context): no view
         * needed. The decision depends on the brick, the TF and allow only, not on what the
         * caches hold. */
        double known = bound_rate(src, b);
        if (known < 0 || known > allow) {
#pragma omp atomic read
            known = src->voxel_rate[b];
        }
        if (known >= 0 && known <= allow) {
            *rate = known;
            return WVOL_OK;
        }
    }
    c->clock++;
    for (slot = 0; slot < c->nused; slot++)
        if (c->id[slot] == (long)b) goto hit;
    if (c->nused < c->nslots) {
        slot = c->nused++;
    } else { /* the least recently used slot */
        slot = 0;
        for (size_t i = 1; i < c->nslots; i++)
            if (c->used[i] < c->used[slot]) slot = i;
        slot_release(c, slot);
    }
    if (src->shared && shared_take(c, slot, b)) goto hit;
    brick_box(src, b, lo, hi);
    {
        size_t blo[3], bhi[3], cnt;
        float *d;
        double mn = INFINITY, mx = -INFINITY;
        wvol_status st;
        if (!c->data[slot] && !(c->data[slot] = malloc(src->slot_floats * sizeof(float)))) return WVOL_ERR_NOMEM;
        if (src->grad_drop && !c->gdata[slot] && !(c->gdata[slot] = malloc(src->slot_floats * sizeof(float))))
            return WVOL_ERR_NOMEM;
        d = c->data[slot];
        for (int a = 0; a < 3; a++) {
            blo[a] = (size_t)lo[a];
            bhi[a] = (size_t)hi[a] + 1;
        }
        st = wvol__idwt3_brick_src(d, &src->cs, blo, bhi, &c->scr, NULL);
        if (st != WVOL_OK) return st;
        cnt = (bhi[0] - blo[0]) * (bhi[1] - blo[1]) * (bhi[2] - blo[2]);
        voxel_range(d, cnt, &mn, &mx);
#pragma omp atomic write
        src->vmin[b] = (float)mn;
#pragma omp atomic write
        src->vmax[b] = (float)mx;
        {
            wvol__view *v = &c->view[slot];
            v->data = d;
            v->grad = NULL;
            for (int a = 0; a < 3; a++) {
                v->off[a] = v->lo[a] = lo[a];
                v->hi[a] = hi[a];
            }
            v->sy = (size_t)(hi[0] - lo[0] + 1);
            v->sz = v->sy * (size_t)(hi[1] - lo[1] + 1);
            wvol__view_finish(v);
            v->local = 1; /* 1 to 127 cells per axis: block_positions_local (ref_samples.h) */
            for (int a = 0; a < 3; a++) v->local &= hi[a] > lo[a] && hi[a] - lo[a] < 128;
            /* voxels min and max are floats: their rate is the one on (float)mn, (float)mx */
            c->rate[slot] = brick_tf_view(src, b, v, c->plane); /* once per build */
#pragma omp atomic write
            src->voxel_rate[b] = c->rate[slot];
            if (src->grad_drop && c->rate[slot] > 0) { /* the shading's smoother field, same voxels */
                wvol__view *gv = &c->gview[slot];
                st = wvol__idwt3_brick_src(c->gdata[slot], &src->low, blo, bhi, &c->scr, NULL);
                if (st != WVOL_OK) return st;
                *gv = *v;
                gv->data = c->gdata[slot];
                gv->grad = NULL;
                v->grad = gv;
            }
        }
        c->id[slot] = (long)b;
        c->vp[slot] = &c->view[slot];
        c->built++;
        /* a brick with rate 0 is never fetched again under this TF (voxel_rate skips it) */
        if (src->shared && c->rate[slot] > 0) shared_put(c, slot, b);
    }
hit:
    c->used[slot] = c->clock;
    *view = c->vp[slot];
    *rate = c->rate[slot];
    return WVOL_OK;
}

/* Slots of a thread's brick cache. A tile's rays walk brick by brick in front-to-back order
 * (ref_bricks.c), so a brick is needed only while its rays take their runs in it: one slot
 * would do; a few keep the bricks a ray meets out of that order (which the order
 * rules out for a straight walk) from being rebuilt. */
#define CACHE_SLOTS 4

/* Bytes for a tile's rays (ref_tiles.c sizes the tile by it; the threads share the tile): a
 * quarter of the dense volume's size, at least 1 MiB (a 64^2 tile) and at most 64 MiB. Two
 * tiles build the bricks both their beams cross, so a larger tile builds fewer
 * (bench/results/render-tuning.md). */
static size_t walk_bytes(const brick_src *src)
{
    double dense = 4.0 * (double)src->n[0] * (double)src->n[1] * (double)src->n[2];
    double b = dense / 4, lo = (double)(1u << 20), hi = (double)(64u << 20);
    return (size_t)(b < lo ? lo : b > hi ? hi : b);
}

/* Whether the threads walk tiles of their own (wvol__source.walk_own) rather than share each
 * tile: when the context's cache holds the bricks built so far that this TF does not skip
 * (all but at most 1/16 of as many as it holds; at least one held). A shared tile exists so
 * that a brick its rays need is built once, by one thread; with the bricks kept built there
 * is nothing to share, and the shared tile's cost stays: its rays' states move between the
 * threads' caches from brick to brick, and the threads wait for each other where the front
 * of ready bricks is narrow. A brick never built before (a view turned towards new bricks)
 * is built by the thread whose tile needs it and put in the cache for the others (two
 * threads needing it at the same moment may both build it). One-shot renders (no cache)
 * and a context's first frame share tiles. The choice changes no image: each ray's samples
 * are taken in its order either way. */
static int walk_own(const brick_src *src)
{
    const size_t nb = src->bn[0] * src->bn[1] * src->bn[2];
    size_t held = 0, missing = 0;
    if (!src->shared) return 0;
    for (size_t b = 0; b < nb; b++) {
        if (!(src->voxel_rate[b] > 0)) continue; /* not built yet, or skipped whole */
        if (src->shared->where[b] >= 0) held++;
        else missing++;
    }
    return held > 0 && missing * 16 <= held;
}

/* Whether two TFs (world units) give every brick the same rate: the same values and kappas. */
static int same_kappa(const wvol_tf *a, const wvol_tf *b)
{
    if (a->count != b->count) return 0;
    for (int i = 0; i < a->count; i++)
        if (memcmp(&a->points[i].value, &b->points[i].value, sizeof(double)) ||
            memcmp(&a->points[i].opacity, &b->points[i].opacity, sizeof(double)))
            return 0;
    return 1;
}

static wvol_status prepare(wvol__source *s, const wvol_tf *tf_world, const wvol_render_params *p, wvol_error *err)
{
    brick_src *src = s->ctx;
    const size_t nb = src->bn[0] * src->bn[1] * src->bn[2];
    (void)err;
    if (!src->tf_known || src->mode != p->mode || !same_kappa(&src->tf_copy, tf_world)) {
        /* the rates are the TF's: the bound's again on demand, the voxels' from their kept range */
        src->tf_copy = *tf_world;
        src->mode = p->mode;
        src->tf_known = 1;
        src->tfgen++;
        for (size_t b = 0; b < nb; b++) {
            if (src->bound_rate) src->bound_rate[b] = -1.0;
            src->voxel_rate[b] = isnan(src->vmin[b]) ? -1.0 : wvol__brick_rate(&src->tf_copy, src->mode, src->vmin[b], src->vmax[b]);
        }
    } else {
        src->tf_copy = *tf_world; /* colours may differ: the samples read the frame's TF */
    }
    src->tf = &src->tf_copy;
    for (int a = 0; a < 3; a++) s->bn[a] = src->bn[a];
    s->walk_bytes = walk_bytes(src);
    s->walk_own = walk_own(src);
    s->tctx = src->tctx;
    return WVOL_OK;
}

/* Bricks built on demand into the threads' caches, walked tile by tile. */
static const wvol__source_ops bricks_ops = {
    .prepare = prepare, .fetch = fetch, .known_rate = known_rate, .walk_bricks = 1, .lowpass_gradient = 1};

/* ---- the state kept across frames (wvol__bricks) ----------------------------------------- */

struct wvol__bricks {
    const wvol_store *store;
    brick_src src;
    int threads, brick, skip_inside, grad_drop; /* the settings it was made for */
    uint64_t frames;
    double pending_wall, pending_cpu;           /* the set-up's time, added to the next frame's */
};

static size_t brick_count(const brick_src *src)
{
    return src->bn[0] * src->bn[1] * src->bn[2];
}

static void shared_free(brick_shared *sh)
{
    if (!sh) return;
    for (size_t i = 0; i < sh->cap; i++) {
        free(sh->ent[i].data);
        free(sh->ent[i].gdata);
    }
    free(sh->ent);
    free(sh->where);
    omp_destroy_lock(&sh->lock);
    free(sh);
}

void wvol__bricks_destroy(wvol__bricks *b)
{
    if (!b) return;
    if (b->src.tctx) {
        for (int t = 0; t < b->src.nthreads; t++) cache_free(b->src.tctx[t]);
        free(b->src.tctx);
    }
    shared_free(b->src.shared);
    wvol__store_blocks_destroy(b->src.blocks);
    wvol__bounds_free(b->src.bounds);
    free(b->src.bound_rate);
    free(b->src.voxel_rate);
    free(b->src.vmin);
    free(b->src.vmax);
    free(b);
}

/* A rate per brick of the grid bn, each -1 (not yet known); NULL when out of memory. */
static double *rates_unknown(const size_t bn[3])
{
    const size_t nb = bn[0] * bn[1] * bn[2];
    double *r = malloc(nb * sizeof *r);
    if (r)
        for (size_t i = 0; i < nb; i++) r[i] = -1.0;
    return r;
}

/* Bytes of one shared entry: the brick's voxels (and its low-pass field's). */
static size_t entry_bytes(const brick_src *src)
{
    return (src->grad_drop ? 2 : 1) * src->slot_floats * sizeof(float);
}

static int grad_drop_of(const wvol_render_params *p)
{
    return p->shading && p->gradient_levels > 0 ? p->gradient_levels : 0;
}

static int brick_side_of(const wvol_render_params *p)
{
    return p->bricks.brick > 0 ? p->bricks.brick : WVOL__BRICKS_BRICK_DEFAULT;
}

wvol_status wvol__bricks_create(wvol__bricks **out, const wvol_store *st, const wvol_render_params *params,
                                size_t cache_bytes, wvol_error *err)
{
    wvol_render_params p;
    wvol_store_info info;
    wvol__bricks *b;
    brick_src *src;
    wvol_status status;
    double t0 = wvol__now(), c0 = wvol__cpu_now();
    *out = NULL;
    WVOL_RETURN_IF(!st, err, WVOL_ERR_ARG, "render: no store");
    wvol__params(&p, params);
    b = calloc(1, sizeof *b);
    WVOL_RETURN_IF(!b, err, WVOL_ERR_NOMEM, "render: out of memory");
    src = &b->src;
    wvol_store_get_info(st, &info);
    b->store = st;
    src->n[0] = info.nx, src->n[1] = info.ny, src->n[2] = info.nz;
    b->threads = p.threads;
    src->nthreads = wvol__threads(p.threads);
    b->brick = src->B = brick_side_of(&p);
    b->skip_inside = src->skip_inside = p.bricks.skip_inside;
    for (int a = 0; a < 3; a++) src->bn[a] = (src->n[a] + (size_t)src->B - 1) / (size_t)src->B;
    src->slot_floats = (size_t)(src->B + 2) * (size_t)(src->B + 2) * (size_t)(src->B + 2);
    status = wvol__store_blocks_create(&src->blocks, &src->bounds, st, src->nthreads, err);
    if (status != WVOL_OK) goto fail;
    wvol__store_blocks_source(&src->cs, src->blocks);
    b->grad_drop = grad_drop_of(&p);
    if (b->grad_drop) {
        if (b->grad_drop > src->cs.levels) {
            status = wvol_error_set(err, WVOL_ERR_ARG, "render: gradient_levels %d, but the store has %d levels",
                                    p.gradient_levels, src->cs.levels);
            goto fail;
        }
        src->grad_drop = b->grad_drop;
        src->low = src->cs;
        src->low.gather = gather_low;
        src->low.ctx = src;
    }
    {
        const size_t nb = brick_count(src);
        src->voxel_rate = rates_unknown(src->bn);
        if (src->bounds) src->bound_rate = rates_unknown(src->bn);
        src->vmin = malloc(nb * sizeof *src->vmin);
        src->vmax = malloc(nb * sizeof *src->vmax);
        src->tctx = calloc((size_t)src->nthreads, sizeof *src->tctx);
        if (!src->voxel_rate || (src->bounds && !src->bound_rate) || !src->vmin || !src->vmax || !src->tctx) {
            status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the brick rates");
            goto fail;
        }
        for (size_t i = 0; i < nb; i++) src->vmin[i] = src->vmax[i] = NAN;
    }
    for (int t = 0; t < src->nthreads; t++) {
        src->tctx[t] = cache_new(src, CACHE_SLOTS);
        if (!src->tctx[t]) {
            status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the brick caches");
            goto fail;
        }
    }
    if (cache_bytes / entry_bytes(src) > 0) {
        const size_t nb = brick_count(src);
        brick_shared *sh = calloc(1, sizeof *sh);
        if (sh) {
            omp_init_lock(&sh->lock);
            sh->cap = cache_bytes / entry_bytes(src);
            if (sh->cap > nb) sh->cap = nb;
            sh->ent = calloc(sh->cap, sizeof *sh->ent);
            sh->where = malloc(nb * sizeof *sh->where);
            src->shared = sh; /* freed with b from here on */
        }
        if (!sh || !sh->ent || !sh->where) {
            status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the context's brick cache");
            goto fail;
        }
        for (size_t i = 0; i < sh->cap; i++) sh->ent[i].id = -1;
        for (size_t i = 0; i < nb; i++) sh->where[i] = -1;
    }
    b->pending_wall = wvol__now() - t0;
    b->pending_cpu = wvol__cpu_now() - c0;
    *out = b;
    return WVOL_OK;
fail:
    wvol__bricks_destroy(b);
    return status;
}

int wvol__bricks_fits(const wvol__bricks *b, const wvol_store *st, const wvol_render_params *params)
{
    wvol_render_params p;
    wvol__params(&p, params);
    return b && b->store == st && b->threads == p.threads && b->brick == brick_side_of(&p) &&
           b->skip_inside == p.bricks.skip_inside && b->grad_drop == grad_drop_of(&p);
}

size_t wvol__bricks_bytes(const wvol__bricks *b)
{
    const brick_src *src = &b->src;
    const size_t nb = brick_count(src);
    size_t bytes = wvol__store_blocks_bytes(src->blocks) + wvol__bounds_bytes(src->bounds) +
                   (size_t)src->nthreads * sizeof(void *) + (src->bound_rate ? nb * sizeof *src->bound_rate : 0) +
                   nb * (sizeof *src->voxel_rate + sizeof *src->vmin + sizeof *src->vmax);
    for (int t = 0; t < src->nthreads; t++) bytes += cache_bytes(src->tctx[t]);
    if (src->shared)
        bytes += sizeof *src->shared + src->shared->cap * sizeof *src->shared->ent + nb * sizeof *src->shared->where +
                 src->shared->used * entry_bytes(src);
    return bytes;
}

size_t wvol__bricks_cache_bytes(const wvol__bricks *b)
{
    return b->src.shared ? b->src.shared->used * entry_bytes(&b->src) : 0;
}

wvol_status wvol__bricks_frame(wvol__bricks *b, wvol_image *img, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_store_info info;
    wvol__source s;
    brick_src *src = &b->src;
    wvol_status status;
    size_t built = 0, reused = 0, bound_skipped = 0;
    const uint64_t tfgen = src->tfgen;
    double t0 = wvol__now(), c0 = wvol__cpu_now();
    wvol__params(&p, params);
    WVOL_FORWARD(wvol__render_check(img, cam, tf, &p, err));
    WVOL_RETURN_IF(!wvol__bricks_fits(b, b->store, &p), err, WVOL_ERR_ARG,
                   "render: the bricked state was made for other settings (threads, brick, shading's levels)");
    wvol_store_get_info(b->store, &info);
    memset(&s, 0, sizeof s);
    for (int a = 0; a < 3; a++) {
        s.n[a] = src->n[a];
        s.spacing[a] = info.spacing[a];
        s.origin[a] = info.origin[a];
    }
    s.ops = &bricks_ops;
    s.ctx = src;
    s.B = src->B;
    b->frames++;
    if (src->shared) src->shared->frame = b->frames;
    for (int t = 0; t < src->nthreads; t++) {
        brick_cache *c = src->tctx[t];
        c->built = c->reused = 0;
    }
    status = wvol__render_sampled(img, &s, cam, tf, &p, stats, err);
    for (int t = 0; t < src->nthreads; t++) {
        /* the slots' views carry this TF's sub-cells, and their entries may be evicted in the
         * next frame: emptied (a next frame takes them from the shared cache again, which
         * refreshes what a TF change made stale) */
        brick_cache *c = src->tctx[t];
        for (size_t i = 0; i < c->nused; i++) slot_release(c, i);
        c->nused = 0;
        built += c->built;
        reused += c->reused;
    }
    if (src->bound_rate)
        for (size_t i = 0; i < brick_count(src); i++) bound_skipped += src->bound_rate[i] == 0;
    if (status == WVOL_OK && stats) {
        /* the whole frame: a first frame's set-up (the view and the bounds) included */
        stats->brick = src->B;
        stats->seconds = wvol__now() - t0 + b->pending_wall;
        stats->cpu_seconds = wvol__cpu_now() - c0 + b->pending_cpu;
        stats->bricks_built = built;
        stats->bricks_reused = reused;
        stats->bricks_bound_skipped = bound_skipped;
        stats->context_frame = (int)b->frames;
        stats->rates_reused = b->frames > 1 && src->tfgen == tfgen;
        stats->cache_bytes = wvol__bricks_cache_bytes(b);
        stats->bytes += wvol__bricks_bytes(b); /* beside the walk's own */
    }
    b->pending_wall = b->pending_cpu = 0;
    return status;
}

wvol_status wvol_render_bricks(wvol_image *img, const wvol_store *st, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol__bricks *b = NULL;
    wvol_render_params p;
    wvol_status status;
    WVOL_RETURN_IF(!st, err, WVOL_ERR_ARG, "render: no store");
    wvol__params(&p, params);
    WVOL_FORWARD(wvol__render_check(img, cam, tf, &p, err));
    WVOL_FORWARD(wvol__bricks_create(&b, st, &p, 0, err));
    status = wvol__bricks_frame(b, img, cam, tf, &p, stats, err);
    if (status == WVOL_OK && stats) stats->context_frame = 0; /* one-shot */
    wvol__bricks_destroy(b);
    return status;
}
