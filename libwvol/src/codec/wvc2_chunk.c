/* SPDX-License-Identifier: MIT
 * The .wvc version-2 chunk coder: one level's bands over one spatial tile, each band
 * coded by the version-1 band coders (wvc_cabac.c, wvc_zstd.c) on a small local grid
 * that holds the tile and its parent region, so that a chunk depends on nothing but
 * its parent chunk (the coarser level's tile whose half-size region holds its parents,
 * which every read of the chunk's region needs anyway). Neighbours outside the tile
 * count as zero, as at a band's edge in version 1. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "core/alloc.h"
#include "wvc2_internal.h"

int wvol__wvc2_geom(wvc2_geom *g, const size_t p[3], int levels, int tile_xy, int tile_z)
{
    size_t first = 0;
    memset(g, 0, sizeof *g);
    g->levels = levels;
    g->tile[0] = g->tile[1] = tile_xy;
    g->tile[2] = tile_z;
    for (int a = 0; a < 3; a++) {
        g->p[a] = p[a];
        g->tr[a] = p[a] > 1;
    }
    for (int m = levels; m >= 1; m--) {
        wvc2_level *L = &g->lv[m];
        size_t n = 1;
        for (int a = 0; a < 3; a++) {
            L->e[a] = g->tr[a] ? p[a] >> m : 1;
            L->nt[a] = (L->e[a] + (size_t)g->tile[a] - 1) / (size_t)g->tile[a];
            if (L->nt[a] && n > SIZE_MAX / L->nt[a]) return -1;
            n *= L->nt[a];
        }
        L->first = first;
        L->count = n;
        if (first > SIZE_MAX - n) return -1;
        first += n;
        L->nb = 0;
        for (int b = m == levels ? 0 : 1; b < 8; b++) {
            int ok = 1;
            for (int a = 0; a < 3; a++)
                if (((b >> a) & 1) && !g->tr[a]) ok = 0;
            if (ok) L->bands[L->nb++] = b;
        }
    }
    g->nchunks = first;
    return 0;
}

int wvol__wvc2_chunk_coords(const wvc2_geom *g, size_t id, size_t t[3])
{
    for (int m = g->levels; m >= 1; m--) {
        const wvc2_level *L = &g->lv[m];
        if (id >= L->first && id < L->first + L->count) {
            size_t k = id - L->first;
            t[0] = k % L->nt[0];
            k /= L->nt[0];
            t[1] = k % L->nt[1];
            t[2] = k / L->nt[1];
            return m;
        }
    }
    return 0;
}

typedef wvc2_local local_grid;

/* The local grid's geometry (band, then its parent region along x, one set of strides);
 * returns its size in int32 values. */
static size_t local_init(local_grid *lg, const wvc2_geom *g, int m, int band, const size_t ext[3])
{
    size_t off0[3] = {0, 0, 0}, poff[3], pext[3];
    int has_parent = m < g->levels && band != 0;
    wvc2_parent_box(g, off0, ext, poff, pext);
    memset(lg, 0, sizeof *lg);
    lg->p[0] = ext[0] + (has_parent ? pext[0] : 0);
    lg->p[1] = ext[1];
    lg->p[2] = ext[2];
    lg->b.level = m;
    lg->b.band = band;
    lg->b.has_parent = has_parent;
    for (int a = 0; a < 3; a++) {
        lg->b.ext[a] = ext[a];
        lg->b.pext[a] = has_parent ? pext[a] : 0;
    }
    lg->b.poff[0] = has_parent ? ext[0] : 0;
    lg->b.count = (uint64_t)ext[0] * ext[1] * ext[2];
    return lg->p[0] * lg->p[1] * lg->p[2];
}

static void box_copy_in(local_grid *lg, size_t x0, const wvc2_qbox *src, const size_t ext[3])
{
    for (size_t z = 0; z < ext[2]; z++)
        for (size_t y = 0; y < ext[1]; y++) {
            int32_t *d = lg->q + x0 + lg->p[0] * (y + lg->p[1] * z);
            if (src->q) {
                memcpy(d, src->q + y * src->sy + z * src->sz, ext[0] * sizeof(int32_t));
            } else {
                const int16_t *r = src->q16 + y * src->sy + z * src->sz;
                for (size_t x = 0; x < ext[0]; x++) d[x] = r[x];
            }
        }
}

static void parent_in(local_grid *lg, const wvc2_qbox *parent)
{
    if (lg->b.has_parent) box_copy_in(lg, lg->b.ext[0], parent, lg->b.pext);
}

/* Payload modes: one stream per band (each CABAC or zstd); one CABAC stream whose model
 * adapts across the chunk's bands; the same with a flag per 4x4x4 block of a detail
 * band (wvc_cabac.c's block_row), which the encoder writes. */
enum { MODE_BANDS = 0, MODE_SHARED = 1, MODE_BLOCKS = 2, MODE_RANS = 3, MODE_RANS4 = 4 };

/* --coder compact's use of mode 3 (docs/wvc-format.md, "Chunk mode 3: the choice"): a chunk
 * without the low-pass cube with at least a quarter of its coefficients non-zero; from
 * 65536 non-zeros on mode 3 alone, below it both modes are coded and the smaller kept
 * (small dense chunks, the coarse levels, are where a static table pays most for itself,
 * and coding both costs little there). */
#define RANS_MIN_DENSITY 0.25
/* --coder compact tries each band on its own (CABAC or zstd) when all-zstd is within this
 * factor of the shared stream (wvol__wvc2_job_code) */
#define ZSTD_NEAR 1.25
#define RANS_ALONE_NONZERO 65536

/* --coder auto's use of mode 4 (docs/wvc-format.md, "Chunk mode 4: the choice"): below this
 * many non-zeros a chunk's decode takes microseconds in any mode, while mode 4's fixed part
 * (its 24 states, its tables) is most of its bytes, and its size jumps with one coefficient
 * more or less (a table entry, the sign choice): those chunks are coded as --coder compact. */
#define RANS4_MIN_NONZERO 4096

void wvol__wvc2_job_pool_free(wvc2_job_pool *pool)
{
    if (!pool) return;
    for (int i = 0; i < pool->n; i++) wvol__reuse_put(pool->block[i]);
    pool->n = 0;
}

/* A block of at least need values from pool (the smallest that fits), or one from the
 * library's reuse pool (core/alloc.h: pages another pass touched before, else whole huge
 * pages); *cap its size. */
static int32_t *pool_take(wvc2_job_pool *pool, size_t need, size_t *cap)
{
    int32_t *b = NULL;
    size_t bytes;
    if (pool) {
#pragma omp critical(wvc2_job_pool)
        {
            int best = -1;
            for (int i = 0; i < pool->n; i++)
                if (pool->cap[i] >= need && (best < 0 || pool->cap[i] < pool->cap[best])) best = i;
            if (best >= 0) {
                b = pool->block[best];
                *cap = pool->cap[best];
                pool->n--;
                pool->block[best] = pool->block[pool->n];
                pool->cap[best] = pool->cap[pool->n];
            }
        }
        if (b) return b;
    }
    if (need > SIZE_MAX / sizeof *b) return NULL;
    bytes = need * sizeof *b;
    b = wvol__reuse_get(bytes);
    *cap = wvol__pages_bytes(bytes) / sizeof *b;
    return b;
}

void wvol__wvc2_job_free(wvc2_job *job, wvc2_job_pool *pool)
{
    int kept = 0;
    if (!job) return;
    if (job->block && pool) {
#pragma omp critical(wvc2_job_pool)
        {
            const int max = pool->max < WVC2_POOL_MAX ? pool->max : WVC2_POOL_MAX;
            int small = 0;
            if (pool->n < max) {
                pool->block[pool->n] = job->block;
                pool->cap[pool->n] = job->cap;
                pool->n++;
                kept = 1;
            } else if (pool->n > 0) {
                /* full: the block replaces the smallest kept if it is larger (the coarse
                 * levels' small chunks would otherwise hold the places the large ones need) */
                for (int i = 1; i < pool->n; i++)
                    if (pool->cap[i] < pool->cap[small]) small = i;
                if (pool->cap[small] < job->cap) {
                    int32_t *b = pool->block[small];
                    pool->block[small] = job->block;
                    pool->cap[small] = job->cap;
                    job->block = b;
                }
            }
        }
    }
    if (!kept) wvol__reuse_put(job->block);
    job->block = NULL;
    job->cap = 0;
    memset(job->lg, 0, sizeof job->lg);
}

int wvol__wvc2_job_make(wvc2_job *job, const wvc2_geom *g, int m, const size_t ext[3], const wvc2_qbox child[8],
                        const wvc2_qbox parent[8], const uint64_t *nonzero, wvc2_job_pool *pool)
{
    const wvc2_level *L = &g->lv[m];
    size_t size[8] = {0}, need = 0, at = 0;
    memset(job, 0, sizeof *job);
    job->m = m;
    memcpy(job->ext, ext, sizeof job->ext);
    for (int i = 0; i < L->nb; i++) {
        if (nonzero) {
            job->nzb[i] = nonzero[i];
        } else {
            for (size_t zz = 0; zz < ext[2]; zz++)
                for (size_t y = 0; y < ext[1]; y++) {
                    const size_t o = y * child[i].sy + zz * child[i].sz;
                    for (size_t x = 0; x < ext[0]; x++)
                        job->nzb[i] += (child[i].q ? child[i].q[o + x] : child[i].q16[o + x]) != 0;
                }
        }
        if (job->nzb[i] == 0) continue;
        job->nonzero += job->nzb[i];
        job->mask |= (uint8_t)(1u << i);
        size[i] = local_init(&job->lg[i], g, m, L->bands[i], ext);
        need += size[i];
        job->nused++;
    }
    if (!need) return 0;
    job->block = pool_take(pool, need, &job->cap);
    if (!job->block) {
        memset(job, 0, sizeof *job);
        return -1;
    }
    for (int i = 0; i < L->nb; i++) {
        local_grid *lg = &job->lg[i];
        if (!size[i]) continue;
        lg->q = job->block + at;
        at += size[i];
        box_copy_in(lg, 0, &child[i], ext);
        parent_in(lg, &parent[i]);
        /* zeros where the parent region leaves the grid's parent columns (the tile's part
         * is copied whole), as in a fresh grid */
        if (lg->b.has_parent)
            for (size_t z = 0; z < ext[2]; z++)
                for (size_t y = 0; y < ext[1]; y++)
                    if (z >= lg->b.pext[2] || y >= lg->b.pext[1])
                        memset(lg->q + ext[0] + lg->p[0] * (y + lg->p[1] * z), 0, lg->b.pext[0] * sizeof *lg->q);
    }
    return 0;
}

/* The mode-4 stream of the present bands (Qs, Ps, Bs: ns of them) as a chunk's payload: mode,
 * band mask, the coder's stream; out->nonzero set by the caller. */
static int rans4_payload(wvc2_coded *out, const wvc2_level *L, uint8_t mask, const uint64_t *nzb, int ns,
                         int32_t *const Qs[], const size_t *const Ps[], const wvc_band *const Bs[],
                         wvc_rans_scratch *scratch)
{
    uint8_t *p = NULL;
    size_t len = 0;
    /* the mode and band-mask bytes go in the two bytes the encoder leaves before its stream */
    if (wvol__wvc_rans4_encode(&p, &len, 2, ns, Qs, Ps, Bs, scratch)) {
        memset(out, 0, sizeof *out);
        return -1;
    }
    p[0] = MODE_RANS4;
    p[1] = mask;
    /* per-band shares of one stream are not separable: split by non-zero counts */
    for (int i = 0; i < L->nb; i++)
        out->band_bytes[i] = (size_t)((double)len * (double)nzb[i] / (double)out->nonzero);
    out->payload = p;
    out->bytes = len;
    out->crc = (uint32_t)crc32(0L, p, (uInt)len);
    return 0;
}

/* A chunk in mode 4 from its job's local grids. */
static int job_code_rans4(wvc2_coded *out, wvc2_job *job, const wvc2_level *L, wvc_rans_scratch *scratch,
                          wvc2_job_pool *pool)
{
    int32_t *Qs[8];
    const size_t *Ps[8];
    const wvc_band *Bs[8];
    int ns = 0, r;
    for (int i = 0; i < L->nb; i++)
        if (job->mask >> i & 1) Qs[ns] = job->lg[i].q, Ps[ns] = job->lg[i].p, Bs[ns] = &job->lg[i].b, ns++;
    r = rans4_payload(out, L, job->mask, job->nzb, ns, Qs, Ps, Bs, scratch);
    wvol__wvc2_job_free(job, pool);
    return r;
}

/* --coder auto's and --coder rans4's choice of mode 4 (docs/wvc-format.md, "Chunk mode 4: the
 * choice"): a chunk of detail bands, with RANS4_MIN_NONZERO non-zeros under auto. */
static int use_rans4(const wvc2_level *L, int nused, uint64_t nonzero, int coder)
{
    return nused && L->bands[0] != 0 &&
           (coder == WVOL_WVC_CODER_RANS4 || (coder == WVOL_WVC_CODER_AUTO && nonzero >= RANS4_MIN_NONZERO));
}

int wvol__wvc2_job_code(wvc2_coded *out, wvc2_job *job, const wvc2_geom *g, int coder, int zstd_level,
                        wvc_rans_scratch *scratch, wvc2_job_pool *pool)
{
    const int m = job->m;
    const size_t *ext = job->ext;
    const wvc2_level *L = &g->lv[m];
    local_grid *lg = job->lg;
    const uint64_t *nzb = job->nzb;
    const uint8_t mask = job->mask;
    const int nused = job->nused;
    uint8_t *shared = NULL, *pay[8] = {0}, kind[8];
    size_t shared_len = 0, len[8] = {0}, zsum = 0;
    int i, failed = 0, use_rans = 0, rans_try, rans_alone;
    uint8_t *rans = NULL;
    size_t rans_len = 0;
    int32_t *Qs[8];
    const size_t *Ps[8];
    const wvc_band *Bs[8];
    int ns = 0;
    memset(out, 0, sizeof *out);
    out->nonzero = job->nonzero;
    /* --coder auto: mode 4 wherever it can code the chunk (detail bands only) and the chunk has
     * RANS4_MIN_NONZERO non-zeros, the decoder's speed first; other chunks as --coder compact */
    if (use_rans4(L, nused, out->nonzero, coder)) return job_code_rans4(out, job, L, scratch, pool);
    if (coder == WVOL_WVC_CODER_COMPACT || coder == WVOL_WVC_CODER_RANS4) coder = WVOL_WVC_CODER_AUTO;
    {
        uint64_t count = (uint64_t)L->nb * ext[0] * ext[1] * ext[2];
        int dense = (double)out->nonzero >= RANS_MIN_DENSITY * (double)count;
        rans_try = nused && L->bands[0] != 0 &&
                   (coder == WVOL_WVC_CODER_RANS || (coder == WVOL_WVC_CODER_AUTO && dense));
        rans_alone = coder == WVOL_WVC_CODER_RANS || out->nonzero >= RANS_ALONE_NONZERO;
    }
    /* the present bands, for the coders of one stream */
    for (i = 0; i < L->nb; i++)
        if (mask >> i & 1) Qs[ns] = lg[i].q, Ps[ns] = lg[i].p, Bs[ns] = &lg[i].b, ns++;
    if (rans_try) {
        if (wvol__wvc_rans_encode(&rans, &rans_len, ns, Qs, Ps, Bs, scratch)) failed = 1;
        out->alt_rans = rans_len;
    }
    if (!failed && nused && !(rans_try && rans_alone) && coder != WVOL_WVC_CODER_ZSTD) {
        if (wvol__wvc_cabac_encode_multi(&shared, &shared_len, ns, Qs, Ps, Bs, 1)) failed = 1;
        out->alt_cabac = shared_len;
    }
    /* the smaller of the two context coders */
    if (rans && (!shared || rans_len <= shared_len)) {
        free(shared);
        shared = rans;
        shared_len = rans_len;
        use_rans = 1;
    } else {
        free(rans);
    }
    rans = NULL;
    /* auto: all zstd when that is smaller (its matches win on small and regular bands) */
    if (!failed && nused && !(rans_try && rans_alone) && coder != WVOL_WVC_CODER_CABAC &&
        coder != WVOL_WVC_CODER_RANS) {
        for (i = 0; i < L->nb && !failed; i++)
            if (mask >> i & 1) {
                if (wvol__wvc_zstd_encode(&pay[i], &len[i], lg[i].q, lg[i].p, &lg[i].b, zstd_level,
                                          scratch ? &scratch->zstd : NULL))
                    failed = 1;
                kind[i] = WVOL_WVC_CODER_ZSTD;
                zsum += len[i];
            }
        out->alt_zstd = zsum;
    }
    /* compact: each band on its own where zstd is close, CABAC with its own model or zstd,
     * whichever is smaller (mode 0, version 1's choice per band): where the bands' statistics
     * differ (a piecewise-constant volume's Haar details, whose runs zstd matches along one
     * axis and not the others) one shared model costs more than the separate ones. Tried only
     * when all-zstd is within ZSTD_NEAR of the shared stream: elsewhere zstd loses on every
     * band and the second CABAC pass would be wasted. */
    if (!failed && shared && !use_rans && out->alt_zstd && (double)zsum <= ZSTD_NEAR * (double)shared_len) {
        size_t msum = 0;
        for (i = 0; i < L->nb && !failed; i++)
            if (mask >> i & 1) {
                uint8_t *cb = NULL;
                size_t cl = 0;
                if (wvol__wvc_cabac_encode(&cb, &cl, lg[i].q, lg[i].p, &lg[i].b)) {
                    free(cb);
                    failed = 1;
                } else if (cl < len[i]) {
                    free(pay[i]);
                    pay[i] = cb, len[i] = cl, kind[i] = WVOL_WVC_CODER_CABAC;
                } else {
                    free(cb);
                }
                msum += len[i];
            }
        zsum = msum;
    }
    wvol__wvc2_job_free(job, pool);
    if (!failed && nused) {
        uint8_t hdr[1 + 8 + 8 * 10], *p;
        size_t head = 0, total;
        int use_shared = shared && (!out->alt_zstd || shared_len + 2 <= zsum + 1 + (size_t)L->nb + 2 * (size_t)nused);
        hdr[head++] = (uint8_t)(use_shared ? (use_rans ? MODE_RANS : MODE_BLOCKS) : MODE_BANDS);
        if (use_shared) {
            hdr[head++] = mask;
            total = head + shared_len;
        } else {
            for (i = 0; i < L->nb; i++) hdr[head++] = (mask >> i & 1) ? kind[i] : WVOL_WVC_CODER_EMPTY;
            for (i = 0; i < L->nb; i++)
                if (mask >> i & 1) head += wvc2_put_varint(hdr + head, len[i]);
            total = head + zsum;
        }
        p = malloc(total);
        if (!p) {
            failed = 1;
        } else {
            memcpy(p, hdr, head);
            if (use_shared) {
                memcpy(p + head, shared, shared_len);
                /* per-band shares of one stream are not separable: split by non-zero counts */
                for (i = 0; i < L->nb; i++)
                    out->band_bytes[i] = (size_t)((double)shared_len * (double)nzb[i] / (double)out->nonzero);
            } else {
                size_t o = head;
                for (i = 0; i < L->nb; i++)
                    if (len[i]) memcpy(p + o, pay[i], len[i]), o += len[i], out->band_bytes[i] = len[i];
            }
            out->payload = p;
            out->bytes = total;
            out->crc = (uint32_t)crc32(0L, p, (uInt)total);
        }
    }
    free(shared);
    for (i = 0; i < 8; i++) free(pay[i]);
    if (failed) {
        free(out->payload);
        memset(out, 0, sizeof *out);
        return -1;
    }
    return 0;
}

/* A chunk in mode 4 coded where its rows lie (int32 boxes whose plane stride is a whole number
 * of rows), the parents through the bands' own pointers: the same stream as from a job's copy
 * (the coder reads the same values, the parent rows clamped to the parent region alike), without
 * the copy. 1 when the chunk is not such a chunk (the caller makes a job), else 0 or -1 as
 * rans4_payload. */
static int direct_rans4(wvc2_coded *out, const wvc2_geom *g, int m, const size_t ext[3], const wvc2_qbox child[8],
                        const wvc2_qbox parent[8], const uint64_t *nonzero, int coder, wvc_rans_scratch *scratch)
{
    const wvc2_level *L = &g->lv[m];
    wvc_band bands[8];
    size_t dims[8][3], zero[3] = {0, 0, 0}, poff[3], pext[3];
    int32_t *Qs[8];
    const size_t *Ps[8];
    const wvc_band *Bs[8];
    uint64_t total = 0;
    uint8_t mask = 0;
    int ns = 0;
    if (!nonzero) return 1;
    for (int i = 0; i < L->nb; i++)
        if (nonzero[i]) total += nonzero[i], mask |= (uint8_t)(1u << i), ns++;
    if (!use_rans4(L, ns, total, coder)) return 1;
    wvc2_parent_box(g, zero, ext, poff, pext);
    ns = 0;
    for (int i = 0; i < L->nb; i++) {
        const wvc2_qbox *c = &child[i], *pa = &parent[i];
        wvc_band *b = &bands[ns];
        if (!(mask >> i & 1)) continue;
        if (!c->q || c->sy < ext[0] || c->sz % c->sy || c->sz / c->sy < ext[1]) return 1;
        memset(b, 0, sizeof *b);
        b->level = m;
        b->band = L->bands[i];
        b->has_parent = m < g->levels && b->band != 0;
        if (b->has_parent && !pa->q) return 1;
        for (int a = 0; a < 3; a++) {
            b->ext[a] = ext[a];
            b->pext[a] = b->has_parent ? pext[a] : 0;
        }
        b->count = (uint64_t)ext[0] * ext[1] * ext[2];
        if (b->has_parent) b->pq = pa->q, b->psy = pa->sy, b->psz = pa->sz;
        dims[ns][0] = c->sy, dims[ns][1] = c->sz / c->sy, dims[ns][2] = ext[2];
        Qs[ns] = c->q, Ps[ns] = dims[ns], Bs[ns] = b;
        ns++;
    }
    memset(out, 0, sizeof *out);
    out->nonzero = total;
    return rans4_payload(out, L, mask, nonzero, ns, Qs, Ps, Bs, scratch);
}

int wvol__wvc2_chunk_encode(wvc2_coded *out, const wvc2_geom *g, int m, const size_t ext[3],
                            const wvc2_qbox child[8], const wvc2_qbox parent[8], const uint64_t *nonzero,
                            int coder, int zstd_level, wvc_rans_scratch *scratch, wvc2_job_pool *pool)
{
    wvc2_job job;
    int r = direct_rans4(out, g, m, ext, child, parent, nonzero, coder, scratch);
    if (r <= 0) return r;
    if (wvol__wvc2_job_make(&job, g, m, ext, child, parent, nonzero, pool)) {
        memset(out, 0, sizeof *out);
        return -1;
    }
    return wvol__wvc2_job_code(out, &job, g, coder, zstd_level, scratch, pool);
}

static void box_zero(const wvc2_qbox *b, const size_t ext[3])
{
    for (size_t z = 0; z < ext[2]; z++)
        for (size_t y = 0; y < ext[1]; y++) {
            const size_t o = y * b->sy + z * b->sz;
            if (b->q) memset(b->q + o, 0, ext[0] * sizeof(int32_t));
            else memset(b->q16 + o, 0, ext[0] * sizeof(int16_t));
        }
}

/* band i of a direct decode: the coder's view on the pyramid itself */
static void direct_view(local_grid *lg, const wvc2_geom *g, int m, int band, const size_t ext[3],
                        const wvc2_direct *d, int i)
{
    size_t zero[3] = {0, 0, 0}, poff[3], pext[3];
    int has_parent = m < g->levels && band != 0;
    wvc2_parent_box(g, zero, ext, poff, pext);
    memset(lg, 0, sizeof *lg);
    lg->q = d->Q;
    memcpy(lg->p, d->p, sizeof lg->p);
    lg->b.level = m;
    lg->b.band = band;
    lg->b.has_parent = has_parent;
    for (int a = 0; a < 3; a++) {
        lg->b.off[a] = d->off[i][a];
        lg->b.ext[a] = ext[a];
        lg->b.poff[a] = has_parent ? d->poff[i][a] : 0;
        lg->b.pext[a] = has_parent ? pext[a] : 0;
    }
    lg->b.count = (uint64_t)ext[0] * ext[1] * ext[2];
}

int wvol__wvc2_chunk_decode(const wvc2_geom *g, int m, const size_t ext[3], const wvc2_qbox child[8],
                            const wvc2_qbox parent[8], const wvc2_direct *direct, wvc2_scratch *scratch,
                            const uint8_t *payload, size_t bytes, uint64_t *nonzero, const char **why)
{
    const wvc2_level *L = &g->lv[m];
    local_grid lg[8];
    size_t len[8] = {0}, pos, sum = 0, at[8] = {0}, need = 0;
    uint8_t used = 0;
    int32_t *base = NULL;
    int i, r = 0, mode;
    *nonzero = 0;
    if (bytes == 0) {
        if (!direct)
            for (i = 0; i < L->nb; i++) box_zero(&child[i], ext);
        return 0;
    }
    mode = payload[0];
    pos = 1;
    if (mode == MODE_SHARED || mode == MODE_BLOCKS || mode == MODE_RANS || mode == MODE_RANS4) {
        if (bytes < 3) {
            *why = "chunk header truncated";
            return -1;
        }
        used = payload[pos++];
        if (!used || (used >> L->nb)) {
            *why = "chunk band mask is not valid";
            return -1;
        }
        if ((mode == MODE_RANS || mode == MODE_RANS4) && L->bands[0] == 0) {
            *why = mode == MODE_RANS ? "chunk mode 3 with the low-pass cube" : "chunk mode 4 with the low-pass cube";
            return -1;
        }
    } else if (mode == MODE_BANDS) {
        if (bytes < 1 + (size_t)L->nb) {
            *why = "chunk header truncated";
            return -1;
        }
        for (i = 0; i < L->nb; i++) {
            uint8_t k = payload[pos + (size_t)i];
            if (k > WVOL_WVC_CODER_ZSTD) {
                *why = "unknown band coder";
                return -1;
            }
            if (k) used |= (uint8_t)(1u << i);
        }
        pos += (size_t)L->nb;
        for (i = 0; i < L->nb; i++) {
            uint64_t v = 0;
            int shift = 0;
            if (!(used >> i & 1)) continue;
            for (;;) {
                uint8_t c;
                if (pos >= bytes || shift > 56) {
                    *why = "malformed band length";
                    return -1;
                }
                c = payload[pos++];
                v |= (uint64_t)(c & 0x7F) << shift;
                shift += 7;
                if (!(c & 0x80)) break;
            }
            if (v == 0 || v > bytes) {
                *why = "band length out of range";
                return -1;
            }
            len[i] = (size_t)v;
            sum += len[i];
        }
        if (sum != bytes - pos) {
            *why = "band lengths do not add up to the chunk";
            return -1;
        }
    } else {
        *why = "unknown chunk mode";
        return -1;
    }
    memset(lg, 0, sizeof lg);
    if (!direct) {
        /* the bands the payload leaves out are zero; the others are copied out whole below */
        for (i = 0; i < L->nb; i++)
            if (!(used >> i & 1)) box_zero(&child[i], ext);
        /* the used bands' local grids in one block, zeroed, then their parents copied in */
        for (i = 0; i < L->nb; i++)
            if (used >> i & 1) at[i] = need, need += local_init(&lg[i], g, m, L->bands[i], ext);
        if (scratch) {
            if (scratch->cap < need) {
                free(scratch->q);
                scratch->q = wvol__malloc_large(need * sizeof *scratch->q);
                scratch->cap = scratch->q ? need : 0;
            }
            base = scratch->q;
            if (base) memset(base, 0, need * sizeof *base);
        } else {
            base = calloc(need ? need : 1, sizeof *base);
        }
        if (!base) {
            *why = "out of memory";
            r = -1;
        }
    }
    for (i = 0; i < L->nb && !r; i++)
        if (used >> i & 1) {
            if (direct) {
                direct_view(&lg[i], g, m, L->bands[i], ext, direct, i);
            } else {
                lg[i].q = base + at[i];
                parent_in(&lg[i], &parent[i]);
            }
        }
    if (!r && mode != MODE_BANDS) {
        int32_t *Q[8];
        const size_t *P[8];
        const wvc_band *B[8];
        int k = 0;
        for (i = 0; i < L->nb; i++)
            if (used >> i & 1) Q[k] = lg[i].q, P[k] = lg[i].p, B[k] = &lg[i].b, k++;
        if (mode == MODE_RANS4)
            r = wvol__wvc_rans4_decode(k, Q, P, B, payload + pos, bytes - pos, WVC_RANS4_AUTO, nonzero, why);
        else if (mode == MODE_RANS)
            r = wvol__wvc_rans_decode(k, Q, P, B, payload + pos, bytes - pos, nonzero, why);
        else
            r = wvol__wvc_cabac_decode_multi(k, Q, P, B, payload + pos, bytes - pos, mode == MODE_BLOCKS, nonzero,
                                             why);
    } else if (!r) {
        for (i = 0; i < L->nb && !r; i++) {
            if (!(used >> i & 1)) continue;
            if (payload[1 + i] == WVOL_WVC_CODER_CABAC)
                r = wvol__wvc_cabac_decode(lg[i].q, lg[i].p, &lg[i].b, payload + pos, len[i], why);
            else
                r = wvol__wvc_zstd_decode(lg[i].q, lg[i].p, &lg[i].b, payload + pos, len[i], why);
            pos += len[i];
        }
    }
    /* the shared stream's coder counted the non-zeros; the per-band coders did not */
    for (i = 0; i < L->nb; i++) {
        uint64_t nz = 0;
        if (!r && (used >> i & 1) && direct && mode == MODE_BANDS) {
            for (size_t z = 0; z < ext[2]; z++)
                for (size_t y = 0; y < ext[1]; y++) {
                    const int32_t *s = lg[i].q + wvc_index(lg[i].p, &lg[i].b, 0, y, z);
                    for (size_t x = 0; x < ext[0]; x++) nz += s[x] != 0;
                }
        } else if (!r && (used >> i & 1) && !direct) {
            for (size_t z = 0; z < ext[2] && !r; z++)
                for (size_t y = 0; y < ext[1]; y++) {
                    const int32_t *s = lg[i].q + lg[i].p[0] * (y + lg[i].p[1] * z);
                    const size_t o = y * child[i].sy + z * child[i].sz;
                    if (child[i].q) {
                        int32_t *d = child[i].q + o;
                        for (size_t x = 0; x < ext[0]; x++) nz += (d[x] = s[x]) != 0;
                    } else if (wvc2_row_to_int16(child[i].q16 + o, s, ext[0], &nz)) {
                        *why = "a decoded value exceeds the chunk's maximum in the index";
                        r = -1;
                        break;
                    }
                }
        }
        if (mode == MODE_BANDS) *nonzero += nz;
    }
    if (!direct && !scratch) free(base);
    return r;
}
