/* SPDX-License-Identifier: MIT
 * The bricked renderer: the reference integrator (trilinear samples, front-to-back, early
 * termination; reference.c) reading its samples from bricks reconstructed on demand from a
 * store, never from the dense volume.
 *
 * - A block-sparse view of the store's coefficients: per (level, band) a directory of
 *   blocks of 4^3 coefficient positions, a block present only where a kept coefficient
 *   lies: a 64-bit mask of its kept positions and the offset of its values, stored
 *   compactly (rank of a position = popcount of the mask below it). Built in two passes
 *   over the kept coefficients: 4 bytes per kept coefficient, 12 per present block, 4 per
 *   directory entry (1/64 of the bands' size). The low-pass cube is read from the store.
 * - Bricks of B^3 voxel cells (render_internal.h): a brick's voxels b B - 1 .. (b + 1) B are
 *   reconstructed by a local inverse transform (wvol__idwt3_brick_src) that gathers its
 *   coefficients through the view and skips every band that is zero there.
 * - Before reconstructing, a brick's samples are bounded from the coefficients alone
 *   (wavelet/bounds.c, the bound the bricked isosurface uses); when the brick's rate on
 *   the bound (kappa 0 over it, or within the ray's skip tolerance) lets the ray skip it, it
 *   is not reconstructed. After reconstruction its actual min/max decide like the dense
 *   path's min/max grid, so skipping at tolerance 0 never changes the image.
 * - Threads take image tiles, whose rays walk the bricks in front-to-back order (reference.c,
 *   render_tile_bricked), so a tile builds each brick it needs once; each thread keeps a few built
 *   bricks (least recently used evicted).
 * Samples, weights and compositing are the reference's, so on the same voxels the image
 * is the reference's image to float rounding (tests/c/test_render_bricks.c). */
#include "render_internal.h"
#include "core/clones.h"
#include "store/store_internal.h"
#include "wavelet/wavelet_internal.h"

#include <math.h>
#include <omp.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define CB_SHIFT 2 /* blocks of 4^3 = 64 coefficient positions: one 64-bit mask */
#define CB (1 << CB_SHIFT)

typedef struct cblock {
    uint64_t mask;     /* bit x + 4 y + 16 z: position kept */
    uint32_t first;    /* index of its first value in the values array */
} cblock;

/* ---- block-sparse view of the kept coefficients ---------------------------------------- */

typedef struct band_view {
    size_t e[3];       /* band extent */
    size_t nb[3];      /* blocks per axis */
    uint32_t *dir;     /* nb0 nb1 nb2: 1 + block number in the pool, 0 = no kept coefficient */
} band_view;

typedef struct coef_blocks {
    int M;
    band_view bv[WVOL_SELECT_MAX_LEVELS + 1][8];
    cblock *blocks;    /* nblocks; directory entries index it + 1 */
    float *values;     /* nvalues, block by block, position order within a block */
    size_t nblocks, nvalues;
    const float *low;  /* the store's low-pass cube, E0 E1 E2 */
    size_t E[3];
    size_t bytes;
} coef_blocks;

static void blocks_free(coef_blocks *cb)
{
    for (int m = 0; m <= WVOL_SELECT_MAX_LEVELS; m++)
        for (int l = 0; l < 8; l++) free(cb->bv[m][l].dir);
    free(cb->blocks);
    free(cb->values);
}

/* The store's nodes hold a position and the bands kept there (store_internal.h): a node's
 * block and bit, the same in each of its level's bands (whose extents agree), are found once
 * for its up to 7 coefficients. (Through wvol_store_next, which decodes the key again for
 * each coefficient, the two passes and the bounds took 56 ms for the 838861 coefficients of a
 * 5% store of a 256^3 volume: a tenth of a 512^2 frame.) */
static inline size_t node_block(const coef_blocks *cb, const wvol__node *nd, int *m, int *bit)
{
    size_t pos[3];
    const band_view *bv;
    *m = wvol__key_level(nd->key);
    wvol__key_pos(nd->key, pos);
    bv = &cb->bv[*m][nd->band_mask ? __builtin_ctz(nd->band_mask) + 1 : 1];
    *bit = (int)((pos[0] & (CB - 1)) + CB * ((pos[1] & (CB - 1)) + CB * (pos[2] & (CB - 1))));
    return (pos[0] >> CB_SHIFT) + bv->nb[0] * ((pos[1] >> CB_SHIFT) + bv->nb[1] * (pos[2] >> CB_SHIFT));
}

/* Builds the view; when bb is not NULL, also feeds every kept detail coefficient to the
 * brick bounds (one pass over the store serves both). Cloned: a value's rank in its block is
 * a population count, an instruction on x86-64-v3 and a library call on the baseline. */
WVOL__CLONES static wvol_status blocks_build(coef_blocks *cb, const wvol_store *s, wvol__brick_bounds *bb,
                                             wvol_error *err)
{
    wvol_store_info info;
    size_t pad[3];
    int a, m, l;
    wvol_store_get_info(s, &info);
    memset(cb, 0, sizeof *cb);
    cb->M = info.levels;
    cb->low = wvol_store_lowpass(s);
    for (a = 0; a < 3; a++) cb->E[a] = info.lowpass[a];
    pad[0] = info.px, pad[1] = info.py, pad[2] = info.pz;
    for (m = 1; m <= cb->M; m++)
        for (l = 1; l < 8; l++) {
            band_view *bv = &cb->bv[m][l];
            size_t n = 1;
            for (a = 0; a < 3; a++) {
                bv->e[a] = wvol__extent(pad[a], m);
                bv->nb[a] = (bv->e[a] + CB - 1) >> CB_SHIFT;
                n *= bv->nb[a];
                if (((l >> a) & 1) && pad[a] == 1) n = 0; /* no high-pass on an untransformed axis */
            }
            if (!n) continue;
            bv->dir = calloc(n, sizeof *bv->dir);
            WVOL_RETURN_IF(!bv->dir, err, WVOL_ERR_NOMEM, "render: out of memory for the coefficient blocks");
            cb->bytes += n * sizeof *bv->dir;
        }
    /* pass 1: the blocks and their masks; the blocks grow by doubling */
    {
        size_t cap = 0;
        for (size_t k = 0; k < s->nnodes; k++) {
            const wvol__node *nd = &s->nodes[k];
            int bit;
            size_t i = node_block(cb, nd, &m, &bit);
            for (unsigned bands = nd->band_mask; bands; bands &= bands - 1) {
                band_view *bv = &cb->bv[m][__builtin_ctz(bands) + 1];
                if (!bv->dir[i]) {
                    if (cb->nblocks == cap) {
                        size_t nc = cap ? 2 * cap : 1024;
                        cblock *nb = realloc(cb->blocks, nc * sizeof *nb);
                        WVOL_RETURN_IF(!nb || nc >= UINT32_MAX, err, WVOL_ERR_NOMEM,
                                       "render: out of memory for the coefficient blocks");
                        cb->blocks = nb;
                        cap = nc;
                    }
                    cb->blocks[cb->nblocks].mask = 0;
                    bv->dir[i] = (uint32_t)++cb->nblocks;
                }
                cb->blocks[bv->dir[i] - 1].mask |= (uint64_t)1 << bit;
            }
        }
        cb->bytes += cap * sizeof *cb->blocks;
    }
    for (size_t i = 0; i < cb->nblocks; i++) {
        cb->blocks[i].first = (uint32_t)cb->nvalues;
        cb->nvalues += (size_t)__builtin_popcountll(cb->blocks[i].mask);
    }
    cb->values = malloc((cb->nvalues + 1) * sizeof *cb->values);
    WVOL_RETURN_IF(!cb->values, err, WVOL_ERR_NOMEM, "render: out of memory for %zu coefficients", cb->nvalues);
    cb->bytes += cb->nvalues * sizeof *cb->values;
    /* pass 2: the values, each at its rank within its block; the bounds */
    for (size_t k = 0; k < s->nnodes; k++) {
        const wvol__node *nd = &s->nodes[k];
        const float *v = s->values + nd->coef_first;
        int bit;
        size_t i = node_block(cb, nd, &m, &bit);
        const uint64_t below = ((uint64_t)1 << bit) - 1;
        for (unsigned bands = nd->band_mask; bands; bands &= bands - 1, v++) {
            const int band = __builtin_ctz(bands) + 1;
            const cblock *b = &cb->blocks[cb->bv[m][band].dir[i] - 1];
            cb->values[b->first + (size_t)__builtin_popcountll(b->mask & below)] = *v;
            if (bb) {
                size_t pos[3];
                wvol__key_pos(nd->key, pos);
                wvol__bounds_add(bb, m, band, pos[0], pos[1], pos[2], *v);
            }
        }
    }
    return WVOL_OK;
}

static inline size_t wrap(ptrdiff_t k, size_t e)
{
    ptrdiff_t r = k % (ptrdiff_t)e;
    return (size_t)(r < 0 ? r + (ptrdiff_t)e : r);
}

/* From position pos (wrapped into the extent e) the step to the next block: to the end of
 * pos's block, or to the wrap if that comes first. */
static ptrdiff_t next_block_step(size_t pos, size_t e)
{
    size_t step = CB - (pos & (CB - 1));
    return (ptrdiff_t)(step < e - pos ? step : e - pos);
}

/* The kept positions of a 4^3 block (bit x + 4 y + 16 z) inside the box [x0, x0 + rx) x
 * [y0, y0 + ry) x [z0, z0 + rz) of block-local positions (a row's bits repeated over the rows
 * and planes by a multiplication: the copies never overlap, so nothing carries). */
static inline uint64_t piece_bits(size_t x0, size_t rx, size_t y0, size_t ry, size_t z0, size_t rz)
{
    const uint64_t row = (((uint64_t)1 << rx) - 1) << x0;
    const uint64_t rows = ((((uint64_t)1 << (4 * ry)) - 1) / 0xf) << (4 * y0); /* 0x1111.. */
    const uint64_t planes = ((rz == 4 ? ~(uint64_t)0 : ((uint64_t)1 << (16 * rz)) - 1) / 0xffff) << (16 * z0);
    return row * rows * planes;
}

/* A band's region (lo, n), taken periodically, from the view: the region is cut where a
 * block or the period ends into pieces that each lie in one block (next_block_step); a
 * present block's kept positions inside its piece are written. dst is zeroed at the first
 * present block; 0 when there is none (dst untouched: the caller skips the band). The work
 * follows the directory entries and the kept positions, not the region's positions: at 5%
 * a brick's finest-level region meets a hundred or so entries, most of them absent. (Row by
 * row, the zeroing and the lookups of every row took as long as the synthesis.) The wrapped
 * positions are stepped, one division per axis. Cloned: a value's rank in its block is a
 * population count. */
WVOL__CLONES static int gather_sparse(const coef_blocks *cb, const band_view *bv, float *dst, const ptrdiff_t lo[3],
                                      const ptrdiff_t n[3])
{
    const size_t sy = (size_t)n[0], sz = (size_t)(n[0] * n[1]);
    const size_t x0 = wrap(lo[0], bv->e[0]);
    size_t z = wrap(lo[2], bv->e[2]);
    int any = 0;
    for (ptrdiff_t k = 0; k < n[2];) {
        const size_t bz = z & (CB - 1);
        ptrdiff_t rz = next_block_step(z, bv->e[2]);
        size_t y = wrap(lo[1], bv->e[1]);
        if (rz > n[2] - k) rz = n[2] - k;
        for (ptrdiff_t j = 0; j < n[1];) {
            const size_t by = y & (CB - 1);
            ptrdiff_t ry = next_block_step(y, bv->e[1]);
            if (ry > n[1] - j) ry = n[1] - j;
            const uint32_t *drow = bv->dir + bv->nb[0] * ((y >> CB_SHIFT) + bv->nb[1] * (z >> CB_SHIFT));
            const uint64_t in_yz = piece_bits(0, CB, by, (size_t)ry, bz, (size_t)rz);
            float *const plane = dst + sy * (size_t)j + sz * (size_t)k;
            size_t x = x0;
            for (ptrdiff_t i = 0; i < n[0];) {
                const size_t bx = x & (CB - 1);
                ptrdiff_t rx = next_block_step(x, bv->e[0]);
                const uint32_t blk = drow[x >> CB_SHIFT];
                if (rx > n[0] - i) rx = n[0] - i;
                if (blk) {
                    const cblock *b = &cb->blocks[blk - 1];
                    const uint64_t take = b->mask & in_yz & (((((uint64_t)1 << rx) - 1) << bx) * 0x1111111111111111ull);
                    /* the piece's first position, and a kept bit's offset from it */
                    float *const base = plane + i - (ptrdiff_t)bx - (ptrdiff_t)(sy * by) - (ptrdiff_t)(sz * bz);
                    const float *vals = cb->values + b->first;
                    if (take && !any) {
                        memset(dst, 0, (size_t)n[2] * sz * sizeof *dst);
                        any = 1;
                    }
                    if (take == b->mask) { /* every kept position in the piece: the values in order */
                        for (uint64_t bits = take; bits; bits &= bits - 1, vals++) {
                            const int bit = __builtin_ctzll(bits);
                            base[(bit & 3) + sy * ((bit >> 2) & 3) + sz * (bit >> 4)] = *vals;
                        }
                    } else { /* each value found by its rank */
                        for (uint64_t bits = take; bits; bits &= bits - 1) {
                            const int bit = __builtin_ctzll(bits);
                            base[(bit & 3) + sy * ((bit >> 2) & 3) + sz * (bit >> 4)] =
                                vals[__builtin_popcountll(b->mask & (((uint64_t)1 << bit) - 1))];
                        }
                    }
                }
                i += rx;
                x += (size_t)rx;
                if (x == bv->e[0]) x = 0;
            }
            j += ry;
            y += (size_t)ry;
            if (y == bv->e[1]) y = 0;
        }
        k += rz;
        z += (size_t)rz;
        if (z == bv->e[2]) z = 0;
    }
    return any;
}

/* wvol__coef_source gather through the view: the low-pass cube read densely, a detail band
 * through its blocks (gather_sparse). */
static int gather_blocks(const void *ctx, float *dst, int m, int band, const ptrdiff_t lo[3],
                         const ptrdiff_t n[3])
{
    const coef_blocks *cb = ctx;
    size_t t = 0;
    if (m == cb->M && band == 0) {
        for (ptrdiff_t k = 0; k < n[2]; k++) {
            size_t z = wrap(lo[2] + k, cb->E[2]);
            for (ptrdiff_t j = 0; j < n[1]; j++) {
                const float *row = cb->low + cb->E[0] * (wrap(lo[1] + j, cb->E[1]) + cb->E[1] * z);
                size_t x = wrap(lo[0], cb->E[0]);
                for (ptrdiff_t i = 0; i < n[0]; i++) {
                    dst[t++] = row[x];
                    if (++x == cb->E[0]) x = 0;
                }
            }
        }
        return 1;
    }
    const band_view *bv = &cb->bv[m][band];
    return bv->dir ? gather_sparse(cb, bv, dst, lo, n) : 0; /* 0: all zero, the caller skips the band */
}

/* ---- the source: bounds, per-thread brick caches ------------------------------------------ */

typedef struct brick_src {
    wvol__coef_source cs;
    coef_blocks blocks;
    wvol__brick_bounds *bounds;   /* NULL: no bound (an untransformed axis) */
    const wvol_tf *tf;            /* world units */
    wvol_render_mode mode;
    size_t n[3], bn[3];
    int B;
    size_t slot_floats;
    int nthreads;
    double *bound_rate;           /* per brick: wvol__brick_rate of its coefficient bound, < 0 not
                                     yet computed */
} brick_src;

/* A thread's brick cache: a few slots (CACHE_SLOTS), found by a scan of their brick numbers,
 * the least recently used evicted. (While tiles' rays walked one run each per round it was a
 * cache of hundreds of slots with a hashed index.) */
typedef struct brick_cache {
    const brick_src *src;
    size_t nslots, nused;
    long *id;                /* per slot: brick index or -1 */
    uint64_t *used;          /* per slot: last use */
    float *data;             /* per slot: slot_floats */
    double *rate;            /* per slot: wvol__brick_rate of its voxels' min/max */
    wvol__view *view;        /* per slot: the brick's view (its voxels' box, finished) */
    uint64_t clock;
    wvol__brick_scratch scr;
    size_t built;
} brick_cache;

static void cache_free(brick_cache *c)
{
    if (!c) return;
    free(c->id);
    free(c->used);
    free(c->data);
    free(c->rate);
    free(c->view);
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
    c->data = malloc(slots * src->slot_floats * sizeof *c->data);
    c->rate = malloc(slots * sizeof *c->rate);
    c->view = malloc(slots * sizeof *c->view);
    if (!c->id || !c->used || !c->data || !c->rate || !c->view) {
        cache_free(c);
        return NULL;
    }
    for (size_t i = 0; i < slots; i++) c->id[i] = -1;
    return c;
}

static size_t cache_bytes(const brick_cache *c)
{
    size_t slots = c->nslots;
    return sizeof *c + slots * (c->src->slot_floats * sizeof(float) + sizeof(long) + sizeof(uint64_t) +
                                sizeof(double) + sizeof(wvol__view)) +
           wvol__brick_scratch_bytes(&c->scr);
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

static wvol_status fetch(void *tctx, size_t b, double allow, const wvol__view **view, double *rate)
{
    brick_cache *c = tctx;
    const brick_src *src = c->src;
    size_t slot;
    long lo[3], hi[3];
    c->clock++;
    for (slot = 0; slot < c->nused; slot++)
        if (c->id[slot] == (long)b) goto hit;
    brick_box(src, b, lo, hi);
    if (src->bounds) {
        /* the bound is computed once per brick (by whichever thread meets it first; two
         * threads may both compute it, with the same result) */
        double known;
#pragma omp atomic read
        known = src->bound_rate[b];
        if (known < 0) {
            double bl, bh;
            wvol__bounds_box(src->bounds, lo, hi, &bl, &bh);
            known = wvol__brick_rate(src->tf, src->mode, bl, bh);
#pragma omp atomic write
            src->bound_rate[b] = known;
        }
        if (known <= allow) { /* skipped on the bound alone: no view needed */
            *rate = known;
            return WVOL_OK;
        }
    }
    {
        size_t blo[3], bhi[3], cnt, i;
        float *d;
        double mn = INFINITY, mx = -INFINITY;
        wvol_status st;
        if (c->nused < c->nslots) {
            slot = c->nused++;
        } else { /* the least recently used slot */
            slot = 0;
            for (i = 1; i < c->nslots; i++)
                if (c->used[i] < c->used[slot]) slot = i;
            c->id[slot] = -1;
        }
        d = c->data + slot * src->slot_floats;
        for (int a = 0; a < 3; a++) {
            blo[a] = (size_t)lo[a];
            bhi[a] = (size_t)hi[a] + 1;
        }
        st = wvol__idwt3_brick_src(d, &src->cs, blo, bhi, &c->scr, NULL);
        if (st != WVOL_OK) return st;
        cnt = (bhi[0] - blo[0]) * (bhi[1] - blo[1]) * (bhi[2] - blo[2]);
        voxel_range(d, cnt, &mn, &mx);
        c->id[slot] = (long)b;
        c->rate[slot] = wvol__brick_rate(src->tf, src->mode, mn, mx); /* once per build */
        {
            wvol__view *v = &c->view[slot];
            v->data = d;
            for (int a = 0; a < 3; a++) {
                v->off[a] = v->lo[a] = lo[a];
                v->hi[a] = hi[a];
            }
            v->sy = (size_t)(hi[0] - lo[0] + 1);
            v->sz = v->sy * (size_t)(hi[1] - lo[1] + 1);
            wvol__view_finish(v);
            v->local = 1; /* 1 to 127 cells per axis: block_positions_local (reference.c) */
            for (int a = 0; a < 3; a++) v->local &= hi[a] > lo[a] && hi[a] - lo[a] < 128;
        }
        c->built++;
    }
hit:
    c->used[slot] = c->clock;
    *view = &c->view[slot];
    *rate = c->rate[slot];
    return WVOL_OK;
}

/* Slots of a thread's brick cache. A tile's rays walk brick by brick in front-to-back order
 * (reference.c, render_tile_bricked), so a brick is needed only while its rays take their runs in it:
 * one slot would do; a few keep the bricks a ray meets out of that order (which the order
 * rules out for a straight walk) from being rebuilt. */
#define CACHE_SLOTS 4

/* Bytes for a tile's rays (reference.c sizes the tile by it; the threads share the tile): a
 * quarter of the dense volume's size, at least 1 MiB (a 64^2 tile) and at most 64 MiB. Two
 * tiles build the bricks both their beams cross, so a larger tile builds fewer: 512^2
 * perspective frame `dir=1,0.7,0.4` of the 256^3 skull at 5% (391 bricks of 32^3 needed):
 * 128^2 tiles 712 builds, 256^2 561, one 512^2 tile 391. At 256^3 this grants 16 MiB: 256^2
 * tiles. */
static size_t walk_bytes(const brick_src *src)
{
    double dense = 4.0 * (double)src->n[0] * (double)src->n[1] * (double)src->n[2];
    double b = dense / 4, lo = (double)(1u << 20), hi = (double)(64u << 20);
    return (size_t)(b < lo ? lo : b > hi ? hi : b);
}

static wvol_status prepare(wvol__sampler *s, const wvol_tf *tf_world, const wvol_render_params *p, wvol_error *err)
{
    brick_src *src = s->src;
    int a;
    src->tf = tf_world;
    src->mode = p->mode;
    s->B = src->B;
    for (a = 0; a < 3; a++) s->bn[a] = src->bn[a];
    s->walk_bytes = walk_bytes(src);
    s->tctx = calloc((size_t)src->nthreads, sizeof *s->tctx);
    WVOL_RETURN_IF(!s->tctx, err, WVOL_ERR_NOMEM, "render: out of memory");
    for (int t = 0; t < src->nthreads; t++) {
        s->tctx[t] = cache_new(src, CACHE_SLOTS);
        WVOL_RETURN_IF(!s->tctx[t], err, WVOL_ERR_NOMEM, "render: out of memory for the brick caches");
    }
    return WVOL_OK;
}

wvol_status wvol_render_bricks(wvol_image *img, const wvol_store *st, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_store_info info;
    wvol__sampler s;
    brick_src src;
    wvol_status status;
    size_t pad[3], bytes = 0, built = 0, bound_skipped = 0;
    double t0 = wvol__now(), c0 = wvol__cpu_now();
    int a;
    WVOL_RETURN_IF(!st, err, WVOL_ERR_ARG, "render: no store");
    wvol__params(&p, params);
    WVOL_FORWARD(wvol__render_check(img, cam, tf, &p, err));
    wvol_store_get_info(st, &info);
    memset(&s, 0, sizeof s);
    memset(&src, 0, sizeof src);
    src.n[0] = info.nx, src.n[1] = info.ny, src.n[2] = info.nz;
    src.nthreads = wvol__threads(p.threads);
    src.B = p.bricks.brick > 0 ? p.bricks.brick : WVOL__BRICKS_BRICK_DEFAULT;
    pad[0] = info.px, pad[1] = info.py, pad[2] = info.pz;
    for (a = 0; a < 3; a++) {
        src.bn[a] = (src.n[a] + (size_t)src.B - 1) / (size_t)src.B;
        s.n[a] = src.n[a];
        s.spacing[a] = info.spacing[a];
        s.origin[a] = info.origin[a];
    }
    src.slot_floats = (size_t)(src.B + 2) * (size_t)(src.B + 2) * (size_t)(src.B + 2);
    /* the bound needs every axis transformed; without it every brick is reconstructed */
    if (pad[0] > 1 && pad[1] > 1 && pad[2] > 1 && info.levels >= 1) {
        const float *low = wvol_store_lowpass(st);
        WVOL_FORWARD(wvol__bounds_create(&src.bounds, info.filter, info.levels, pad, low, info.lowpass[0],
                                         info.lowpass[0] * info.lowpass[1], err));
    }
    if (src.bounds) {
        size_t nb = src.bn[0] * src.bn[1] * src.bn[2];
        src.bound_rate = malloc(nb * sizeof *src.bound_rate);
        if (!src.bound_rate) {
            status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the brick bounds");
            goto done;
        }
        for (size_t i = 0; i < nb; i++) src.bound_rate[i] = -1.0;
    }
    status = blocks_build(&src.blocks, st, src.bounds, err);
    if (status != WVOL_OK) goto done;
    if (src.bounds) wvol__bounds_finish(src.bounds);
    src.cs.gather = gather_blocks;
    src.cs.ctx = &src.blocks;
    src.cs.filter = info.filter;
    src.cs.levels = info.levels;
    for (a = 0; a < 3; a++) {
        src.cs.dims[a] = src.n[a];
        src.cs.pad[a] = pad[a];
    }
    s.src = &src;
    s.prepare = prepare;
    s.fetch = fetch;
    status = wvol__render_sampled(img, &s, cam, tf, &p, stats, err);
    bytes = src.blocks.bytes + wvol__bounds_bytes(src.bounds) + (size_t)src.nthreads * sizeof(void *) +
            (src.bound_rate ? src.bn[0] * src.bn[1] * src.bn[2] * sizeof *src.bound_rate : 0);
    if (src.bound_rate)
        for (size_t i = 0; i < src.bn[0] * src.bn[1] * src.bn[2]; i++) bound_skipped += src.bound_rate[i] == 0;
    if (s.tctx)
        for (int t = 0; t < src.nthreads; t++)
            if (s.tctx[t]) {
                brick_cache *c = s.tctx[t];
                bytes += cache_bytes(c);
                built += c->built;
            }
    if (status == WVOL_OK && stats) {
        /* the whole call: building the view and the bounds included */
        stats->brick = src.B;
        stats->seconds = wvol__now() - t0;
        stats->cpu_seconds = wvol__cpu_now() - c0;
        stats->bricks_built = built;
        stats->bricks_bound_skipped = bound_skipped;
        stats->bytes += bytes; /* beside the walk's own */
    }
done:
    if (s.tctx) {
        for (int t = 0; t < src.nthreads; t++) cache_free(s.tctx[t]);
        free(s.tctx);
    }
    blocks_free(&src.blocks);
    wvol__bounds_free(src.bounds);
    free(src.bound_rate);
    return status;
}
