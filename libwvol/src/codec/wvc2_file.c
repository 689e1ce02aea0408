/* SPDX-License-Identifier: MIT
 * An open .wvc file with a chunk cache bounded by a memory budget: chunks are read
 * (pread) and decoded on demand, each with its parent chunk (pinned while it is
 * decoded: the coder's context), kept as quantised int32 and dequantised as they are
 * gathered; least recently used chunks go first when the budget is reached. A
 * version-1 file (no index) is decoded whole at open. Region reads reconstruct
 * locally from the chunks their box needs (wavelet/wavelet_bricks.h). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sched.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/file_open.h"
#include "core/alloc.h"
#include "core/clock.h"
#include "core/clones.h"
#include "wvc2_read.h"
#include "wvc_dequant.h"
#include "wvc_format.h"
#include "wvc_source.h"

#define SPARE_SCRATCH 8

typedef struct centry {
    size_t id;
    int ref;
    struct centry *prev, *next; /* LRU list, most recent first */
    size_t bytes;
    size_t ext[3];
    void *q[8];                 /* per band of the level's list, ext[0] ext[1] ext[2] each */
    int es;                     /* their size: int32, or int16 where the index's maximum allows */
    unsigned char nz[8];        /* per band: any non-zero value */
} centry;

/* Marks a slot whose chunk one thread is decoding: the others wait for it rather than
 * decode the same chunk again (threads reconstructing parts of one region need the same
 * chunks at about the same time). */
static centry decoding_marker;
#define DECODING (&decoding_marker)

/* A source's context: the file, the levels skipped, where its gathers' errors go (NULL: the
 * file's own slot) */
typedef struct skip_ctx {
    wvol_wvc_file *f;
    int skip;
    wvc2_read_errors *E;
} skip_ctx;

struct wvol_wvc_file {
    char *path;
    int fd;
    wvol_wvc_info info;
    wvc2_index *x;              /* version 2 */
    wvol_coeffs *dense;         /* version 1: decoded whole */
    wvol__coef_source dense_src;
    skip_ctx skips[WVOL_WVC_MAX_LEVELS + 1];
    double o1[WVOL_WVC_MAX_SECTIONS], d2[WVOL_WVC_MAX_SECTIONS];
    int32_t *zeros;             /* a parent region of an all-zero chunk */
    /* the coarsest low-pass band's offset (wavelet_bricks.h, "DC offset"), under the lock;
     * found from the whole band on the first reconstruction (wvol__wvc_file_dc) */
    float dc;
    int dc_known;
    /* cache, under the lock */
    centry **slot;
    centry *mru, *lru;
    size_t budget, held, peak, chunk_max;
    size_t chain;               /* one decoded chunk per level: the least budget (format 2) */
    uint64_t decoded, decoded_narrow, hits, bytes_read;
    wvc2_read_errors errors;    /* the stores' reads' (wvc2_read.h) */
    /* reconstruction scratch kept between region reads (under the lock): a reader that
     * fills its output slab by slab reuses the same buffers instead of faulting in fresh
     * pages for every slab */
    wvol__brick_scratch spare[SPARE_SCRATCH];
    int spares;
    /* the chunk decoder's local grids, likewise kept between chunks (under the lock) */
    wvc2_scratch dspare[SPARE_SCRATCH];
    int dspares;
#ifdef _OPENMP
    omp_lock_t lock;
#endif
};

static void lock(wvol_wvc_file *f)
{
#ifdef _OPENMP
    omp_set_lock(&f->lock);
#else
    (void)f;
#endif
}

static void unlock(wvol_wvc_file *f)
{
#ifdef _OPENMP
    omp_unset_lock(&f->lock);
#else
    (void)f;
#endif
}

/* The first error of a read is kept for it in E (NULL: the file's slot), gathers and pins
 * being unable to return one. */
static void record(wvol_wvc_file *f, wvc2_read_errors *E, wvol_status s, const char *fmt, const char *a,
                   const char *b)
{
    wvc2_read_errors *T = E ? E : &f->errors;
    lock(f);
    if (T->status == WVOL_OK) {
        T->status = s;
        snprintf(T->message, sizeof T->message, fmt, a, b);
    }
    unlock(f);
}

wvol_status wvol__wvc_file_read_error(wvol_wvc_file *f, wvc2_read_errors *E, wvol_error *err)
{
    wvc2_read_errors *T = E ? E : &f->errors;
    wvol_status s;
    lock(f);
    s = T->status;
    if (s != WVOL_OK) wvol_error_set(err, s, "%s: %s", f->path, T->message);
    T->status = WVOL_OK;
    unlock(f);
    return s;
}

wvol_status wvol__wvc_file_error(wvol_wvc_file *f, wvol_error *err) { return wvol__wvc_file_read_error(f, NULL, err); }

/* The bytes an entry of chunk (m, t) holds resident with values of es bytes: the values in
 * whole huge pages (the cache's buffers are huge pages, which a decode fills whole) and the
 * entry itself. */
static size_t entry_size(const wvc2_geom *g, int m, const size_t t[3], size_t es)
{
    size_t off[3], ext[3];
    wvc2_tile_box(g, m, t, off, ext);
    return sizeof(centry) + wvol__pages_bytes(ext[0] * ext[1] * ext[2] * (size_t)g->lv[m].nb * es);
}

/* The budget's bound per chunk: its entry with int32 values. */
static size_t chunk_decoded_bytes(const wvc2_geom *g, int m, const size_t t[3])
{
    return entry_size(g, m, t, sizeof(int32_t));
}

/* The value size of chunk id's cache entry: int16 when the index's maximum bounds every
 * |q| by 32767 (half the memory a cache of int32 values fills and first-touches), int32
 * otherwise. chunk_decoded_bytes stays the budget's bound per chunk. */
static int entry_es(const wvol_wvc_file *f, size_t id)
{
    return wvc2_fits_int16(f->x->chunks[id].maxabs, f->x->step) ? (int)sizeof(int16_t) : (int)sizeof(int32_t);
}

/* The bytes chunk id's entry holds resident. */
static size_t entry_bytes(const wvol_wvc_file *f, size_t id)
{
    size_t t[3];
    int m = wvol__wvc2_chunk_coords(&f->x->g, id, t);
    return entry_size(&f->x->g, m, t, (size_t)entry_es(f, id));
}

void wvol_wvc_close(wvol_wvc_file *f)
{
    if (!f) return;
    if (f->slot && f->x)
        for (size_t i = 0; i < f->x->g.nchunks; i++)
            if (f->slot[i] && f->slot[i] != DECODING) {
                free(f->slot[i]->q[0]);
                free(f->slot[i]);
            }
    free(f->slot);
    for (int i = 0; i < f->spares; i++) wvol__brick_scratch_free(&f->spare[i]);
    for (int i = 0; i < f->dspares; i++) free(f->dspare[i].q);
    wvol__wvc2_index_free(f->x);
    wvol_coeffs_destroy(f->dense);
    free(f->zeros);
    if (f->fd >= 0) close(f->fd);
#ifdef _OPENMP
    omp_destroy_lock(&f->lock);
#endif
    free(f->path);
    free(f);
}

static int read_at(int fd, void *buf, size_t n, uint64_t off)
{
    uint8_t *p = buf;
    while (n) {
        ssize_t r = pread(fd, p, n, (off_t)off);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return -1;
        p += r, n -= (size_t)r, off += (uint64_t)r;
    }
    return 0;
}

/* Bytes of a version-1 file's whole decode. */
static size_t dense_bytes(const wvol_wvc_file *f)
{
    return f->dense->px * f->dense->py * f->dense->pz * sizeof(float);
}

/* Whether budget b holds what the file must hold at least: a version-1 file's whole decode, or
 * one chain of decoded chunks (one per level); at open and when the budget is set. */
static wvol_status budget_holds(const wvol_wvc_file *f, size_t b, wvol_error *err)
{
    if (f->dense)
        WVOL_RETURN_IF(dense_bytes(f) > b, err, WVOL_ERR_NOMEM,
                       "%s: a version-1 file is decoded whole (%zu bytes), more than the memory budget of %zu bytes; "
                       "recompress it (format 2) for reads within a budget",
                       f->path, dense_bytes(f), b);
    else
        WVOL_RETURN_IF(f->chain > b, err, WVOL_ERR_NOMEM,
                       "%s: memory budget of %zu bytes is below the %zu bytes one chain of decoded chunks (one per "
                       "level) needs",
                       f->path, b, f->chain);
    return WVOL_OK;
}

wvol_status wvol_wvc_open(wvol_wvc_file **out, const char *path, size_t budget, wvol_error *err)
{
    wvol_wvc_file *f;
    struct stat sb;
    uint8_t *h = NULL;
    size_t want;
    wvol_status st;
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "wvc open: missing argument");
    *out = NULL;
    f = calloc(1, sizeof *f);
    WVOL_RETURN_IF(!f, err, WVOL_ERR_NOMEM, "wvc open: out of memory");
    for (int s = 0; s <= WVOL_WVC_MAX_LEVELS; s++) /* the stores' sources' contexts, never written after */
        f->skips[s] = (skip_ctx){.f = f, .skip = s, .E = NULL};
#ifdef _OPENMP
    omp_init_lock(&f->lock);
#endif
    if (wvol__open_regular(&f->fd, path, err) != WVOL_OK) {
        wvol_status s = err ? err->status : WVOL_ERR_IO;
        wvol_wvc_close(f);
        return s;
    }
    f->path = strdup(path);
    f->budget = budget ? budget : WVOL_WVC_DEFAULT_BUDGET;
    if (!f->path) {
        wvol_wvc_close(f);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc open: out of memory");
    }
    if (fstat(f->fd, &sb) != 0) { /* a regular file (wvol__open_regular): its size */
        wvol_status s = wvol_error_set(err, WVOL_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
        wvol_wvc_close(f);
        return s;
    }
    /* the fixed header says how long the table and the index are */
    want = WVC2_HEADER_SIZE;
    h = malloc(want);
    if (!h || (uint64_t)sb.st_size < 16 || read_at(f->fd, h, (uint64_t)sb.st_size < want ? (size_t)sb.st_size : want, 0)) {
        free(h);
        wvol_wvc_close(f);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: not a .wvc file (too short or unreadable)", path);
    }
    if ((uint64_t)sb.st_size >= WVC2_HEADER_SIZE && h[8] == 2 && h[9] == 0) {
        uint64_t pre = wvol__wvc2_prefix_bytes(h, WVC2_HEADER_SIZE);
        if (pre > WVC2_HEADER_SIZE && pre <= (uint64_t)sb.st_size && pre <= SIZE_MAX) {
            uint8_t *nh = realloc(h, (size_t)pre);
            if (!nh || read_at(f->fd, nh, (size_t)pre, 0)) {
                free(nh ? nh : h);
                wvol_wvc_close(f);
                return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot read the chunk index", path);
            }
            h = nh;
            want = (size_t)pre;
        }
        /* the common header fields and the index, against the real file size */
        st = wvol__wvc_parse_prefix(&f->info, h, want, (uint64_t)sb.st_size, err);
        if (st == WVOL_OK) st = wvol__wvc2_parse(&f->info, &f->x, h, want, (uint64_t)sb.st_size, err);
        free(h);
        if (st != WVOL_OK) {
            wvol_error_prefix(err, "%s", path);
            wvol_wvc_close(f);
            return st;
        }
    } else {
        /* version 1 (or not a .wvc at all): no index, decoded whole if it fits */
        free(h);
        st = wvol_wvc_read(&f->dense, path, NULL, &f->info, err);
        if (st != WVOL_OK) {
            wvol_wvc_close(f);
            return st;
        }
        if ((st = budget_holds(f, f->budget, err)) != WVOL_OK) {
            wvol_wvc_close(f);
            return st;
        }
        f->held = f->peak = dense_bytes(f);
        wvol__coef_source_of_coeffs(&f->dense_src, f->dense);
        *out = f;
        return WVOL_OK;
    }
    {
        const wvc2_geom *g = &f->x->g;
        size_t chain = 0, zero_n = (size_t)g->tile[0] * (size_t)g->tile[1] * (size_t)g->tile[2];
        for (int m = g->levels; m >= 1; m--) {
            size_t t0[3] = {0, 0, 0}, b = chunk_decoded_bytes(g, m, t0);
            chain += b;
            if (b > f->chunk_max) f->chunk_max = b;
        }
        f->slot = calloc(g->nchunks ? g->nchunks : 1, sizeof *f->slot);
        f->zeros = calloc(zero_n, sizeof *f->zeros);
        if (!f->slot || !f->zeros) {
            wvol_wvc_close(f);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc open: out of memory");
        }
        f->chain = chain;
        if ((st = budget_holds(f, f->budget, err)) != WVOL_OK) {
            wvol_wvc_close(f);
            return st;
        }
    }
    for (int s = 0; s < f->info.nsections; s++) {
        f->o1[s] = (1.0 + (double)f->x->d1[s]) * f->info.step;
        f->d2[s] = f->x->d2[s];
    }
    *out = f;
    return WVOL_OK;
}

const char *wvol__wvc_file_path(const wvol_wvc_file *f) { return f->path; }

const wvol_wvc_info *wvol_wvc_file_info(const wvol_wvc_file *f) { return f ? &f->info : NULL; }

const char *wvol_wvc_chunk_mode_name(int k)
{
    static const char *const names[WVOL_WVC_CHUNK_MODES] = {"bands_apart", "cabac", "cabac_blocks",
                                                            "rans",        "rans4", "empty"};
    return k >= 0 && k < WVOL_WVC_CHUNK_MODES ? names[k] : NULL;
}

wvol_status wvol_wvc_file_chunk_modes(wvol_wvc_file *f, uint64_t counts[][WVOL_WVC_CHUNK_MODES], wvol_error *err)
{
    WVOL_RETURN_IF(!f || !counts, err, WVOL_ERR_ARG, "wvc: missing argument");
    memset(counts, 0, (size_t)(f->info.levels + 1) * sizeof *counts);
    if (!f->x) return WVOL_OK; /* version 1 */
    for (size_t id = 0; id < f->x->g.nchunks; id++) {
        const wvc2_chunk *c = &f->x->chunks[id];
        size_t t[3];
        const int m = wvol__wvc2_chunk_coords(&f->x->g, id, t);
        uint8_t mode = WVOL_WVC_CHUNK_MODES - 1;
        if (c->bytes) {
            const int unread = read_at(f->fd, &mode, 1, c->offset) != 0;
            if (unread || mode >= WVOL_WVC_CHUNK_MODES - 1) {
                char d[96];
                wvol__wvc2_describe(d, sizeof d, f->x, id);
                if (unread) return wvol_error_set(err, WVOL_ERR_IO, ".wvc %s: cannot read its first byte", d);
                return wvol_error_set(err, WVOL_ERR_FORMAT, ".wvc %s: unknown chunk mode %d", d, mode);
            }
        }
        counts[m][mode]++;
    }
    return WVOL_OK;
}

void wvol_wvc_file_stats(const wvol_wvc_file *f, wvol_wvc_cache_stats *st)
{
    if (!st) return;
    memset(st, 0, sizeof *st);
    if (!f) return;
    lock((wvol_wvc_file *)f);
    st->budget = f->budget;
    st->held = f->held;
    st->peak = f->peak;
    st->chunk_bytes = f->chunk_max;
    st->decoded = f->decoded;
    st->decoded_narrow = f->decoded_narrow;
    st->hits = f->hits;
    st->bytes_read = f->bytes_read;
    unlock((wvol_wvc_file *)f);
}

/* ---- the cache ------------------------------------------------------------------- */

static void lru_unlink(wvol_wvc_file *f, centry *e)
{
    if (e->prev) e->prev->next = e->next;
    else f->mru = e->next;
    if (e->next) e->next->prev = e->prev;
    else f->lru = e->prev;
    e->prev = e->next = NULL;
}

static void lru_front(wvol_wvc_file *f, centry *e)
{
    e->next = f->mru;
    e->prev = NULL;
    if (f->mru) f->mru->prev = e;
    f->mru = e;
    if (!f->lru) f->lru = e;
}

static void release(wvol_wvc_file *f, centry *e)
{
    if (!e) return;
    lock(f);
    e->ref--;
    unlock(f);
}

/* Under the lock: drops unpinned chunks, least recent first, until `need` more bytes fit
 * the budget beside what is held. With reuse (before a chunk of decoded size `need` is
 * decoded), the first dropped entry of that size hands its values buffer back in *reuse
 * instead of freeing it (the interior tiles of a level all have one size; the accounting
 * stays that of a fresh buffer): the new chunk then fills pages already mapped instead of
 * faulting in fresh ones, and the cache holds at most the budget while it decodes. */
static void evict_for(wvol_wvc_file *f, size_t need, void **reuse)
{
    centry *e = f->lru;
    while (f->held + need > f->budget && e) {
        centry *prev = e->prev;
        if (e->ref == 0) {
            lru_unlink(f, e);
            f->slot[e->id] = NULL;
            f->held -= e->bytes;
            if (reuse && !*reuse && e->bytes == need) *reuse = e->q[0];
            else free(e->q[0]);
            free(e);
        }
        e = prev;
    }
}

/* Under the lock: the same, until the budget holds. */
static void evict(wvol_wvc_file *f)
{
    evict_for(f, 0, NULL);
}

static centry *get_chunk(wvol_wvc_file *f, wvc2_read_errors *E, size_t id);

/* Scratch kept between reads: a pool of at most SPARE_SCRATCH items of `size` bytes at
 * `pool` (*n of them), under the lock. take copies one out, or zeros when the pool is
 * empty; give keeps the item and returns 1, or returns 0 when the pool is full (the
 * caller then frees it). */
static void pool_take(wvol_wvc_file *f, void *pool, int *n, size_t size, void *item)
{
    lock(f);
    if (*n > 0) memcpy(item, (char *)pool + (size_t)--*n * size, size);
    else memset(item, 0, size);
    unlock(f);
}

static int pool_give(wvol_wvc_file *f, void *pool, int *n, size_t size, const void *item)
{
    int kept = 0;
    lock(f);
    if (*n < SPARE_SCRATCH) {
        memcpy((char *)pool + (size_t)(*n)++ * size, item, size);
        kept = 1;
    }
    unlock(f);
    return kept;
}

/* Reads and decodes chunk id (not all zero) into a new entry; reuse, when not NULL, is a
 * buffer of its decoded values' size (evict_for) that the entry takes (freed on failure). */
static centry *decode_chunk(wvol_wvc_file *f, wvc2_read_errors *E, size_t id, void *reuse)
{
    const wvc2_geom *g = &f->x->g;
    const wvc2_chunk *c = &f->x->chunks[id];
    size_t t[3], off[3], ext[3], poff[3], pext[3], n;
    int m = wvol__wvc2_chunk_coords(g, id, t), nb = g->lv[m].nb;
    centry *e = NULL, *P = NULL;
    wvc2_qbox child[8], parent[8];
    uint8_t *pay = NULL;
    uint64_t nz = 0;
    const char *why = NULL;
    char d[96];
    wvc2_tile_box(g, m, t, off, ext);
    wvc2_parent_box(g, off, ext, poff, pext);
    memset(parent, 0, sizeof parent);
    memset(child, 0, sizeof child);
    if (m < g->levels) {
        size_t pt[3], pid, po[3], pe[3];
        const wvc2_level *PG = &g->lv[m + 1];
        for (int a = 0; a < 3; a++) pt[a] = poff[a] / (size_t)g->tile[a];
        pid = wvc2_chunk_id(g, m + 1, pt);
        wvc2_tile_box(g, m + 1, pt, po, pe);
        if (f->x->chunks[pid].bytes) {
            P = get_chunk(f, E, pid);
            if (!P) {
                free(reuse);
                return NULL;
            }
        }
        for (int k = 0; k < nb; k++) {
            int pk = 0;
            while (PG->bands[pk] != g->lv[m].bands[k]) pk++;
            if (P) {
                const size_t o = (poff[0] - po[0]) + pe[0] * ((poff[1] - po[1]) + pe[1] * (poff[2] - po[2]));
                if (P->es == sizeof(int16_t)) parent[k].q16 = (int16_t *)P->q[pk] + o;
                else parent[k].q = (int32_t *)P->q[pk] + o;
                parent[k].sy = pe[0];
                parent[k].sz = pe[0] * pe[1];
            } else {
                parent[k].q = f->zeros;
                parent[k].sy = pext[0];
                parent[k].sz = pext[0] * pext[1];
            }
        }
    }
    n = ext[0] * ext[1] * ext[2];
    e = calloc(1, sizeof *e);
    pay = malloc(c->bytes);
    if (e) {
        size_t vb;
        e->es = entry_es(f, id);
        vb = n * (size_t)nb * (size_t)e->es;
        e->q[0] = reuse ? reuse : wvol__malloc_pages(&vb);
        reuse = NULL;
    }
    free(reuse);
    if (!e || !pay || !e->q[0]) {
        if (e) free(e->q[0]);
        free(e);
        free(pay);
        release(f, P);
        record(f, E, WVOL_ERR_NOMEM, "out of memory decoding a chunk%s%s", "", "");
        return NULL;
    }
    for (int k = 0; k < nb; k++) {
        e->q[k] = (char *)e->q[0] + (size_t)k * n * (size_t)e->es;
        if (e->es == sizeof(int16_t)) child[k].q16 = e->q[k];
        else child[k].q = e->q[k];
        child[k].sy = ext[0];
        child[k].sz = ext[0] * ext[1];
    }
    wvol__wvc2_describe(d, sizeof d, f->x, id);
    if (read_at(f->fd, pay, c->bytes, c->offset)) {
        why = "cannot read the chunk (file shorter than its index says?)";
    } else if (wvol__wvc2_chunk_check(f->x, id, pay, &why) == 0) {
        wvc2_scratch scr;
        pool_take(f, f->dspare, &f->dspares, sizeof scr, &scr);
        if (wvol__wvc2_chunk_decode(g, m, ext, child, parent, NULL, &scr, pay, c->bytes, &nz, &why) == 0 &&
            nz != c->nonzero)
            why = "decoded non-zero count does not match the index";
        if (!pool_give(f, f->dspare, &f->dspares, sizeof scr, &scr)) free(scr.q);
    }
    free(pay);
    release(f, P);
    if (why) {
        record(f, E, WVOL_ERR_FORMAT, ".wvc %s: %s", d, why);
        free(e->q[0]);
        free(e);
        return NULL;
    }
    for (int k = 0; k < nb; k++) {
        int32_t any = 0;
        if (e->es == sizeof(int16_t))
            for (size_t i = 0; i < n; i++) any |= ((const int16_t *)e->q[k])[i];
        else
            for (size_t i = 0; i < n; i++) any |= ((const int32_t *)e->q[k])[i];
        e->nz[k] = any != 0;
    }
    e->id = id;
    memcpy(e->ext, ext, sizeof ext);
    e->bytes = entry_bytes(f, id);
    return e;
}

/* The decoded chunk id, pinned (release it), or NULL after recording an error. The
 * chunk must not be all zero (index bytes 0). */
static centry *get_chunk(wvol_wvc_file *f, wvc2_read_errors *E, size_t id)
{
    centry *e, *mine;
    void *reuse = NULL;
    int over;
    size_t budget;
    lock(f);
    while ((e = f->slot[id]) == DECODING) {
        unlock(f);
        sched_yield();
        lock(f);
    }
    if (e) {
        e->ref++;
        f->hits++;
        lru_unlink(f, e);
        lru_front(f, e);
        unlock(f);
        return e;
    }
    evict_for(f, entry_bytes(f, id), &reuse);
    f->slot[id] = DECODING;
    unlock(f);
    mine = decode_chunk(f, E, id, reuse);
    lock(f);
    if (!mine) {
        f->slot[id] = NULL;
        unlock(f);
        return NULL;
    }
    f->decoded++;
    f->decoded_narrow += mine->es == (int)sizeof(int16_t);
    f->bytes_read += f->x->chunks[id].bytes;
    mine->ref = 1;
    f->slot[id] = mine;
    lru_front(f, mine);
    f->held += mine->bytes;
    evict(f);
    if (f->held > f->peak) f->peak = f->held;
    /* read under the lock: another thread's insertion raises held before its own eviction */
    over = f->held > f->budget;
    budget = f->budget;
    unlock(f);
    if (over) {
        char b[64];
        snprintf(b, sizeof b, "%zu", budget);
        record(f, E, WVOL_ERR_NOMEM,
               "memory budget of %s bytes exceeded by the chunks one request holds at once%s (raise --memory)", b,
               "");
    }
    return mine;
}

void *wvol__wvc_file_pin(wvol_wvc_file *f, wvc2_read_errors *E, size_t id, void *const **q, int *es)
{
    centry *e = get_chunk(f, E, id);
    if (e && q) *q = e->q;
    if (e && es) *es = e->es;
    return e;
}

void wvol__wvc_file_unpin(wvol_wvc_file *f, void *pinned) { release(f, pinned); }

const wvc2_index *wvol__wvc_file_index(const wvol_wvc_file *f) { return f ? f->x : NULL; }

size_t wvol__wvc_file_pin_need(const wvol_wvc_file *f, int pinned)
{
    return f->chain + (size_t)(pinned > 0 ? pinned : 0) * f->chunk_max;
}

/* Outside the lock a budget is read atomically: wvol_wvc_set_budget may change it while a read
 * is in progress (the Python module holds no lock of its own around reads). */
static size_t budget_now(const wvol_wvc_file *f)
{
    size_t b;
#pragma omp atomic read
    b = f->budget;
    return b;
}

size_t wvol__wvc_file_budget(const wvol_wvc_file *f) { return budget_now(f); }

/* ---- gathering ------------------------------------------------------------------- */

/* Pins of one gather: a few recent chunks stay pinned while a region is copied. */
#define PINS 8
typedef struct pins {
    centry *e[PINS];
    size_t n, next;
    wvc2_read_errors *E; /* the gather's read's */
} pins;

static centry *pin(wvol_wvc_file *f, pins *p, size_t id)
{
    for (size_t i = 0; i < p->n; i++)
        if (p->e[i]->id == id) return p->e[i];
    centry *e = get_chunk(f, p->E, id);
    if (!e) return NULL;
    if (p->n < PINS) {
        p->e[p->n++] = e;
    } else {
        release(f, p->e[p->next]);
        p->e[p->next] = e;
        p->next = (p->next + 1) % PINS;
    }
    return e;
}

static void unpin_all(wvol_wvc_file *f, pins *p)
{
    for (size_t i = 0; i < p->n; i++) release(f, p->e[i]);
    p->n = 0;
}

static ptrdiff_t pmod(ptrdiff_t a, ptrdiff_t n)
{
    ptrdiff_t r = a % n;
    return r < 0 ? r + n : r;
}

/* Whether band k of level m may have a non-zero value in the region (lo, n), taken
 * periodically: some chunk there is non-empty and has a non-zero value in the band (its
 * chunks decoded and pinned for the copy that follows). Regions meeting more tiles than
 * fit the table answer yes without looking. */
#define MAX_TILE_RUN 64
static int band_may_be_nonzero(wvol_wvc_file *f, pins *P, int m, int k, const ptrdiff_t lo[3], const ptrdiff_t n[3])
{
    const wvc2_geom *g = &f->x->g;
    const wvc2_level *G = &g->lv[m];
    size_t tl[3][MAX_TILE_RUN], nt[3];
    for (int a = 0; a < 3; a++) {
        /* the tiles the positions lo .. lo + n - 1 (wrapped) meet, in order, each once */
        const ptrdiff_t e = (ptrdiff_t)G->e[a], T = (ptrdiff_t)g->tile[a];
        ptrdiff_t left = n[a], x = pmod(lo[a], e);
        nt[a] = 0;
        if (n[a] >= e) left = e, x = 0; /* the whole period */
        while (left > 0) {
            ptrdiff_t run = T - x % T;
            if (x + run > e) run = e - x;
            if (nt[a] == MAX_TILE_RUN) return 1;
            tl[a][nt[a]++] = (size_t)(x / T);
            left -= run;
            x += run;
            if (x == e) x = 0;
        }
    }
    for (size_t z = 0; z < nt[2]; z++)
        for (size_t y = 0; y < nt[1]; y++)
            for (size_t x = 0; x < nt[0]; x++) {
                const size_t tc[3] = {tl[0][x], tl[1][y], tl[2][z]};
                const size_t id = wvc2_chunk_id(g, m, tc);
                const centry *e;
                if (!f->x->chunks[id].bytes) continue;
                e = pin(f, P, id);
                if (!e || e->nz[k]) return 1; /* a chunk that does not decode: the copy records it */
            }
    return 0;
}

/* wvc2_read.h. The full decoder's arithmetic (wvc_dequant.h), so values are bit-equal to
 * it, without a branch per value: every lane computes (|v| + d2) * step and the selects
 * pick o1 for +-1 and +0 for 0 (a branch on each zero mispredicted wherever the zeros and
 * non-zeros of a sparse band mix), so the loop vectorises. Contraction off: (|v| + d2) *
 * step is rounded twice, as the decoder rounds it; no trapping math: without it GCC keeps a
 * branch so as not to compute the unused lane's value, which cannot trap here (no FP
 * exceptions are enabled, and each lane's value is finite). */
#define WVC_DEQUANT_RUN(name, T)                                                                               \
    WVOL__CLONES WVOL__NO_CONTRACT_NO_TRAP int name(                                                              \
        float *restrict dst, const T *restrict q, size_t n, double o1, double d2, double step)                    \
    {                                                                                                             \
        const float f1 = (float)o1;                                                                               \
        int32_t any = 0;                                                                                          \
        for (size_t i = 0; i < n; i++) {                                                                          \
            const int32_t v = q[i];                                                                               \
            dst[i] = wvc_dequant1(v, f1, d2, step);                                                               \
            any |= v;                                                                                             \
        }                                                                                                         \
        return any != 0;                                                                                          \
    }
WVC_DEQUANT_RUN(wvol__wvc_dequant_run, int32_t)
WVC_DEQUANT_RUN(wvol__wvc_dequant_run16, int16_t)
#undef WVC_DEQUANT_RUN

int wvol__wvc_dequant_any(float *dst, const void *q, int es, size_t at, size_t n, double o1, double d2, double step)
{
    if (es == (int)sizeof(int16_t)) return wvol__wvc_dequant_run16(dst, (const int16_t *)q + at, n, o1, d2, step);
    return wvol__wvc_dequant_run(dst, (const int32_t *)q + at, n, o1, d2, step);
}

static int gather_chunks(const void *ctx, float *dst, int mm, int band, const ptrdiff_t lo[3], const ptrdiff_t n[3])
{
    const skip_ctx *sc = ctx;
    wvol_wvc_file *f = sc->f;
    const wvc2_geom *g = &f->x->g;
    int m = mm + sc->skip, any = 0, k = -1;
    const wvc2_level *G;
    size_t t = 0, total = (size_t)(n[0] * n[1] * n[2]);
    double o1, d2, step = f->info.step;
    pins P;
    if (mm == 0) m = g->levels, band = 0; /* a pyramid of no levels: the low-pass cube */
    G = &g->lv[m];
    for (int i = 0; i < G->nb; i++)
        if (G->bands[i] == band) k = i;
    if (k < 0) return 0;
    {
        int s = wvc2_section(g->levels, m, band);
        o1 = f->o1[s];
        d2 = f->d2[s];
    }
    memset(&P, 0, sizeof P);
    P.E = sc->E;
    if (!band_may_be_nonzero(f, &P, m, k, lo, n)) {
        unpin_all(f, &P);
        return 0; /* every chunk there is empty or has this band all zero: the caller skips it */
    }
    for (ptrdiff_t zk = 0; zk < n[2]; zk++) {
        size_t z = (size_t)pmod(lo[2] + zk, (ptrdiff_t)G->e[2]);
        for (ptrdiff_t yj = 0; yj < n[1]; yj++) {
            size_t y = (size_t)pmod(lo[1] + yj, (ptrdiff_t)G->e[1]);
            ptrdiff_t left = n[0];
            size_t x = (size_t)pmod(lo[0], (ptrdiff_t)G->e[0]);
            while (left > 0) {
                size_t tc[3] = {x / (size_t)g->tile[0], y / (size_t)g->tile[1], z / (size_t)g->tile[2]};
                size_t id = wvc2_chunk_id(g, m, tc), tx0 = tc[0] * (size_t)g->tile[0];
                size_t run = (size_t)g->tile[0] - (x - tx0);
                if (x + run > G->e[0]) run = G->e[0] - x;
                if ((ptrdiff_t)run > left) run = (size_t)left;
                if (!f->x->chunks[id].bytes) {
                    memset(dst + t, 0, run * sizeof *dst);
                } else {
                    centry *e = pin(f, &P, id);
                    if (!e) {
                        memset(dst + t, 0, run * sizeof *dst);
                    } else {
                        const size_t o = (x - tx0) + e->ext[0] * ((y - tc[1] * (size_t)g->tile[1]) +
                                                                  e->ext[1] * (z - tc[2] * (size_t)g->tile[2]));
                        any |= wvol__wvc_dequant_any(dst + t, e->q[k], e->es, o, run, o1, d2, step);
                    }
                }
                t += run;
                left -= (ptrdiff_t)run;
                x += run;
                if (x == G->e[0]) x = 0;
            }
        }
    }
    unpin_all(f, &P);
    (void)total;
    return any;
}

static int gather_dense_skip(const void *ctx, float *dst, int mm, int band, const ptrdiff_t lo[3],
                             const ptrdiff_t n[3])
{
    const skip_ctx *sc = ctx;
    int m = mm == 0 ? sc->f->dense->levels : mm + sc->skip;
    return sc->f->dense_src.gather(sc->f->dense_src.ctx, dst, m, mm == 0 ? 0 : band, lo, n);
}

/* A source for one read, whose gathers record their errors in E through ctx (the caller's). */
static void read_source(wvol__coef_source *src, skip_ctx *ctx, wvol_wvc_file *f, int skip, wvc2_read_errors *E)
{
    wvol__wvc_file_source(src, f, skip);
    *ctx = (skip_ctx){.f = f, .skip = skip, .E = E};
    src->ctx = ctx;
}

void wvol__wvc_file_source(wvol__coef_source *src, wvol_wvc_file *f, int skip)
{
    const wvol_filter *flt = NULL;
    size_t n[3] = {f->info.nx, f->info.ny, f->info.nz}, p[3] = {f->info.px, f->info.py, f->info.pz};
    memset(src, 0, sizeof *src);
    wvol_filter_get(&flt, f->info.filter, NULL);
    src->gather = f->dense ? gather_dense_skip : gather_chunks;
    src->ctx = &f->skips[skip];
    lock(f);
    src->dc = f->dc;
    unlock(f);
    src->filter = flt;
    src->levels = f->info.levels - skip;
    for (int a = 0; a < 3; a++) {
        src->dims[a] = p[a] > 1 ? (n[a] + ((size_t)1 << skip) - 1) >> skip : 1;
        src->pad[a] = p[a] > 1 ? p[a] >> skip : 1;
    }
}

/* The band's offset found: kept for the sources made after (under the lock). */
static float dc_set(wvol_wvc_file *f, float dc)
{
    lock(f);
    f->dc = dc;
    f->dc_known = 1;
    unlock(f);
    return dc;
}

/* No offset worth finding: no levels (nothing is synthesised), or the data's own range near 0
 * against its spread, where what taking one out gains is below float32's rounding of the
 * spread (and not worth decoding the band for). */
static int dc_ruled_out(const wvol_wvc_file *f)
{
    return f->info.levels == 0 || wvol__band_range_offset(f->info.value_min, f->info.value_max) == 0.0f;
}

wvol_status wvol__wvc_file_lowpass(wvol_wvc_file *f, float *dst, wvol_error *err)
{
    wvol__coef_source src;
    skip_ctx ctx;
    wvc2_read_errors E = {0};
    ptrdiff_t lo[3] = {0, 0, 0}, n[3];
    size_t e[3];
    wvol_status st;
    read_source(&src, &ctx, f, 0, &E);
    for (int a = 0; a < 3; a++) {
        n[a] = (ptrdiff_t)(src.pad[a] > 1 ? src.pad[a] >> f->info.levels : 1);
        e[a] = (size_t)n[a];
    }
    if (!src.gather(src.ctx, dst, f->info.levels, 0, lo, n))
        memset(dst, 0, (size_t)(n[0] * n[1] * n[2]) * sizeof *dst);
    st = wvol__wvc_file_read_error(f, &E, err);
    if (st == WVOL_OK) (void)dc_set(f, dc_ruled_out(f) ? 0.0f : wvol__lowpass_offset(dst, e, 0)); /* band at hand */
    return st;
}

wvol_status wvol__wvc_file_dc(wvol_wvc_file *f, float *dc, wvol_error *err)
{
    wvol__coef_source src;
    skip_ctx ctx;
    wvc2_read_errors E = {0};
    const wvc2_geom *g;
    double lo = INFINITY, hi = -INFINITY;
    size_t t[3], cap;
    float *tile, v;
    wvol_status st = WVOL_OK;
    int known;
    lock(f);
    known = f->dc_known;
    v = f->dc;
    unlock(f);
    if (!known) {
        if (dc_ruled_out(f)) v = dc_set(f, 0.0f);
        else if (f->dense) /* version 1 holds the band in memory */
            v = dc_set(f, wvol__lowpass_offset(f->dense->data, (size_t[3]){f->dense->px, f->dense->py, f->dense->pz},
                                               f->info.levels));
        else
            known = -1;
    }
    if (known >= 0) {
        if (dc) *dc = v;
        return WVOL_OK;
    }
    /* tile by tile: a read under the least budget pins one chunk at a time */
    g = &f->x->g;
    cap = (size_t)g->tile[0] * (size_t)g->tile[1] * (size_t)g->tile[2];
    tile = malloc(cap * sizeof *tile);
    WVOL_RETURN_IF(!tile, err, WVOL_ERR_NOMEM, "%s: out of memory for a tile of the low-pass band", f->path);
    read_source(&src, &ctx, f, 0, &E);
    for (t[2] = 0; t[2] < g->lv[g->levels].nt[2] && st == WVOL_OK; t[2]++)
        for (t[1] = 0; t[1] < g->lv[g->levels].nt[1] && st == WVOL_OK; t[1]++)
            for (t[0] = 0; t[0] < g->lv[g->levels].nt[0] && st == WVOL_OK; t[0]++) {
                ptrdiff_t b0[3], bn[3];
                size_t cnt = 1;
                for (int a = 0; a < 3; a++) {
                    const size_t T = (size_t)g->tile[a], x0 = t[a] * T, e = g->lv[g->levels].e[a];
                    b0[a] = (ptrdiff_t)x0;
                    bn[a] = (ptrdiff_t)(x0 + T < e ? T : e - x0);
                    cnt *= (size_t)bn[a];
                }
                if (!src.gather(src.ctx, tile, g->levels, 0, b0, bn)) memset(tile, 0, cnt * sizeof *tile);
                st = wvol__wvc_file_read_error(f, &E, err);
                for (size_t i = 0; i < cnt && st == WVOL_OK; i++) {
                    lo = tile[i] < lo ? tile[i] : lo;
                    hi = tile[i] > hi ? tile[i] : hi;
                }
            }
    free(tile);
    if (st != WVOL_OK) return st;
    v = dc_set(f, wvol__band_range_offset(lo, hi));
    if (dc) *dc = v;
    return WVOL_OK;
}

void wvol__wvc_file_level_max(const wvol_wvc_file *f, int m, float *max, size_t nt[3], size_t tile[3])
{
    const wvc2_geom *g;
    if (f->dense) {
        /* version 1: one "tile" per level, the maximum over its detail bands */
        const wvol_coeffs *c = f->dense;
        size_t p[3] = {c->px, c->py, c->pz};
        float mx = 0;
        for (int a = 0; a < 3; a++) {
            nt[a] = 1;
            tile[a] = p[a] > 1 ? p[a] >> m : 1;
        }
        if (!max) return;
        for (int band = 1; band < 8; band++)
            for (size_t z = 0; z < tile[2]; z++)
                for (size_t y = 0; y < tile[1]; y++)
                    for (size_t x = 0; x < tile[0]; x++) {
                        size_t idx = wvol_coeffs_index(c, m, band, x, y, z);
                        if (idx != (size_t)-1 && fabsf(c->data[idx]) > mx) mx = fabsf(c->data[idx]);
                    }
        max[0] = mx;
        return;
    }
    g = &f->x->g;
    for (int a = 0; a < 3; a++) {
        nt[a] = g->lv[m].nt[a];
        tile[a] = (size_t)g->tile[a];
    }
    if (max)
        for (size_t i = 0; i < g->lv[m].count; i++) max[i] = f->x->chunks[g->lv[m].first + i].maxabs;
}

wvol_status wvol_wvc_level_geometry(const wvol_wvc_info *info, int level, size_t grid[3], double spacing[3],
                                    double origin[3], wvol_error *err)
{
    const wvol_filter *flt;
    WVOL_RETURN_IF(!info, err, WVOL_ERR_ARG, "wvc level geometry: missing file info");
    WVOL_RETURN_IF(level < 0 || level > info->levels, err, WVOL_ERR_ARG,
                   "wvc level geometry: level %d outside 0..%d", level, info->levels);
    WVOL_FORWARD(wvol_filter_get(&flt, info->filter, err));
    {
        const size_t n[3] = {info->nx, info->ny, info->nz}, p[3] = {info->px, info->py, info->pz};
        for (int a = 0; a < 3; a++) {
            const int halved = p[a] > 1;
            if (grid) grid[a] = halved ? (n[a] + ((size_t)1 << level) - 1) >> level : n[a];
            if (spacing) spacing[a] = info->spacing[a] * ldexp(1.0, halved ? level : 0);
            if (origin) origin[a] = info->origin[a] + (halved ? info->spacing[a] * wvol_level_offset(flt, level) : 0);
        }
    }
    return WVOL_OK;
}

/* Spacing and origin of the box starting at lo in level `level`'s grid (a level the
 * caller has checked), and the factor 2^{-s/2} per transformed axis that
 * wvol_idwt3_level applies to that level's low-pass. */
static void region_geometry(const wvol_wvc_file *f, int level, const size_t lo[3], double spacing[3],
                            double origin[3], double *scale)
{
    const size_t p[3] = {f->info.px, f->info.py, f->info.pz};
    (void)wvol_wvc_level_geometry(&f->info, level, NULL, spacing, origin, NULL);
    *scale = 1.0;
    for (int a = 0; a < 3; a++) {
        if (p[a] > 1) *scale *= pow(2.0, -0.5 * level);
        origin[a] += spacing[a] * (double)lo[a];
    }
}

static void scratch_take(wvol_wvc_file *f, wvol__brick_scratch *scr)
{
    pool_take(f, f->spare, &f->spares, sizeof *scr, scr);
}

static void scratch_give(wvol_wvc_file *f, wvol__brick_scratch *scr)
{
    if (!pool_give(f, f->spare, &f->spares, sizeof *scr, scr)) wvol__brick_scratch_free(scr);
}

/* Reconstructs the box [lo, hi) of source src into dst with `threads` threads, each a
 * part of the box along y (its own scratch and buffer, copied into dst's rows): the parts
 * share their z range, so they need the same rows of chunks at the same time and the
 * shared cache (under its lock) decodes each chunk once. */
static wvol_status reconstruct_parts(wvol_wvc_file *f, float *dst, const wvol__coef_source *src,
                                     const size_t lo[3], const size_t hi[3], int threads, wvol_error *err)
{
    size_t nx = hi[0] - lo[0], ny = hi[1] - lo[1], nz = hi[2] - lo[2];
    wvol_status st = WVOL_OK;
    int nt = wvol__threads(threads);
    /* a part thinner than a few rows would repeat the filters' margins for little work */
    if ((size_t)nt > ny / 8) nt = ny / 8 > 0 ? (int)(ny / 8) : 1;
    if (nt == 1) {
        wvol__brick_scratch scr;
        scratch_take(f, &scr);
        st = wvol__idwt3_brick_src(dst, src, lo, hi, &scr, err);
        scratch_give(f, &scr);
        return st;
    }
#ifdef _OPENMP
#pragma omp parallel num_threads(nt)
    {
        int t = omp_get_thread_num();
        size_t y0 = lo[1] + ny * (size_t)t / (size_t)nt, y1 = lo[1] + ny * (size_t)(t + 1) / (size_t)nt;
        size_t l[3] = {lo[0], y0, lo[2]}, h[3] = {hi[0], y1, hi[2]}, rows = y1 - y0;
        float *part = malloc(nx * rows * nz * sizeof *part);
        wvol__brick_scratch scr;
        wvol_error e;
        wvol_status s = WVOL_ERR_NOMEM;
        scratch_take(f, &scr);
        if (part) s = wvol__idwt3_brick_src(part, src, l, h, &scr, &e);
        else wvol_error_set(&e, s, "wvc region: out of memory for a part of %zu samples", nx * rows * nz);
        scratch_give(f, &scr);
        if (s == WVOL_OK)
            for (size_t z = 0; z < nz; z++)
                memcpy(dst + (z * ny + (y0 - lo[1])) * nx, part + z * rows * nx, rows * nx * sizeof *part);
        free(part);
        if (s != WVOL_OK) {
#pragma omp critical(wvol_wvc_region)
            if (st == WVOL_OK) {
                st = s;
                if (err) *err = e;
            }
        }
    }
#endif
    return st;
}

/* Checks a region request (the box inside level `level`'s grid) and gives the level's
 * coefficient source for this read (its errors into E, through ctx): both region reads
 * validate here, before anything is allocated. */
static wvol_status region_source(wvol__coef_source *src, skip_ctx *ctx, wvc2_read_errors *E, wvol_wvc_file *f,
                                 const size_t lo[3], const size_t hi[3], int level, wvol_error *err)
{
    WVOL_RETURN_IF(!f || !lo || !hi, err, WVOL_ERR_ARG, "wvc region: missing argument");
    WVOL_RETURN_IF(level < 0 || level > f->info.levels, err, WVOL_ERR_ARG, "wvc region: level %d outside 0..%d",
                   level, f->info.levels);
    read_source(src, ctx, f, level, E);
    for (int a = 0; a < 3; a++)
        WVOL_RETURN_IF(lo[a] >= hi[a] || hi[a] > src->dims[a], err, WVOL_ERR_ARG,
                       "wvc region: box %zu..%zu along axis %d is empty or outside 0..%zu (level %d)", lo[a], hi[a],
                       a, src->dims[a], level);
    WVOL_FORWARD(wvol__wvc_file_dc(f, &src->dc, err)); /* the source was made before it was known */
    return WVOL_OK;
}

size_t wvol_wvc_region_slab_slices(const wvol_wvc_file *f, const size_t lo[3], const size_t hi[3])
{
    size_t slice, per;
    if (!f || !lo || !hi || hi[0] <= lo[0] || hi[1] <= lo[1] || hi[2] <= lo[2]) return 0;
    slice = (hi[0] - lo[0]) * (hi[1] - lo[1]) * sizeof(float);
    per = budget_now(f) / 16 / slice;
    if (per < 8) per = 8;
    /* no thicker than a tile layer: a slab and its margins then meet two layers of every
     * level, what wvol_wvc_slab_budget sizes the cache for */
    if (f->info.tile_z > 0 && per > (size_t)f->info.tile_z) per = (size_t)f->info.tile_z;
    return per < hi[2] - lo[2] ? per : hi[2] - lo[2];
}

wvol_status wvol_wvc_read_region_into(float *dst, wvol_wvc_file *f, const size_t lo[3], const size_t hi[3],
                                      int level, int threads, double spacing[3], double origin[3], wvol_error *err)
{
    wvol__coef_source src;
    skip_ctx ctx;
    wvc2_read_errors E = {0};
    wvol_status st;
    double scale, sp[3], org[3];
    const wvol_filter *flt;
    WVOL_RETURN_IF(!dst, err, WVOL_ERR_ARG, "wvc region: missing argument");
    WVOL_FORWARD(wvol__threads_check(threads, "wvc region", err));
    WVOL_FORWARD(region_source(&src, &ctx, &E, f, lo, hi, level, err));
    WVOL_FORWARD(wvol_filter_get(&flt, f->info.filter, err));
    {
        /* slab by slab along z: a box made whole would hold working buffers of about twice its
         * size beyond the budget, and its gathers could pin more chunks than a small budget
         * holds, each evicted and decoded again without end; a sample does not depend on the box
         * it is made in, so the slabs give the whole box's bits */
        const size_t per = wvol_wvc_region_slab_slices(f, lo, hi), plane = (hi[0] - lo[0]) * (hi[1] - lo[1]);
        /* the level grid's sample i is the level's coefficient i - shift (wvol_level_shift): the
         * box moved by that, in the unwrapped indices the reconstruction reads periodically */
        size_t sh[3];
        for (int a = 0; a < 3; a++)
            sh[a] = src.pad[a] > 1 ? (src.pad[a] - wvol_level_shift(flt, level) % src.pad[a]) % src.pad[a] : 0;
        st = WVOL_OK;
        for (size_t z = lo[2]; z < hi[2] && st == WVOL_OK; z += per) {
            const size_t l[3] = {lo[0] + sh[0], lo[1] + sh[1], z + sh[2]},
                         h[3] = {hi[0] + sh[0], hi[1] + sh[1], (z + per < hi[2] ? z + per : hi[2]) + sh[2]};
            st = reconstruct_parts(f, dst + (z - lo[2]) * plane, &src, l, h, threads, err);
            if (st == WVOL_OK) st = wvol__wvc_file_read_error(f, &E, err);
        }
    }
    if (st != WVOL_OK) return st;
    region_geometry(f, level, lo, sp, org, &scale);
    for (int a = 0; a < 3; a++) {
        if (spacing) spacing[a] = sp[a];
        if (origin) origin[a] = org[a];
    }
    if (scale != 1.0) {
        size_t nv = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
        for (size_t i = 0; i < nv; i++) dst[i] = (float)(dst[i] * scale);
    }
    return WVOL_OK;
}

wvol_status wvol_wvc_read_region(wvol_volume **out, wvol_wvc_file *f, const size_t lo[3], const size_t hi[3],
                                 int level, wvol_error *err)
{
    wvol__coef_source src;
    skip_ctx ctx;
    wvc2_read_errors E = {0};
    wvol_volume *v = NULL;
    wvol_status st;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvc region: missing argument");
    *out = NULL;
    WVOL_FORWARD(region_source(&src, &ctx, &E, f, lo, hi, level, err));
    WVOL_FORWARD(wvol_volume_create(&v, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], err));
    st = wvol_wvc_read_region_into(v->data, f, lo, hi, level, 1, v->spacing, v->origin, err);
    if (st != WVOL_OK) {
        wvol_volume_destroy(v);
        return st;
    }
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_wvc_set_budget(wvol_wvc_file *f, size_t budget, wvol_error *err)
{
    size_t b = budget ? budget : WVOL_WVC_DEFAULT_BUDGET;
    WVOL_RETURN_IF(!f, err, WVOL_ERR_ARG, "wvc set budget: file is NULL");
    WVOL_FORWARD(budget_holds(f, b, err));
    lock(f);
#pragma omp atomic write
    f->budget = b;
    if (!f->dense) evict(f); /* a lower budget: unpinned chunks go, least recent first */
    unlock(f);
    return WVOL_OK;
}

size_t wvol_wvc_slab_budget(const wvol_wvc_file *f, int level, const size_t lo[3], const size_t hi[3])
{
    const wvc2_geom *g;
    const wvol_filter *flt;
    size_t total = 0, grid[3];
    if (!f || !f->x || !lo || !hi || level < 0 || level > f->info.levels ||
        wvol_filter_get(&flt, f->info.filter, NULL) != WVOL_OK ||
        wvol_wvc_level_geometry(&f->info, level, grid, NULL, NULL, NULL) != WVOL_OK)
        return 0;
    for (int a = 0; a < 3; a++)
        if (lo[a] >= hi[a] || hi[a] > grid[a]) return 0; /* not a box of the level's grid */
    g = &f->x->g;
    for (int m = level + 1; m <= g->levels; m++) {
        size_t t0[3] = {0, 0, 0}, count = 1;
        /* a sample at i of the level's grid meets the level-m coefficients near i / 2^(m - level),
         * within the filter's length (the synthesis chain's reach is shorter; this bounds it) */
        for (int a = 0; a < 2; a++) {
            ptrdiff_t T = g->tile[a], c0, c1, t0a, t1a;
            size_t n;
            if (!g->tr[a]) continue;
            c0 = (ptrdiff_t)(lo[a] >> (m - level)) - flt->length;
            c1 = (ptrdiff_t)((hi[a] - 1) >> (m - level)) + flt->length;
            t0a = c0 >= 0 ? c0 / T : -((-c0 + T - 1) / T);
            t1a = c1 / T;
            n = (size_t)(t1a - t0a + 1);
            count *= n < g->lv[m].nt[a] ? n : g->lv[m].nt[a];
        }
        count *= g->lv[m].nt[2] < 2 ? g->lv[m].nt[2] : 2;
        total += count * chunk_decoded_bytes(g, m, t0);
    }
    return total;
}
