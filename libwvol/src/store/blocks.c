/* SPDX-License-Identifier: MIT
 * A block-sparse view of a store's kept coefficients (store/store_blocks.h): per (level,
 * band) a directory of blocks of 4^3 coefficient positions, a block present only where a
 * kept coefficient lies: a 64-bit mask of its kept positions and the offset of its values,
 * stored compactly (rank of a position = popcount of the mask below it), and its values'
 * largest magnitude (what the bounds take). Built block by block from the store's tree, each
 * block's few nodes read twice while in cache, the blocks numbered level by level in the
 * directories' order at the coarsest two levels, the tree's below: 4 bytes per kept
 * coefficient, 16 per present block, 4 per directory entry (1/64 of the bands' size). The
 * low-pass cube is read from the store. */
#include "store/store_blocks.h"
#include "core/alloc.h"
#include "core/clock.h"
#include "core/clones.h"
#include "store/store_internal.h"
#include "codec/wvc_source.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <pthread.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define CB_SHIFT 2 /* blocks of 4^3 = 64 coefficient positions: one 64-bit mask */
#define CB (1 << CB_SHIFT)

typedef struct cblock {
    uint64_t mask;     /* bit x + 4 y + 16 z: position kept */
    uint32_t first;    /* index of its first value in the values array */
    float amax;        /* its values' largest magnitude (+inf where one is NaN) */
} cblock;

typedef struct band_view {
    size_t e[3];       /* band extent */
    size_t nb[3];      /* blocks per axis */
    uint32_t *dir;     /* nb0 nb1 nb2: 1 + block number in the pool, 0 = no kept coefficient */
} band_view;

struct wvol__store_blocks {
    int M;
    band_view bv[WVOL_SELECT_MAX_LEVELS + 1][8];
    uint32_t *dirs;    /* every band's directory, one allocation */
    cblock *blocks;    /* nblocks; directory entries index it + 1 */
    float *values;     /* nvalues, block by block, position order within a block */
    size_t nblocks, nvalues;
    const float *low;  /* the store's low-pass cube, E0 E1 E2 */
    size_t E[3];
    size_t bytes;
    wvol__coef_source cs;  /* a reconstruction's source reading through the view */
    int cached;            /* the store's own (wvol_store.view): destroy leaves it */
    struct kept_table *tables; /* wvol__store_blocks_keep_table's, guarded by table_lock */
    pthread_mutex_t table_lock;
    int table_lock_ok;
};

struct kept_table {
    int key;
    double *v;
    struct kept_table *next;
};
typedef struct wvol__store_blocks coef_blocks;

static void blocks_free(coef_blocks *cb)
{
    while (cb->tables) {
        struct kept_table *t = cb->tables;
        cb->tables = t->next;
        free(t->v);
        free(t);
    }
    if (cb->table_lock_ok) pthread_mutex_destroy(&cb->table_lock);
    free(cb->dirs);
    free(cb->blocks);
    free(cb->values);
}

/* The store's nodes hold a position and the bands kept there (store_internal.h): a node's
 * bit in its 4^3 block (x + 4 y + 16 z), the same in each of its level's bands (whose extents
 * agree), is found once for its up to 7 coefficients (wvol_store_next would decode the key
 * again for each one; bench/results/render-tuning.md). */
static inline int node_bit(const wvol__node *nd)
{
    size_t pos[3];
    wvol__key_pos(nd->key, pos);
    return (int)((pos[0] & (CB - 1)) + CB * ((pos[1] & (CB - 1)) + CB * (pos[2] & (CB - 1))));
}

/* Below this many nodes a level's view (and below this many blocks the bounds' tables) is
 * made on one thread: a small view takes less time than the threads' start and the ranges'
 * counting (bench/results/view_threads.md). The tests lower it. */
static size_t parallel_min = (size_t)1 << 17;

size_t wvol__store_blocks_parallel_min(size_t n)
{
    const size_t was = parallel_min;
    parallel_min = n;
    return was;
}

/* Where place_block numbers what it makes: its blocks from nb (below cap), its values from nv
 * (below vcap). A range of groups built by one thread owns such a range, sized by count_groups. */
typedef struct cursor {
    size_t nb, cap, nv, vcap;
} cursor;

/* Block i of level m from the level-m nodes of the node ranges r[0..nr) (r[j][0] to
 * r[j][1]), which are all the block's nodes: their masks per band, the block of each band with
 * a kept position (numbered at the cursor), each value placed at its rank, and the blocks'
 * largest magnitudes, while the few nodes are in cache. 1 when the cursor's range is too
 * small (the store's tree is not what the counts said). */
WVOL__CLONES static int place_block(coef_blocks *cb, const wvol_store *s, int m, size_t i, const size_t (*r)[2],
                                    int nr, cursor *cu)
{
    band_view *const bvs = cb->bv[m];
    uint64_t mask[8] = {0};
    float amax[8] = {0};
    uint32_t first[8], blk[8];
    unsigned present = 0, nan = 0, bands;
    int j, band;
    /* the per-node loops over a node's bands are branch-free where they can be: a block of
     * sparse coefficients holds a few values, so mispredicted loop exits would cost more than
     * the work */
    for (j = 0; j < nr; j++)
        for (size_t k = r[j][0]; k < r[j][1]; k++) {
            const wvol__node *nd = &s->nodes[k];
            const unsigned bm = nd->band_mask;
            const int bit = node_bit(nd);
            for (band = 1; band < 8; band++) mask[band] |= (uint64_t)((bm >> (band - 1)) & 1) << bit;
            present |= bm;
        }
    for (bands = present; bands; bands &= bands - 1) {
        const size_t n = (size_t)__builtin_popcountll(mask[band = __builtin_ctz(bands) + 1]);
        if (n > cu->vcap - cu->nv || cu->nb == cu->cap) return 1;
        first[band] = (uint32_t)cu->nv;
        blk[band] = (uint32_t)cu->nb;
        cb->blocks[cu->nb] = (cblock){.mask = mask[band], .first = first[band]};
        bvs[band].dir[i] = (uint32_t)++cu->nb;
        cu->nv += n;
    }
    for (j = 0; j < nr; j++)
        for (size_t k = r[j][0]; k < r[j][1]; k++) {
            const wvol__node *nd = &s->nodes[k];
            const float *v = s->values + nd->coef_first;
            const uint64_t below = ((uint64_t)1 << node_bit(nd)) - 1;
            for (bands = nd->band_mask; bands; bands &= bands - 1, v++) {
                const float av = fabsf(*v);
                band = __builtin_ctz(bands) + 1;
                cb->values[first[band] + (size_t)__builtin_popcountll(mask[band] & below)] = *v;
                amax[band] = av > amax[band] ? av : amax[band];
                nan |= (unsigned)(av != av) << band;
            }
        }
    /* a block's largest magnitude, +inf where a value is NaN (the bound's convention) */
    for (bands = present; bands; bands &= bands - 1) {
        band = __builtin_ctz(bands) + 1;
        cb->blocks[blk[band]].amax = (nan >> band) & 1 ? INFINITY : amax[band];
    }
    return 0;
}

/* The children of node nd, [child_first, + popcount(child_mask)) (the store lists each
 * node's children together; a node without children has child_first where they would be). */
static inline size_t children_end(const wvol__node *nd)
{
    return (size_t)nd->child_first + (size_t)__builtin_popcount(nd->child_mask);
}

/* The first node of a level lower than m (the store lists the levels from the coarsest
 * down): levels are contiguous runs, found by halving. */
static size_t level_end(const wvol_store *s, int m)
{
    size_t lo = 0, hi = s->nnodes;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (wvol__key_level(s->nodes[mid].key) >= m) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

/* Level m <= M - 2: a 4^3 block of level m holds the level-m descendants of one node two
 * levels up (its position is the block's), and the store lists them together (breadth first,
 * each node's children together, so any node's descendants at one level are consecutive: from
 * its first child's first child to its last child's last). Group g is the node of level m + 2;
 * its descendants' range into r: 1, or 0 when it has none, -1 when they lie past the nodes. */
static int group_range(const wvol_store *s, size_t g, size_t r[2])
{
    const wvol__node *gn = &s->nodes[g];
    if (!gn->child_mask) return 0;
    if (children_end(gn) > s->nnodes) return -1;
    r[0] = s->nodes[gn->child_first].child_first;
    r[1] = children_end(&s->nodes[children_end(gn) - 1]);
    if (r[0] >= r[1]) return 0;
    return r[1] <= s->nnodes ? 1 : -1;
}

/* The blocks of groups [g0, g1), placed at the cursor; 1 when the store's tree is not what
 * the view expects. */
static int build_groups(coef_blocks *cb, const wvol_store *s, int m, size_t g0, size_t g1, cursor *cu)
{
    const band_view *bv = &cb->bv[m][1]; /* the level's bands share their extents */
    for (size_t g = g0; g < g1; g++) {
        size_t gpos[3], r[1][2];
        const int has = group_range(s, g, r[0]);
        if (has < 0) return 1;
        if (!has) continue;
        wvol__key_pos(s->nodes[g].key, gpos);
        if (place_block(cb, s, m, gpos[0] + bv->nb[0] * (gpos[1] + bv->nb[1] * gpos[2]), (const size_t(*)[2])r, 1,
                        cu))
            return 1;
    }
    return 0;
}

/* What groups [g0, g1) will make: blocks (a (group, band) holding a kept position) and values. */
static void count_groups(const wvol_store *s, size_t g0, size_t g1, size_t *blocks, size_t *values)
{
    size_t nb = 0, nv = 0;
    for (size_t g = g0; g < g1; g++) {
        size_t r[2];
        unsigned present = 0;
        if (group_range(s, g, r) <= 0) continue; /* a tree past the nodes: build_groups says so */
        for (size_t k = r[0]; k < r[1]; k++) {
            present |= s->nodes[k].band_mask;
            nv += (size_t)__builtin_popcount(s->nodes[k].band_mask);
        }
        nb += (size_t)__builtin_popcount(present);
    }
    *blocks = nb, *values = nv;
}

/* Level m <= M - 2 from the groups [g0, g1). With threads, the groups are cut into ranges,
 * each range's blocks and values counted first, so that every range places its own at the
 * offsets the ranges before it leave: the view is the one thread's, block for block. */
static wvol_status build_grouped(coef_blocks *cb, const wvol_store *s, int m, size_t g0, size_t g1, int threads,
                                 size_t cap, size_t *nv, wvol_error *err)
{
    size_t per, nr, (*at)[2] = NULL;
    int bad = 0;
    const int nth = wvol__threads(threads);
    /* about eight ranges a thread, for the dynamic schedule to even out */
    per = (g1 - g0) / (8 * (size_t)nth);
    per = per < 64 ? 64 : per;
    nr = (g1 - g0 + per - 1) / per;
    if (nth <= 1 || nr < 2 || level_end(s, m) - level_end(s, m + 1) < parallel_min) {
        cursor cu = {cb->nblocks, cap, *nv, s->nvalues};
        bad = build_groups(cb, s, m, g0, g1, &cu);
        cb->nblocks = cu.nb, *nv = cu.nv;
    } else {
        at = malloc((nr + 1) * sizeof *at);
        WVOL_RETURN_IF(!at, err, WVOL_ERR_NOMEM, "store: out of memory for the coefficient blocks");
        long long n = (long long)nr;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
        for (long long k = 0; k < n; k++) {
            const size_t a = g0 + (size_t)k * per, b = a + per < g1 ? a + per : g1;
            count_groups(s, a, b, &at[k + 1][0], &at[k + 1][1]);
        }
        at[0][0] = cb->nblocks, at[0][1] = *nv;
        for (size_t k = 1; k <= nr; k++) at[k][0] += at[k - 1][0], at[k][1] += at[k - 1][1];
        if (at[nr][0] > cap || at[nr][1] > s->nvalues) bad = 1;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth) reduction(| : bad) if (!bad)
        for (long long k = 0; k < n; k++) {
            const size_t a = g0 + (size_t)k * per, b = a + per < g1 ? a + per : g1;
            cursor cu = {at[k][0], at[k + 1][0], at[k][1], at[k + 1][1]};
            bad |= build_groups(cb, s, m, a, b, &cu) || cu.nb != at[k + 1][0] || cu.nv != at[k + 1][1];
        }
        cb->nblocks = at[nr][0], *nv = at[nr][1];
        free(at);
    }
    WVOL_RETURN_IF(bad, err, WVOL_ERR_INTERNAL, "store: level %d's nodes are not the tree the view expects", m);
    return WVOL_OK;
}

/* The coarsest two levels, block by block in directory order: a block of level M holds up to
 * 4^3 roots (the store's root table finds them), one of level M - 1 the children of up to 2^3
 * roots. */
static wvol_status build_rooted(coef_blocks *cb, const wvol_store *s, int m, size_t cap, size_t *nv, wvol_error *err)
{
    const band_view *bv = &cb->bv[m][1];
    const size_t w = m == cb->M ? CB : 2; /* roots per block edge */
    cursor cu = {cb->nblocks, cap, *nv, s->nvalues};
    for (size_t z = 0; z < bv->nb[2]; z++)
        for (size_t y = 0; y < bv->nb[1]; y++)
            for (size_t x = 0; x < bv->nb[0]; x++) {
                size_t r[CB * CB * CB][2];
                int nr = 0;
                for (size_t k = z * w; k < (z + 1) * w && k < cb->E[2]; k++)
                    for (size_t j = y * w; j < (y + 1) * w && j < cb->E[1]; j++)
                        for (size_t i = x * w; i < (x + 1) * w && i < cb->E[0]; i++) {
                            const int32_t ni = s->root_of[i + cb->E[0] * (j + cb->E[1] * k)];
                            if (ni < 0) continue;
                            if (m == cb->M) {
                                r[nr][0] = (size_t)ni;
                                r[nr++][1] = (size_t)ni + 1;
                            } else if (s->nodes[ni].child_mask) {
                                r[nr][0] = s->nodes[ni].child_first;
                                r[nr++][1] = children_end(&s->nodes[ni]);
                                WVOL_RETURN_IF(r[nr - 1][1] > s->nnodes, err, WVOL_ERR_INTERNAL,
                                               "store: a root's children lie past the nodes");
                            }
                        }
                WVOL_RETURN_IF(nr && place_block(cb, s, m, x + bv->nb[0] * (y + bv->nb[1] * z),
                                                 (const size_t(*)[2])r, nr, &cu),
                               err, WVOL_ERR_INTERNAL, "store: level %d's blocks exceed the directory or the values",
                               m);
            }
    cb->nblocks = cu.nb, *nv = cu.nv;
    return WVOL_OK;
}

/* Builds the view, level by level from the coarsest, block by block (place_block), each
 * block's nodes found from the store's tree; the finer levels on `threads` (0: OpenMP's
 * default). */
static wvol_status blocks_build(coef_blocks *cb, const wvol_store *s, int threads, wvol_error *err)
{
    wvol_store_info info;
    size_t pad[3], ndir = 0, at[WVOL_SELECT_MAX_LEVELS + 1][8] = {{0}}; /* a directory's offset + 1 */
    size_t cap = 0, nv = 0;
    int a, m, l;
    wvol_status st;
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
            if (!n || s->file) continue; /* a file store's details come from its chunks */
            at[m][l] = ndir + 1;
            ndir += n;
        }
    /* every band's directory carved from one zeroed allocation (whole huge pages when large:
     * a fresh view's first touches of many small directories cost more than their filling) */
    if (ndir) {
        size_t bytes = ndir * sizeof *cb->dirs;
        cb->dirs = ndir <= SIZE_MAX / sizeof *cb->dirs ? wvol__malloc_pages(&bytes) : NULL;
        WVOL_RETURN_IF(!cb->dirs, err, WVOL_ERR_NOMEM, "store: out of memory for the coefficient blocks");
        memset(cb->dirs, 0, ndir * sizeof *cb->dirs);
        cb->bytes += ndir * sizeof *cb->dirs;
        for (m = 1; m <= cb->M; m++)
            for (l = 1; l < 8; l++)
                if (at[m][l]) cb->bv[m][l].dir = cb->dirs + (at[m][l] - 1);
    }
    if (s->file || !s->nnodes) return WVOL_OK;
    cb->values = wvol__malloc_large((s->nvalues + 1) * sizeof *cb->values);
    WVOL_RETURN_IF(!cb->values, err, WVOL_ERR_NOMEM, "store: out of memory for %zu coefficients", s->nvalues);
    /* at most one block per directory entry and per value: reserved at once (only the pages
     * filled are touched) instead of grown by doubling, whose copies and fresh pages cost a
     * view of a million sparse blocks more than filling them; in whole huge pages from the
     * start, as the blocks in use are the reservation's first: in the 4 KiB pages before a
     * malloc'd block's first 2 MiB boundary the gathers' TLB misses slowed every later
     * extraction (iso_mc_profile.md) */
    cap = ndir < s->nvalues ? ndir : s->nvalues;
    {
        size_t bytes = (cap + 1) * sizeof *cb->blocks;
        cb->blocks = cap < UINT32_MAX ? wvol__malloc_pages(&bytes) : NULL;
    }
    WVOL_RETURN_IF(!cb->blocks, err, WVOL_ERR_NOMEM, "store: out of memory for the coefficient blocks");
    for (m = cb->M, st = WVOL_OK; m >= 1 && st == WVOL_OK; m--)
        st = m >= cb->M - 1 ? build_rooted(cb, s, m, cap, &nv, err)
                            : build_grouped(cb, s, m, level_end(s, m + 3), level_end(s, m + 2), threads, cap, &nv, err);
    cb->bytes += cb->nblocks * sizeof *cb->blocks;
    WVOL_FORWARD(st);
    WVOL_RETURN_IF(nv != s->nvalues, err, WVOL_ERR_INTERNAL, "store: the view holds %zu of the store's %zu values",
                   nv, s->nvalues);
    cb->nvalues = nv;
    cb->bytes += nv * sizeof *cb->values;
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
 * a brick's finest-level region meets a hundred or so entries, most of them absent. The
 * wrapped positions are stepped, one division per axis. Cloned: a value's rank in its block is a
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

/* max |v| over n values, NaN as +inf; written so that it vectorises */

/* The bounds' block maxima from the view, block by block: where the bound's blocks are the
 * view's 4^3 (level 1) a block's maximum (kept with it) is its slot's; bound blocks of 2^3 (level
 * 2) get the maxima of the view block's eight octants; any other shape (larger blocks, or finer
 * ones) takes the block's maximum over its box, or each value at its position. Levels above the
 * bound's own are skipped (its low-pass cube holds them). */
static inline void take_max(float *slot, float av)
{
    if (!(av <= *slot)) *slot = av; /* av is a magnitude, NaN already +inf */
}

static void blocks_bounds(const coef_blocks *cb, wvol__brick_bounds *bb, int threads)
{
    const int L = wvol__bounds_levels(bb) < cb->M ? wvol__bounds_levels(bb) : cb->M;
    /* a task per (level, band): each fills its band's table alone */
    long long tasks = 7LL * L;
    const int nth = wvol__threads(threads);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth) if (nth > 1 && cb->nblocks >= parallel_min)
    for (long long task = 0; task < tasks; task++) {
        const int m = 1 + (int)(task / 7), band = 1 + (int)(task % 7);
        const size_t edge = wvol__bounds_block(bb, m);
        const band_view *bv = &cb->bv[m][band];
        size_t tn[3];
        int sh[3];
        float *t = bv->dir ? wvol__bounds_table(bb, m, band, tn, sh) : NULL;
        const int same = t && sh[0] == CB_SHIFT && sh[1] == CB_SHIFT && sh[2] == CB_SHIFT;
        const int half = t && sh[0] == 1 && sh[1] == 1 && sh[2] == 1;
        if (!t) continue;
        for (size_t z = 0; z < bv->nb[2]; z++)
            for (size_t y = 0; y < bv->nb[1]; y++)
                for (size_t x = 0; x < bv->nb[0]; x++) {
                    const uint32_t blk = bv->dir[x + bv->nb[0] * (y + bv->nb[1] * z)];
                    if (!blk) continue;
                    const cblock *b = &cb->blocks[blk - 1];
                    const float *v = cb->values + b->first;
                    const size_t lo[3] = {x << CB_SHIFT, y << CB_SHIFT, z << CB_SHIFT};
                    if (same) {
                        take_max(&t[x + tn[0] * (y + tn[1] * z)], b->amax);
                    } else if (edge >= CB) {
                        const size_t hi[3] = {lo[0] + CB, lo[1] + CB, lo[2] + CB};
                        wvol__bounds_add_box(bb, m, band, lo, hi, b->amax);
                    } else if (half) {
                        float oct[8] = {0};
                        for (uint64_t bits = b->mask; bits; bits &= bits - 1, v++) {
                            const int bit = __builtin_ctzll(bits);
                            const int o = ((bit >> 1) & 1) | ((bit >> 2) & 2) | ((bit >> 3) & 4);
                            const float av = fabsf(*v);
                            if (!(av <= oct[o])) oct[o] = av != av ? INFINITY : av;
                        }
                        for (int o = 0; o < 8; o++)
                            if (oct[o] != 0)
                                take_max(&t[(2 * x + (size_t)(o & 1)) +
                                            tn[0] * ((2 * y + (size_t)((o >> 1) & 1)) + tn[1] * (2 * z + (size_t)(o >> 2)))],
                                         oct[o]);
                    } else {
                        for (uint64_t bits = b->mask; bits; bits &= bits - 1, v++) {
                            const int bit = __builtin_ctzll(bits);
                            wvol__bounds_add(bb, m, band, lo[0] + (size_t)(bit & 3), lo[1] + (size_t)((bit >> 2) & 3),
                                             lo[2] + (size_t)(bit >> 4), *v);
                        }
                    }
                }
    }
}

/* A file's chunk maxima of the levels 1..L from its index (nothing decoded). */
typedef struct file_tiles {
    int L;
    size_t nt[WVOL_SELECT_MAX_LEVELS + 1][3], tile[WVOL_SELECT_MAX_LEVELS + 1][3];
    float *mx[WVOL_SELECT_MAX_LEVELS + 1]; /* per level, chunk order */
    size_t nonzero;                        /* chunks with a non-zero maximum */
    size_t need;                           /* their decoded size, all bands */
    size_t least[3];                       /* per axis the smallest tile */
} file_tiles;

static void tiles_free(file_tiles *ft)
{
    for (int m = 1; m <= ft->L; m++) free(ft->mx[m]);
}

static wvol_status tiles_load(file_tiles *ft, wvol_wvc_file *f, int L, wvol_error *err)
{
    memset(ft, 0, sizeof *ft);
    ft->L = L;
    for (int m = 1; m <= L; m++) {
        size_t n;
        wvol__wvc_file_level_max(f, m, NULL, ft->nt[m], ft->tile[m]);
        n = ft->nt[m][0] * ft->nt[m][1] * ft->nt[m][2];
        ft->mx[m] = malloc(n * sizeof *ft->mx[m] + 1);
        WVOL_RETURN_IF(!ft->mx[m], err, WVOL_ERR_NOMEM, "store: out of memory for the file's bounds");
        wvol__wvc_file_level_max(f, m, ft->mx[m], ft->nt[m], ft->tile[m]);
        for (size_t k = 0; k < n; k++)
            if (ft->mx[m][k] != 0)
                ft->nonzero++, ft->need += ft->tile[m][0] * ft->tile[m][1] * ft->tile[m][2] * 7 * sizeof(int32_t);
        for (int a = 0; a < 3; a++)
            if (!ft->least[a] || ft->tile[m][a] < ft->least[a]) ft->least[a] = ft->tile[m][a];
    }
    return WVOL_OK;
}

/* The bound of a chunk's coefficients is its maximum from the index, spread over every
 * bound block the chunk covers (nothing is decoded). */
static void file_bounds(wvol__brick_bounds *bb, const file_tiles *ft)
{
    for (int m = 1; m <= ft->L; m++)
        for (size_t k = 0; k < ft->nt[m][2]; k++)
            for (size_t j = 0; j < ft->nt[m][1]; j++)
                for (size_t i = 0; i < ft->nt[m][0]; i++) {
                    const size_t *tile = ft->tile[m];
                    const size_t lo[3] = {i * tile[0], j * tile[1], k * tile[2]};
                    const size_t hi[3] = {lo[0] + tile[0], lo[1] + tile[1], lo[2] + tile[2]};
                    float v = ft->mx[m][i + ft->nt[m][0] * (j + ft->nt[m][1] * k)];
                    if (v == 0) continue;
                    for (int band = 1; band < 8; band++) wvol__bounds_add_box(bb, m, band, lo, hi, v);
                }
}

/* The bounds from the decoded coefficients themselves instead of the index's per-chunk
 * maxima (one maximum over a tile of all seven bands, so loose that a surface through a few
 * bricks of a tile leaves every brick of it undecided): every chunk with a non-zero maximum
 * is decoded (threads over chunks; the shared cache decodes each once and keeps it for the
 * reconstruction that follows) and its bands' block maxima are taken. */
static wvol_status decoded_bounds(wvol__brick_bounds *bb, const wvol_store *s, const file_tiles *ft, int threads,
                                  wvol_error *err)
{
    wvol_store_info info;
    wvol__coef_source cs;
    size_t k, (*list)[4], n = 0;
    wvol_status st = WVOL_OK;
    int m, parallel = 1;
    wvol_store_get_info(s, &info);
    list = malloc((ft->nonzero + 1) * sizeof *list);
    WVOL_RETURN_IF(!list, err, WVOL_ERR_NOMEM, "store: out of memory for the file's bounds");
    for (m = 1; m <= ft->L; m++) {
        for (int a = 0; a < 3; a++)
            if (ft->tile[m][a] % 4) parallel = 0; /* tiles could share a bound block */
        for (k = 0; k < ft->nt[m][0] * ft->nt[m][1] * ft->nt[m][2]; k++)
            if (ft->mx[m][k] != 0) {
                list[n][0] = (size_t)m;
                list[n][1] = k % ft->nt[m][0];
                list[n][2] = (k / ft->nt[m][0]) % ft->nt[m][1];
                list[n++][3] = k / (ft->nt[m][0] * ft->nt[m][1]);
            }
    }
    wvol__wvc_file_source(&cs, s->file, 0);
    (void)wvol__wvc_file_error(s->file, NULL);
#ifdef _OPENMP
#pragma omp parallel num_threads(threads > 0 ? threads : omp_get_max_threads()) if (parallel && threads != 1)
#endif
    {
        float *buf = NULL;
        size_t cap = 0;
        int oom = 0;
        long q;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
        for (q = 0; q < (long)n; q++) {
            const int lm = (int)list[q][0];
            const size_t pad[3] = {info.px, info.py, info.pz};
            size_t lo[3], cnt[3], vol;
            ptrdiff_t plo[3], pn[3];
            for (int a = 0; a < 3; a++) {
                size_t e = wvol__extent(pad[a], lm);
                lo[a] = list[q][1 + a] * ft->tile[lm][a];
                cnt[a] = lo[a] + ft->tile[lm][a] < e ? ft->tile[lm][a] : e - lo[a];
                plo[a] = (ptrdiff_t)lo[a];
                pn[a] = (ptrdiff_t)cnt[a];
            }
            vol = cnt[0] * cnt[1] * cnt[2];
            if (vol > cap) {
                free(buf);
                buf = malloc(vol * sizeof *buf);
                cap = buf ? vol : 0;
            }
            if (!buf) { /* this chunk's bound blocks would stay 0: refused below */
                oom = 1;
                continue;
            }
            for (int band = 1; band < 8; band++)
                if (cs.gather(cs.ctx, buf, lm, band, plo, pn))
                    wvol__bounds_add_dense(bb, lm, band, lo, cnt, buf, cnt[0], cnt[0] * cnt[1]);
        }
        if (oom) {
#ifdef _OPENMP
#pragma omp critical(wvol_store_decoded_bounds)
#endif
            st = WVOL_ERR_NOMEM;
        }
        free(buf);
    }
    free(list);
    if (st != WVOL_OK) return wvol_error_set(err, st, "store: out of memory for a chunk's bounds");
    return wvol__wvc_file_error(s->file, err);
}

/* exact_threads < 0: a file store's bounds from its index; else from its decoded chunks when
 * their decoded size fits in half the file's budget (decoded_bounds, that many threads),
 * *exact saying whether they did. Bounds from the index keep their maxima per tile-sized
 * block (one value per chunk and band: at 2048^3 the default small blocks would take over a
 * gigabyte to repeat them). */
static wvol_status build_view(wvol__store_blocks **out, wvol__brick_bounds **bounds, const wvol_store *s,
                              int threads, int exact_threads, int *exact, wvol_error *err)
{
    wvol_store_info info;
    wvol__brick_bounds *bb = NULL;
    wvol__store_blocks *cb;
    wvol_status st;
    *out = NULL;
    if (bounds) *bounds = NULL;
    if (exact) *exact = 0;
    wvol_store_get_info(s, &info);
    cb = malloc(sizeof *cb);
    st = cb ? blocks_build(cb, s, threads, err)
            : wvol_error_set(err, WVOL_ERR_NOMEM, "store: out of memory for the coefficient blocks");
    if (st != WVOL_OK) {
        wvol__store_blocks_destroy(cb);
        return st;
    }
    cb->table_lock_ok = pthread_mutex_init(&cb->table_lock, NULL) == 0; /* else no table is kept */
    cb->cs = (wvol__coef_source){.gather = gather_blocks, .ctx = cb, .filter = info.filter, .levels = info.levels,
                                 .dims = {info.nx, info.ny, info.nz}, .pad = {info.px, info.py, info.pz}};
    if (cb->low && !s->file) cb->cs.dc = wvol__lowpass_offset(cb->low, cb->E, 0); /* the cube is the band */
    /* a store opened on a file: the detail bands come from its chunks, decoded on demand */
    if (s->file) wvol__wvc_file_source(&cb->cs, s->file, 0);
    /* the bound needs every axis transformed; without it every brick is reconstructed */
    if (bounds && info.px > 1 && info.py > 1 && info.pz > 1 && info.levels >= 1) {
        file_tiles ft;
        int decoded = 0;
        memset(&ft, 0, sizeof ft);
        if (s->file) {
            wvol_wvc_cache_stats cst;
            wvol_wvc_file_stats(s->file, &cst);
            const size_t pad[3] = {info.px, info.py, info.pz};
            st = tiles_load(&ft, s->file, wvol__bounds_levels_for(pad, info.levels), err);
            decoded = exact_threads >= 0 && ft.nonzero > 0 && ft.need <= cst.budget / 2;
        }
        if (st == WVOL_OK) st = wvol__bounds_create_src(&bb, &cb->cs, s->file && !decoded ? ft.least : NULL, err);
        if (st == WVOL_OK && s->file) st = wvol__wvc_file_error(s->file, err);
        if (st == WVOL_OK) {
            if (decoded) st = decoded_bounds(bb, s, &ft, exact_threads, err);
            else if (s->file) file_bounds(bb, &ft);
            else blocks_bounds(cb, bb, threads);
        }
        tiles_free(&ft);
        if (st != WVOL_OK) {
            wvol__store_blocks_destroy(cb);
            wvol__bounds_free(bb);
            return st;
        }
        if (exact) *exact = decoded;
        wvol__bounds_finish(bb);
    }
    if (bounds) *bounds = bb;
    *out = cb;
    return WVOL_OK;
}

/* A built store's view and bounds depend on the store alone: made together, once, on first
 * use, and kept by the store (wvol_store is immutable, so they never go stale); the caller gets
 * the shared view and bounds (destroying or freeing them is then a no-op). A store opened on a
 * file builds them each time: its bounds depend on what its chunk cache can hold. */
static wvol_status create(wvol__store_blocks **out, wvol__brick_bounds **bounds, const wvol_store *s,
                          int threads, int exact_threads, int *exact, wvol_error *err)
{
    wvol_store *w = (wvol_store *)s; /* the lazily made view: guarded by its lock */
    wvol_status st = WVOL_OK;
    if (s->file || !s->view_lock_ok) return build_view(out, bounds, s, threads, exact_threads, exact, err);
    *out = NULL;
    if (bounds) *bounds = NULL;
    if (exact) *exact = 0;
    pthread_mutex_lock(&w->view_lock);
    if (!w->view) {
        wvol__store_blocks *v = NULL;
        wvol__brick_bounds *b = NULL; /* stays NULL where the bound does not apply */
        st = build_view(&v, &b, s, threads, -1, NULL, err);
        if (st == WVOL_OK) {
            v->cached = 1;
            wvol__bounds_keep(b, 1);
            w->view = v;
            w->view_bounds = b;
        }
    }
    if (st == WVOL_OK) {
        *out = w->view;
        if (bounds) *bounds = w->view_bounds;
    }
    pthread_mutex_unlock(&w->view_lock);
    return st;
}

wvol_status wvol__store_blocks_create(wvol__store_blocks **out, wvol__brick_bounds **bounds, const wvol_store *s,
                                      int threads, wvol_error *err)
{
    return create(out, bounds, s, threads, -1, NULL, err);
}

wvol_status wvol__store_blocks_create_exact(wvol__store_blocks **out, wvol__brick_bounds **bounds,
                                            const wvol_store *s, int threads, int *exact, wvol_error *err)
{
    if (exact) *exact = 0;
    return create(out, bounds, s, threads, threads > 0 ? threads : 0, exact, err);
}

void wvol__store_blocks_source(wvol__coef_source *src, const wvol__store_blocks *b)
{
    *src = b->cs;
}

static struct kept_table *find_table(const coef_blocks *b, int key)
{
    struct kept_table *t = b->tables;
    while (t && t->key != key) t = t->next;
    return t;
}

const double *wvol__store_blocks_table(wvol__store_blocks *b, int key)
{
    struct kept_table *t;
    if (!b || !b->table_lock_ok) return NULL;
    pthread_mutex_lock(&b->table_lock);
    t = find_table(b, key);
    pthread_mutex_unlock(&b->table_lock);
    return t ? t->v : NULL;
}

int wvol__store_blocks_keep_table(wvol__store_blocks *b, int key, double **table)
{
    struct kept_table *t;
    int kept = 0;
    if (!b || !b->table_lock_ok || !*table) return 0;
    pthread_mutex_lock(&b->table_lock);
    t = find_table(b, key);
    if (t) {
        free(*table); /* another thread's made meanwhile: the same values */
        *table = t->v;
        kept = 1;
    } else if ((t = malloc(sizeof *t))) {
        t->key = key;
        t->v = *table;
        t->next = b->tables;
        b->tables = t;
        kept = 1;
    }
    pthread_mutex_unlock(&b->table_lock);
    return kept;
}

int wvol__store_file_room(const wvol_store *s, size_t bytes)
{
    wvol_wvc_cache_stats cst;
    if (!s || !s->file) return 0;
    wvol_wvc_file_stats(s->file, &cst);
    return cst.held <= cst.budget && bytes <= cst.budget - cst.held;
}

size_t wvol__store_blocks_bytes(const wvol__store_blocks *b)
{
    return b ? b->bytes : 0;
}

static void blocks_destroy(wvol__store_blocks *b)
{
    if (!b) return;
    blocks_free(b);
    free(b);
}

void wvol__store_blocks_destroy(wvol__store_blocks *b)
{
    if (b && !b->cached) blocks_destroy(b);
}

void wvol__store_view_free(wvol_store *s)
{
    blocks_destroy(s->view);
    wvol__bounds_keep(s->view_bounds, 0);
    wvol__bounds_free(s->view_bounds);
    s->view = NULL;
    s->view_bounds = NULL;
}
