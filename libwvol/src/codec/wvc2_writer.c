/* SPDX-License-Identifier: MIT
 * The .wvc version-2 slab writer (contract in wvc2_writer.h): rows of each level are
 * quantised on arrival into per-level row buffers, with per-(chunk, band) sums taken
 * in a fixed order (z, then y, then x within a tile) so that the result depends on
 * neither the arrival order nor the thread count; a tile row of chunks is coded once
 * its rows and its parent rows are in, and the rows nobody needs any more are dropped.
 * Payloads go to a spill (an unlinked temporary file beside the output, or memory)
 * in coding order and are copied in chunk order (coarsest level first) by close().
 * Based on: Sullivan 1996 (centroid reconstruction offsets, as in version 1). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/alloc.h"
#include "core/clock.h"
#include "core/file_open.h"
#include "wvc2_internal.h"
#include "wvc2_writer.h"
#include "wvc_format.h"
#include "wvc_quant.h"
#include "wvol/io.h"

typedef struct chunk_rec {
    uint64_t spill;      /* offset in the spill */
    uint32_t bytes, crc, nonzero;
    float maxabs;
    double energy;
} chunk_rec;

typedef struct wlevel {
    size_t plane;        /* e0 e1 */
    size_t z_base, z_next, cap_rows;
    size_t es;           /* bytes per value of the rows: 4 (int32), 2 (int16, h.narrow) */
    void *q[8];          /* per band of the level's list: rows [z_base, z_next), in block */
    void *block;
    int32_t *xq[8];      /* in place (h.in_place): each band's row 0 in the caller's planes, */
    size_t xsy[8], xsz[8]; /* and its strides */
    size_t tz_next;      /* next tile row to code */
    sec_stats *acc;      /* per chunk of the level x band */
    float *maxabs;       /* per chunk of the level x band, as acc: each written by one task only */
} wlevel;

/* A chunk's largest |coefficient| over its bands. */
static float chunk_maxabs(const wlevel *L, const wvc2_level *G, size_t id)
{
    float mx = 0.0f;
    for (int i = 0; i < G->nb; i++) {
        const float a = L->maxabs[id * (size_t)G->nb + (size_t)i];
        mx = a > mx ? a : mx;
    }
    return mx;
}

struct wvc2_writer {
    wvc2_header h;
    double *zero_edge;   /* copy of h.zero_edge (or NULL) */
    char filter[16];
    wvc2_geom g;
    wlevel lv[WVOL_WVC_MAX_LEVELS + 1];
    chunk_rec *chunks;
    uint64_t band_bytes[WVOL_WVC_MAX_SECTIONS];
    /* output */
    int to_mem;
    wvol_atomic_file out;
    FILE *spill;
    uint8_t *mem;
    size_t mem_size, mem_cap;
    uint64_t spill_size;
    size_t alt_cabac, alt_zstd, alt_rans;
    double seconds_code;
    /* wvol__wvc2_writer_run: chunks coded as OpenMP tasks while the producer goes on */
    int async;           /* set while the producer runs inside the writer's team */
    int inflight;        /* chunk tasks spawned and not finished (atomic) */
    int task_failed;     /* 1: memory, 2: the spill (atomic; a later failure may overwrite) */
    int spill_errno;     /* why the spill's write failed (set by spill_write, which one thread runs at a time) */
    /* the rANS encoder's buffers per OpenMP thread of the writer's teams (thread number) */
    wvc_rans_scratch *scratch;
    int nscratch;
    wvc2_job_pool pool; /* grid blocks of coded jobs */
};

/* Chunks queued per coding thread before the producer codes the next one itself (and so
 * slows down to the coders' pace): enough that a coder never waits for work while the
 * producer has some, few enough that the copied jobs stay small (a level-1 chunk of
 * 64 x 64 x 32 is 3.7 MB). */
enum { JOBS_PER_THREAD = 2 };

static int nthreads(const wvc2_writer *w)
{
#ifdef _OPENMP
    return w->h.threads > 0 ? w->h.threads : omp_get_max_threads();
#else
    (void)w;
    return 1;
#endif
}

/* The calling thread's encoder buffers (NULL, the encoder's own, past the array: a team
 * larger than the writer's count). A chunk is coded by one thread from start to end. */
static wvc_rans_scratch *thread_scratch(wvc2_writer *w)
{
#ifdef _OPENMP
    const int t = omp_get_thread_num();
#else
    const int t = 0;
#endif
    return t < w->nscratch ? &w->scratch[t] : NULL;
}

void wvol__wvc2_header_default(wvc2_header *h)
{
    if (!h) return;
    memset(h, 0, sizeof *h);
    h->rounding = WVC_DEFAULT_ROUNDING;
    h->tile = WVC2_TILE_DEFAULT;
    h->tile_z = WVC2_TILE_Z_DEFAULT;
    h->coder = WVOL_WVC_CODER_AUTO;
    h->zstd_level = 3;
}

static wvol_status check_header(const wvc2_header *h, wvol_error *err)
{
    const wvol_filter *f;
    size_t n[3] = {h->nx, h->ny, h->nz}, p[3] = {h->px, h->py, h->pz}, bytes;
    int a, tile = h->tile ? h->tile : WVC2_TILE_DEFAULT, tz = h->tile_z ? h->tile_z : WVC2_TILE_Z_DEFAULT;
    WVOL_RETURN_IF(!memchr(h->filter, 0, sizeof h->filter), err, WVOL_ERR_ARG, "wvc2 writer: filter name unterminated");
    WVOL_FORWARD(wvol_filter_get(&f, h->filter, err));
    WVOL_RETURN_IF(h->levels < 1 || h->levels > WVOL_WVC_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "wvc2 writer: levels %d outside 1..%d", h->levels, WVOL_WVC_MAX_LEVELS);
    for (a = 0; a < 3; a++) {
        WVOL_RETURN_IF(n[a] < 1 || n[a] > ((size_t)1 << 40) || p[a] < n[a] || (n[a] == 1) != (p[a] == 1) ||
                           (p[a] > 1 && (p[a] & (((size_t)1 << h->levels) - 1))) ||
                           p[a] > n[a] + ((size_t)1 << h->levels),
                       err, WVOL_ERR_DIMS, "wvc2 writer: size %zu padded to %zu is not valid for %d levels", n[a],
                       p[a], h->levels);
        WVOL_RETURN_IF(!(isfinite(h->spacing[a]) && h->spacing[a] > 0) || !isfinite(h->origin[a]), err,
                       WVOL_ERR_ARG, "wvc2 writer: spacing must be > 0 and origin finite");
    }
    WVOL_RETURN_IF(!wvol_size_mul3(p[0], p[1], p[2], sizeof(float), &bytes), err, WVOL_ERR_DIMS,
                   "wvc2 writer: padded size overflows");
    WVOL_RETURN_IF(h->levels > wvol_dwt_max_levels(n[0], n[1], n[2]), err, WVOL_ERR_DIMS,
                   "wvc2 writer: %d levels is more than %zux%zux%zu allows", h->levels, n[0], n[1], n[2]);
    WVOL_RETURN_IF(!(h->step >= WVC_MIN_STEP && h->step <= WVC_MAX_STEP), err, WVOL_ERR_ARG,
                   "wvc2 writer: step %g outside [%g, %g]", h->step, WVC_MIN_STEP, WVC_MAX_STEP);
    WVOL_RETURN_IF(!(h->rounding >= 0 && h->rounding <= 0.5), err, WVOL_ERR_ARG,
                   "wvc2 writer: rounding %g outside [0, 0.5]", h->rounding);
    WVOL_RETURN_IF(!isfinite(h->value_min) || !isfinite(h->value_max) || h->value_min > h->value_max ||
                       !(h->dropped_energy >= 0) || !isfinite(h->dropped_energy),
                   err, WVOL_ERR_ARG, "wvc2 writer: bad value range or dropped energy");
    WVOL_RETURN_IF(tile < WVC2_TILE_MIN || tile > WVC2_TILE_MAX || (tile & (tile - 1)), err, WVOL_ERR_ARG,
                   "wvc2 writer: tile %d is not a power of two in [%d, %d]", tile, WVC2_TILE_MIN, WVC2_TILE_MAX);
    WVOL_RETURN_IF(tz < WVC2_TILE_MIN || tz > WVC2_TILE_MAX || (tz & (tz - 1)), err, WVOL_ERR_ARG,
                   "wvc2 writer: tile depth %d is not a power of two in [%d, %d]", tz, WVC2_TILE_MIN, WVC2_TILE_MAX);
    WVOL_RETURN_IF(h->coder < WVOL_WVC_CODER_AUTO || h->coder > WVOL_WVC_CODER_COMPACT, err, WVOL_ERR_ARG,
                   "wvc2 writer: unknown coder %d", (int)h->coder);
    if (h->zero_edge)
        for (a = 0; a < 1 + 7 * h->levels; a++)
            WVOL_RETURN_IF(!(h->zero_edge[a] >= 0) || !isfinite(h->zero_edge[a]), err, WVOL_ERR_ARG,
                           "wvc2 writer: zero edge of section %d is not valid", a);
    return WVOL_OK;
}

/* Bytes per value of level m's rows of the writer's own: int16 where h.narrow names the
 * level, int32 otherwise (in place the rows are the caller's int32). */
static size_t rows_es(const wvc2_header *h, int m)
{
    return !h->in_place && (h->narrow >> m & 1u) ? sizeof(int16_t) : sizeof(int32_t);
}

static wvol_status writer_new(wvc2_writer **out, const wvc2_header *h, wvol_error *err)
{
    wvc2_writer *w;
    size_t p[3];
    int m;
    *out = NULL;
    WVOL_RETURN_IF(!h, err, WVOL_ERR_ARG, "wvc2 writer: missing header");
    WVOL_FORWARD(check_header(h, err));
    w = calloc(1, sizeof *w);
    WVOL_RETURN_IF(!w, err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
    w->h = *h;
    if (!w->h.tile) w->h.tile = WVC2_TILE_DEFAULT;
    if (!w->h.tile_z) w->h.tile_z = WVC2_TILE_Z_DEFAULT;
    if (!w->h.zstd_level) w->h.zstd_level = 3;
    memcpy(w->filter, h->filter, sizeof w->filter);
    p[0] = h->px, p[1] = h->py, p[2] = h->pz;
    if (h->zero_edge) {
        size_t n = (size_t)(1 + 7 * h->levels);
        w->zero_edge = malloc(n * sizeof *w->zero_edge);
        if (w->zero_edge) memcpy(w->zero_edge, h->zero_edge, n * sizeof *w->zero_edge);
    }
    w->h.zero_edge = NULL;
    if ((h->zero_edge && !w->zero_edge) || wvol__wvc2_geom(&w->g, p, h->levels, w->h.tile, w->h.tile_z)) {
        wvol__wvc2_writer_abort(w);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
    }
    w->chunks = calloc(w->g.nchunks ? w->g.nchunks : 1, sizeof *w->chunks);
    w->nscratch = nthreads(w);
    w->scratch = calloc((size_t)w->nscratch, sizeof *w->scratch);
    /* as many blocks as jobs can be queued and coded at once */
    w->pool.max = JOBS_PER_THREAD * (w->nscratch - 1) + w->nscratch;
    if (!w->chunks || !w->scratch) {
        wvol__wvc2_writer_abort(w);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
    }
    for (m = 1; m <= h->levels; m++) {
        wlevel *L = &w->lv[m];
        const wvc2_level *G = &w->g.lv[m];
        L->plane = G->e[0] * G->e[1];
        L->es = rows_es(h, m);
        L->acc = calloc(G->count * (size_t)G->nb + 1, sizeof *L->acc);
        L->maxabs = calloc(G->count * (size_t)G->nb + 1, sizeof *L->maxabs);
        if (!L->acc || !L->maxabs) {
            wvol__wvc2_writer_abort(w);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
        }
    }
    *out = w;
    return WVOL_OK;
}

wvol_status wvol__wvc2_writer_open_mem(wvc2_writer **w, const wvc2_header *h, wvol_error *err)
{
    WVOL_RETURN_IF(!w, err, WVOL_ERR_ARG, "wvc2 writer: missing argument");
    WVOL_FORWARD(writer_new(w, h, err));
    (*w)->to_mem = 1;
    return WVOL_OK;
}

wvol_status wvol__wvc2_writer_open(wvc2_writer **w, const char *path, const wvc2_header *h, wvol_error *err)
{
    wvc2_writer *x;
    char *spill_path;
    int fd;
    WVOL_RETURN_IF(!w || !path, err, WVOL_ERR_ARG, "wvc2 writer: missing argument");
    WVOL_FORWARD(writer_new(&x, h, err));
    if (wvol_atomic_open(&x->out, path, err) != WVOL_OK) {
        wvol__wvc2_writer_abort(x);
        return err ? err->status : WVOL_ERR_IO;
    }
    /* the spill lives beside the output (same file system, same space), unlinked at once */
    spill_path = wvol__temp_template(path, ".spill-", "");
    if (!spill_path) {
        wvol__wvc2_writer_abort(x);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
    }
    fd = mkstemp(spill_path);
    if (fd >= 0) unlink(spill_path);
    free(spill_path);
    if (fd < 0 || !(x->spill = fdopen(fd, "w+b"))) {
        int e = errno;
        if (fd >= 0) close(fd);
        wvol__wvc2_writer_abort(x);
        return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot create the writer's spill file: %s", path, strerror(e));
    }
    *w = x;
    return WVOL_OK;
}

void wvol__wvc2_writer_abort(wvc2_writer *w)
{
    if (!w) return;
    for (int m = 1; m <= WVOL_WVC_MAX_LEVELS; m++) {
        free(w->lv[m].block);
        free(w->lv[m].acc);
        free(w->lv[m].maxabs);
    }
    if (w->out.fp || w->out.tmp_path) wvol_atomic_abort(&w->out);
    if (w->spill) fclose(w->spill);
    free(w->mem);
    free(w->chunks);
    for (int t = 0; w->scratch && t < w->nscratch; t++) wvol__wvc_rans_scratch_free(&w->scratch[t]);
    wvol__wvc2_job_pool_free(&w->pool);
    free(w->scratch);
    free(w->zero_edge);
    free(w);
}

static int spill_write(wvc2_writer *w, const uint8_t *d, size_t n, uint64_t *off)
{
    *off = w->spill_size;
    if (!n) return 0;
    if (w->to_mem) {
        if (w->mem_size + n > w->mem_cap) {
            size_t cap = w->mem_cap ? w->mem_cap : 65536;
            uint8_t *m;
            while (cap < w->mem_size + n) cap *= 2;
            m = realloc(w->mem, cap);
            if (!m) {
                w->spill_errno = ENOMEM;
                return -1;
            }
            w->mem = m;
            w->mem_cap = cap;
        }
        memcpy(w->mem + w->mem_size, d, n);
        w->mem_size += n;
    } else if (fwrite(d, 1, n, w->spill) != n) {
        w->spill_errno = errno ? errno : EIO;
        return -1;
    }
    w->spill_size += n;
    return 0;
}

/* The error of a failed spill_write: the file it names and why (a full disk, mostly). */
static wvol_status spill_error(const wvc2_writer *w, wvol_error *err)
{
    if (w->to_mem || w->spill_errno == ENOMEM)
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory for the coded chunks");
    return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot write the coded chunks to the spill file beside it: %s",
                          w->out.final_path ? w->out.final_path : "", strerror(w->spill_errno ? w->spill_errno : EIO));
}

/* ---- rows ------------------------------------------------------------------------ */

static int band_index(const wvc2_level *G, int band)
{
    for (int i = 0; i < G->nb; i++)
        if (G->bands[i] == band) return i;
    return -1;
}

enum { ROW_SLACK = 4 };

/* A level's rows reserved at first (reserve_rows) and counted by wvol__wvc2_writer_memory:
 * a tile row, the coarser level's lag, a few more. */
static size_t first_rows(const wvc2_header *h, size_t tile_z)
{
    return tile_z + h->lag_rows + ROW_SLACK;
}

static int reserve_rows(wlevel *L, const wvc2_level *G, size_t first, size_t rows)
{
    const size_t es = L->es;
    size_t cap, band, bytes;
    char *block;
    if (rows <= L->cap_rows) return 0;
    /* The level's bands share one block of whole huge pages (core/alloc.h): in 4 KiB pages
     * the rows' first touches were the largest share of a compression's page faults. The
     * first reservation holds `first` rows (a tile row, the filter's lag of the coarser
     * level's rows, a few more: wvol__wvc2_writer_memory), an upper bound: rows never
     * reached are never touched, so they take no memory. A block regrown (the longest
     * filters, whose lag the hint underestimates) is fresh, the rows copied in, by a
     * quarter at least, so that few regrowths copy. */
    cap = rows + ROW_SLACK;
    if (!L->cap_rows && cap < first) cap = first;
    if (L->cap_rows && cap < L->cap_rows + L->cap_rows / 4) cap = L->cap_rows + L->cap_rows / 4;
    if (cap > G->e[2]) cap = G->e[2];
    if (cap > SIZE_MAX / sizeof(int32_t) / L->plane / 8) return -1;
    band = cap * L->plane;
    bytes = band * (size_t)G->nb * es;
    block = wvol__malloc_pages(&bytes);
    if (!block) return -1;
    for (int i = 0; i < G->nb; i++) {
        char *q = block + (size_t)i * band * es;
        if (L->q[i]) memcpy(q, L->q[i], (L->z_next - L->z_base) * L->plane * es);
        L->q[i] = q;
    }
    free(L->block);
    L->block = block;
    L->cap_rows = cap;
    return 0;
}

/* Quantises one row segment with a widened dead zone (|c| < edge step gives 0); the
 * same sums and largest |c| as wvol__wvc_row_stats (qrow may be the row itself). */
static float row_stats_edge(double t[8], const float *row, int32_t *qrow, size_t n, double step, double f,
                            double edge)
{
    const double inv = 1.0 / step;
    float amax = 0.0f;
    memset(t, 0, 8 * sizeof *t);
    for (size_t x = 0; x < n; x++) {
        double c = row[x], a = fabs(c) * inv, tt = a + f, cc = c * c;
        amax = fabsf(row[x]) > amax ? fabsf(row[x]) : amax;
        double q = a < edge ? 0.0 : (double)(int32_t)(tt < WVC_QMAX ? tt : WVC_QMAX), r = a - q;
        t[1] += cc;
        if (q == 0) t[0] += cc;
        else if (q == 1) t[2] += r, t[3] += r * r, t[6] += 1;
        else t[4] += r, t[5] += r * r, t[7] += 1;
        qrow[x] = c < 0 ? -(int32_t)q : (int32_t)q;
    }
    return amax;
}

/* ---- coding ---------------------------------------------------------------------- */

static wvc2_qbox box_of(const wvc2_writer *w, const wlevel *L, const wvc2_level *G, int i, const size_t off[3])
{
    wvc2_qbox b = {NULL, 0, 0, NULL};
    if (w->h.in_place) {
        b.q = L->xq[i] + off[2] * L->xsz[i] + off[1] * L->xsy[i] + off[0];
        b.sy = L->xsy[i];
        b.sz = L->xsz[i];
        return b;
    }
    const size_t o = (off[2] - L->z_base) * L->plane + off[1] * G->e[0] + off[0];
    if (L->es == sizeof(int16_t)) b.q16 = (int16_t *)L->q[i] + o;
    else b.q = (int32_t *)L->q[i] + o;
    b.sy = G->e[0];
    b.sz = L->plane;
    return b;
}

static int tile_row_ready(const wvc2_writer *w, int m, size_t k)
{
    const wvc2_level *G = &w->g.lv[m];
    size_t end = (k + 1) * (size_t)w->g.tile[2];
    if (end > G->e[2]) end = G->e[2];
    if (w->lv[m].z_next < end) return 0;
    if (m < w->g.levels) {
        size_t pend = w->g.tr[2] ? (end + 1) / 2 : 1;
        if (w->lv[m + 1].z_next < pend) return 0;
    }
    return 1;
}

/* Files one coded chunk: its payload to the spill, its record, the totals. Integer sums
 * and per-chunk fields only, so the file does not depend on the order of the calls. */
static int chunk_store(wvc2_writer *w, int m, size_t id, const wvc2_coded *cd)
{
    const wvc2_level *G = &w->g.lv[m];
    chunk_rec *c = &w->chunks[id];
    if (spill_write(w, cd->payload, cd->bytes, &c->spill)) return 2;
    c->bytes = (uint32_t)cd->bytes;
    c->crc = cd->crc;
    c->nonzero = (uint32_t)cd->nonzero;
    w->alt_cabac += cd->alt_cabac;
    w->alt_zstd += cd->alt_zstd;
    w->alt_rans += cd->alt_rans;
    for (int i = 0; i < G->nb; i++) w->band_bytes[wvc2_section(w->g.levels, m, G->bands[i])] += cd->band_bytes[i];
    return 0;
}

/* The boxes of chunk (tx, ty, k) of level m in the writer's rows. */
static void chunk_boxes(const wvc2_writer *w, int m, const size_t tc[3], size_t ext[3], wvc2_qbox child[8],
                        wvc2_qbox parent[8])
{
    const wvc2_level *G = &w->g.lv[m];
    size_t off[3], poff[3], pext[3];
    wvc2_tile_box(&w->g, m, tc, off, ext);
    wvc2_parent_box(&w->g, off, ext, poff, pext);
    memset(parent, 0, 8 * sizeof *parent);
    for (int i = 0; i < G->nb; i++) {
        child[i] = box_of(w, &w->lv[m], G, i, off);
        if (m < w->g.levels) {
            const wvc2_level *PG = &w->g.lv[m + 1];
            parent[i] = box_of(w, &w->lv[m + 1], PG, band_index(PG, G->bands[i]), poff);
        }
    }
}

/* Each band's count of non-zero values in chunk id of level m, from the quantiser's sums. */
static void chunk_nonzero(const wvc2_writer *w, int m, size_t id, uint64_t nz[8])
{
    const wvc2_level *G = &w->g.lv[m];
    const sec_stats *acc = w->lv[m].acc + (id - G->first) * (size_t)G->nb;
    for (int i = 0; i < G->nb; i++) nz[i] = acc[i].n1 + acc[i].n2;
}

/* A chunk whose rows stay where they are (in place): coded from them by the task. */
typedef struct box_job {
    int m;
    size_t ext[3];
    wvc2_qbox child[8], parent[8];
    uint64_t nz[8];
} box_job;

/* A task: codes one job (a copy of its rows, or a box_job) and files it (under a lock: the
 * spill is one stream). */
static void code_job(wvc2_writer *w, wvc2_job *job, box_job *bj, size_t id)
{
    wvc2_coded cd;
    int m = job ? job->m : bj->m, r;
    double t0 = wvol__now();
    if (job)
        r = wvol__wvc2_job_code(&cd, job, &w->g, (int)w->h.coder, w->h.zstd_level, thread_scratch(w), &w->pool);
    else
        r = wvol__wvc2_chunk_encode(&cd, &w->g, m, bj->ext, bj->child, bj->parent, bj->nz, (int)w->h.coder,
                                    w->h.zstd_level, thread_scratch(w), &w->pool);
    r = r ? 1 : 0;
    free(job);
    free(bj);
#pragma omp critical(wvc2_writer_spill)
    {
        if (!r) r = chunk_store(w, m, id, &cd);
        w->seconds_code += wvol__now() - t0;
    }
    wvol__reuse_put(cd.payload); /* the mode-4 payloads come from the pool's middle tier */
    if (r) {
#pragma omp atomic write
        w->task_failed = r;
    }
#pragma omp atomic
    w->inflight--;
}

static wvol_status code_tile_row(wvc2_writer *w, int m, size_t k, wvol_error *err)
{
    const wvc2_level *G = &w->g.lv[m];
    const size_t ntile = G->nt[0] * G->nt[1];
    wvc2_coded *coded;
    long t;
    int failed = 0;
    double t0;
    int nth = nthreads(w);
    if (w->async) {
        /* the copies are made here, so the rows can move on, and the coding is a task; rows
         * quantised in place stay, so the task makes its own copy (the producer goes on) */
        for (size_t u = 0; u < ntile; u++) {
            size_t tc[3] = {u % G->nt[0], u / G->nt[0], k}, id = wvc2_chunk_id(&w->g, m, tc);
            wvc2_job *job = NULL;
            box_job *bj = malloc(sizeof *bj);
            int busy;
            if (bj) {
                bj->m = m;
                chunk_boxes(w, m, tc, bj->ext, bj->child, bj->parent);
                chunk_nonzero(w, m, id, bj->nz);
                if (!w->h.in_place) {
                    job = malloc(sizeof *job);
                    if (job && wvol__wvc2_job_make(job, &w->g, m, bj->ext, bj->child, bj->parent, bj->nz, &w->pool)) {
                        free(job);
                        job = NULL;
                    }
                    free(bj);
                    bj = NULL;
                }
            }
            if (!job && !bj) return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory while coding");
#pragma omp atomic read
            busy = w->inflight;
#pragma omp atomic
            w->inflight++;
            if (busy >= JOBS_PER_THREAD * (nth - 1)) {
                code_job(w, job, bj, id); /* the others have enough queued: this one here */
            } else {
#pragma omp task default(none) firstprivate(w, job, bj, id)
                code_job(w, job, bj, id);
            }
        }
        return WVOL_OK;
    }
    coded = calloc(ntile ? ntile : 1, sizeof *coded);
    WVOL_RETURN_IF(!coded, err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
    t0 = wvol__now();
#pragma omp parallel for schedule(dynamic, 1) reduction(| : failed) if (ntile > 1) \
    num_threads(nth)
    for (t = 0; t < (long)ntile; t++) {
        size_t tc[3] = {(size_t)t % G->nt[0], (size_t)t / G->nt[0], k}, ext[3];
        wvc2_qbox child[8], parent[8];
        uint64_t nz[8];
        chunk_boxes(w, m, tc, ext, child, parent);
        chunk_nonzero(w, m, wvc2_chunk_id(&w->g, m, tc), nz);
        if (wvol__wvc2_chunk_encode(&coded[t], &w->g, m, ext, child, parent, nz, (int)w->h.coder,
                                    w->h.zstd_level, thread_scratch(w), &w->pool))
            failed = 1;
    }
    for (t = 0; t < (long)ntile && !failed; t++) {
        size_t tc[3] = {(size_t)t % G->nt[0], (size_t)t / G->nt[0], k};
        failed = chunk_store(w, m, wvc2_chunk_id(&w->g, m, tc), &coded[t]);
    }
    for (t = 0; t < (long)ntile; t++) wvol__reuse_put(coded[t].payload);
    free(coded);
    w->seconds_code += wvol__now() - t0;
    if (failed == 2) return spill_error(w, err);
    WVOL_RETURN_IF(failed, err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory while coding");
    return WVOL_OK;
}

/* A failed task's error, once the tasks are done. */
static wvol_status task_status(const wvc2_writer *w, wvol_error *err)
{
    int f;
#pragma omp atomic read
    f = w->task_failed;
    if (f == 2) return spill_error(w, err);
    WVOL_RETURN_IF(f, err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory while coding");
    return WVOL_OK;
}

wvol_status wvol__wvc2_writer_run(wvc2_writer *w, wvol_status (*produce)(void *user, wvol_error *err), void *user,
                                  wvol_error *err)
{
    wvol_status s = WVOL_OK;
    int nth;
    WVOL_RETURN_IF(!w || !produce, err, WVOL_ERR_ARG, "wvc2 writer: missing argument");
    nth = nthreads(w);
#ifdef _OPENMP
    if (nth > 1 && !omp_in_parallel()) {
#pragma omp parallel num_threads(nth) shared(s)
#pragma omp single
        {
            w->async = 1;
            s = produce(user, err);
#pragma omp taskwait
            w->async = 0;
        }
        if (s == WVOL_OK) s = task_status(w, err);
        return s;
    }
#endif
    return produce(user, err);
}

/* Drops the rows of level m that neither its own next tile row nor its children's need. */
static void release_rows(wvc2_writer *w, int m)
{
    wlevel *L = &w->lv[m];
    const wvc2_level *G = &w->g.lv[m];
    size_t keep = L->tz_next * (size_t)w->g.tile[2], nb, i;
    if (!w->g.tr[2] || w->h.in_place) return; /* one row per level, or the caller's rows */
    if (m > 1) {
        size_t child = w->lv[m - 1].tz_next * (size_t)w->g.tile[2] / 2;
        if (child < keep) keep = child;
    }
    if (keep > L->z_next) keep = L->z_next;
    if (keep <= L->z_base) return;
    nb = keep - L->z_base;
    for (i = 0; i < (size_t)G->nb; i++)
        memmove(L->q[i], (char *)L->q[i] + nb * L->plane * L->es, (L->z_next - keep) * L->plane * L->es);
    L->z_base = keep;
}

static wvol_status code_ready(wvc2_writer *w, wvol_error *err)
{
    int progress = 1;
    while (progress) {
        progress = 0;
        for (int m = w->g.levels; m >= 1; m--) {
            wlevel *L = &w->lv[m];
            while (L->tz_next < w->g.lv[m].nt[2] && tile_row_ready(w, m, L->tz_next)) {
                WVOL_FORWARD(code_tile_row(w, m, L->tz_next, err));
                L->tz_next++;
                progress = 1;
            }
        }
    }
    for (int m = 1; m <= w->g.levels; m++) release_rows(w, m);
    return WVOL_OK;
}

/* Quantises the rows z0 .. z0 + nz - 1 of one (band, tile column) of level `level` (task
 * number `task` of writer_put's loop) into the level's rows, adding their sums and max |c| to
 * the chunks'. Returns 1 when a sum is not finite, 2 when a value does not fit narrow rows. */
static int put_segment(wvc2_writer *w, int level, size_t z0, size_t nz, const wvc2_planes *pl, long task)
{
    const wvc2_level *G = &w->g.lv[level];
    wlevel *L = &w->lv[level];
    int i = (int)(task % G->nb), band = G->bands[i], s = wvc2_section(w->g.levels, level, band), bad = 0;
    size_t tt = (size_t)task / (size_t)G->nb, tx = tt % G->nt[0], ty = tt / G->nt[0];
    const size_t T = (size_t)w->g.tile[0];
    size_t x0 = tx * T, y0 = ty * T;
    size_t x1 = x0 + T < G->e[0] ? x0 + T : G->e[0];
    size_t y1 = y0 + T < G->e[1] ? y0 + T : G->e[1];
    double f = band == 0 ? 0.5 : w->h.rounding;
    double edge = (w->zero_edge && band != 0) ? w->zero_edge[s] : 0.0;
    int use_edge = edge > 1.0 - f;
    for (size_t z = z0; z < z0 + nz; z++) {
        size_t tc[3] = {tx, ty, z / (size_t)w->g.tile[2]};
        size_t id = wvc2_chunk_id(&w->g, level, tc) - G->first;
        sec_stats *acc = &L->acc[id * (size_t)G->nb + (size_t)i];
        float mx = L->maxabs[id * (size_t)G->nb + (size_t)i];
        for (size_t y = y0; y < y1; y++) {
            const float *row = pl->band[band] + (y * pl->sy[band] + (z - z0) * pl->sz[band]) + x0;
            const size_t at = (z - L->z_base) * L->plane + y * G->e[0] + x0; /* in the writer's rows */
            const int narrow = L->es == sizeof(int16_t);
            int32_t wide[WVC2_TILE_MAX];
            int32_t *qrow = w->h.in_place ? L->xq[i] + z * L->xsz[i] + y * L->xsy[i] + x0
                            : narrow      ? wide
                                          : (int32_t *)L->q[i] + at;
            /* a kept pyramid is read from memory one short segment per row, too short for the
             * hardware's prefetch to see: the rows a few ahead (the next plane's first at the
             * end of a plane) are asked for now */
            size_t ahead = y + 4 < y1 ? 4 * pl->sy[band] : pl->sz[band];
            double t[8];
            float a;
            for (size_t x = 0; x < x1 - x0; x += 16) __builtin_prefetch(row + ahead + x);
            if (use_edge)
                a = row_stats_edge(t, row, qrow, x1 - x0, w->h.step, f, edge);
            else
                a = wvol__wvc_row_stats(t, row, qrow, x1 - x0, w->h.step, f);
            if (!isfinite(t[1])) bad = 1;
            if (narrow && wvc2_row_to_int16((int16_t *)L->q[i] + at, wide, x1 - x0, NULL)) bad |= 2;
            wvol__wvc_sec_add_row(acc, t);
            mx = a > mx ? a : mx;
        }
        L->maxabs[id * (size_t)G->nb + (size_t)i] = mx;
    }
    return bad;
}

/* In place: the first rows of a level fix where its bands' rows are; later rows must be
 * where that layout puts them (the chunks are coded from there). */
static wvol_status place_rows(wlevel *L, const wvc2_level *G, int level, size_t z0, const wvc2_planes *pl,
                              wvol_error *err)
{
    for (int i = 0; i < G->nb; i++) {
        const int b = G->bands[i];
        if (z0 == 0) {
            L->xq[i] = (int32_t *)(uintptr_t)pl->band[b];
            L->xsy[i] = pl->sy[b], L->xsz[i] = pl->sz[b];
        }
        WVOL_RETURN_IF(pl->sy[b] != L->xsy[i] || pl->sz[b] != L->xsz[i] ||
                           (const void *)pl->band[b] != (const void *)(L->xq[i] + z0 * L->xsz[i]),
                       err, WVOL_ERR_ARG,
                       "wvc2 writer: level %d band %d rows from %zu are not where its first rows' layout puts "
                       "them (quantised in place)", level, b, z0);
    }
    return WVOL_OK;
}

wvol_status wvol__wvc2_writer_put(wvc2_writer *w, int level, size_t z0, size_t nz, const wvc2_planes *pl,
                                  wvol_error *err)
{
    const wvc2_level *G;
    wlevel *L;
    long task, ntask;
    int bad = 0, nth;
    WVOL_RETURN_IF(!w || !pl, err, WVOL_ERR_ARG, "wvc2 writer: missing argument");
    WVOL_RETURN_IF(level < 1 || level > w->g.levels, err, WVOL_ERR_ARG, "wvc2 writer: level %d outside 1..%d",
                   level, w->g.levels);
    G = &w->g.lv[level];
    L = &w->lv[level];
    WVOL_RETURN_IF(z0 != L->z_next || nz > G->e[2] - z0, err, WVOL_ERR_ARG,
                   "wvc2 writer: level %d rows %zu..%zu: expected the next rows from %zu (of %zu)", level, z0,
                   z0 + nz, L->z_next, G->e[2]);
    for (int i = 0; i < G->nb; i++)
        WVOL_RETURN_IF(!pl->band[G->bands[i]], err, WVOL_ERR_ARG, "wvc2 writer: level %d band %d missing", level,
                       G->bands[i]);
    if (!nz) return WVOL_OK;
    WVOL_FORWARD(task_status(w, err));
    nth = nthreads(w);
    (void)nth;
    if (w->h.in_place) {
        WVOL_FORWARD(place_rows(L, G, level, z0, pl, err));
    } else {
        WVOL_RETURN_IF(reserve_rows(L, G, first_rows(&w->h, (size_t)w->g.tile[2]), z0 + nz - L->z_base), err,
                       WVOL_ERR_NOMEM, "wvc2 writer: out of memory for level %d rows", level);
    }
    /* one task per (band, tile column): each (chunk, band) sum is taken by one thread, in z, y, x order */
    ntask = (long)G->nb * (long)(G->nt[0] * G->nt[1]);
#ifdef _OPENMP
    if (w->async && omp_get_num_threads() > 1) {
        /* inside the writer's team (wvol__wvc2_writer_run): task loops, so that a thread
         * with no chunk to code shares the rows (a nested parallel region would run on the
         * producer alone) */
#pragma omp taskloop grainsize(1) shared(bad) \
    if (G->e[0] * G->e[1] * nz > 32768)
        for (size_t t = 0; t < (size_t)ntask; t++) { /* unsigned: as dwt3_stream.c's taskloops */
            int r = put_segment(w, level, z0, nz, pl, (long)t);
            if (r) {
#pragma omp atomic
                bad |= r;
            }
        }
    } else
#endif
    {
#pragma omp parallel for schedule(dynamic, 1) reduction(| : bad) if (ntask > 1 && G->e[0] * G->e[1] * nz > 32768) \
    num_threads(nth)
        for (task = 0; task < ntask; task++) bad |= put_segment(w, level, z0, nz, pl, task);
    }
    WVOL_RETURN_IF(bad & 2, err, WVOL_ERR_INTERNAL,
                   "wvc2 writer: level %d rows %zu..%zu: a quantised value beyond the 16-bit rows the caller asked "
                   "for (its bound on |q| was wrong)", level, z0, z0 + nz);
    WVOL_RETURN_IF(bad, err, WVOL_ERR_NONFINITE, "wvc2 writer: level %d rows %zu..%zu hold NaN or Inf (or overflow)",
                   level, z0, z0 + nz);
    for (size_t id = 0; id < G->count; id++) {
        /* as the whole-pyramid encoder: |q| stays below WVC_QMAX / 2, and the largest value
         * the decoder can make, (|q| + offset) step with |offset| <= 1, is a float32 */
        double mx = chunk_maxabs(L, G, id);
        WVOL_RETURN_IF(mx / w->h.step > (double)(WVC_QMAX / 2), err, WVOL_ERR_ARG,
                       "wvc2 writer: step %g is below %g, the smallest coefficients of %g allow", w->h.step,
                       mx / (double)(WVC_QMAX / 2), mx);
        WVOL_RETURN_IF((floor(mx / w->h.step + 0.5) + 1.0) * w->h.step > WVC_MAX_STEP, err, WVOL_ERR_NONFINITE,
                       "wvc2 writer: coefficients reach %g: with step %g a dequantised value could exceed "
                       "float32's 3.4e38; scale the volume down (or give a smaller step)",
                       mx, w->h.step);
    }
    L->z_next = z0 + nz;
    return code_ready(w, err);
}

/* ---- close --------------------------------------------------------------------------- */

unsigned wvol__wvc2_narrow_levels(const double *maxabs, int levels, double step)
{
    unsigned bits = 0;
    for (int m = 1; m <= levels; m++)
        if (wvc2_fits_int16(maxabs[m], step)) bits |= 1u << m;
    return bits;
}

size_t wvol__wvc2_writer_memory(const wvc2_header *h)
{
    size_t total = 0, p[3] = {h->px, h->py, h->pz};
    wvc2_geom g;
    int tile = h->tile ? h->tile : WVC2_TILE_DEFAULT, tz = h->tile_z ? h->tile_z : WVC2_TILE_Z_DEFAULT;
    if (h->levels < 1 || h->levels > WVOL_WVC_MAX_LEVELS || wvol__wvc2_geom(&g, p, h->levels, tile, tz)) return 0;
    size_t chunk = 0, nth = (size_t)(h->threads > 0 ? h->threads : omp_get_max_threads());
    for (int m = 1; m <= h->levels; m++) {
        const wvc2_level *G = &g.lv[m];
        size_t rows = h->in_place ? 0 : first_rows(h, (size_t)tz), c = (size_t)G->nb;
        if (rows > G->e[2]) rows = G->e[2];
        total += rows * G->e[0] * G->e[1] * (size_t)G->nb * rows_es(h, m);
        total += G->count * ((size_t)G->nb * sizeof(sec_stats) + sizeof(float) + sizeof(chunk_rec));
        for (int a = 0; a < 3; a++) c *= G->e[a] < (size_t)g.tile[a] ? G->e[a] : (size_t)g.tile[a];
        if (c > chunk) chunk = c;
    }
    /* chunks being coded: each a copy with its parent region (at most 1.5 x 4 bytes per
     * coefficient) and the coder's scratch (symbols, contexts, streams: under 16 bytes per
     * coefficient), one per thread; and the copies queued for the coding threads */
    if (nth < 1) nth = 1;
    total += nth * chunk * (6 + 16) + (nth - 1) * JOBS_PER_THREAD * chunk * 6;
    return total;
}

static void header_fill(uint8_t *h, const wvc2_writer *w, double sse, double energy, uint64_t nonzero,
                        uint64_t payload, const sec_stats *st, const float *d1, const float *d2, const double *serr)
{
    const wvc2_header *H = &w->h;
    const int nsec = 1 + 7 * H->levels;
    int s, tl = 0, tlz = 0;
    wvc_header_fields hf = {WVC2_VERSION, (uint32_t)nsec, w->filter, H->levels, {H->nx, H->ny, H->nz},
                            {H->px, H->py, H->pz}, {0}, {0}, H->value_min, H->value_max, H->step, H->rounding, sse,
                            energy, H->dropped_energy, nonzero, payload};
    memcpy(hf.spacing, H->spacing, sizeof hf.spacing);
    memcpy(hf.origin, H->origin, sizeof hf.origin);
    while ((1 << tl) < H->tile) tl++;
    while ((1 << tlz) < H->tile_z) tlz++;
    wvol__wvc_header_put(h, &hf);
    h[33] = (uint8_t)tl;
    h[34] = (uint8_t)tlz;
    wvc_put_u64(h + 208, w->g.nchunks);
    for (s = 0; s < nsec; s++) {
        uint8_t *e = h + WVC2_HEADER_SIZE + (size_t)s * WVC2_BAND_SIZE;
        int level = s == 0 ? H->levels : H->levels - (s - 1) / 7, band = s == 0 ? 0 : 1 + (s - 1) % 7;
        e[0] = (uint8_t)level;
        e[1] = (uint8_t)band;
        wvc_put_u64(e + 8, st[s].n1 + st[s].n2);
        wvc_put_f32(e + 16, d1[s]);
        wvc_put_f32(e + 20, d2[s]);
        wvc_put_f64(e + 24, st[s].energy);
        wvc_put_f64(e + 32, serr[s]);
        wvc_put_u64(e + 40, w->band_bytes[s]);
    }
}

wvol_status wvol__wvc2_writer_close(wvc2_writer *w, void **out, size_t *out_size, wvol_wvc_report *report,
                                    wvol_error *err)
{
    const int nsec = w ? 1 + 7 * w->g.levels : 0;
    sec_stats st[WVOL_WVC_MAX_SECTIONS];
    float d1[WVOL_WVC_MAX_SECTIONS], d2[WVOL_WVC_MAX_SECTIONS];
    double serr[WVOL_WVC_MAX_SECTIONS], sse = 0, energy = 0;
    uint64_t nonzero = 0, payload = 0, off;
    size_t hbytes, id, count = 0;
    uint8_t *h = NULL;
    wvol_status status = WVOL_OK;
    int m, s;
    if (out) *out = NULL;
    if (out_size) *out_size = 0;
    WVOL_RETURN_IF(!w, err, WVOL_ERR_ARG, "wvc2 writer: missing writer");
    if (w->to_mem ? (!out || !out_size) : (out || out_size)) {
        wvol__wvc2_writer_abort(w);
        return wvol_error_set(err, WVOL_ERR_ARG, "wvc2 writer: close's outputs do not match how it was opened");
    }
    for (m = 1; m <= w->g.levels; m++)
        if (w->lv[m].z_next != w->g.lv[m].e[2] || w->lv[m].tz_next != w->g.lv[m].nt[2]) {
            status = wvol_error_set(err, WVOL_ERR_ARG, "wvc2 writer: level %d has %zu of its %zu rows", m,
                                    w->lv[m].z_next, w->g.lv[m].e[2]);
            goto fail;
        }
    /* per-section sums in chunk order (fixed, so the offsets do not depend on threads) */
    memset(st, 0, sizeof st);
    for (m = w->g.levels; m >= 1; m--) {
        const wvc2_level *G = &w->g.lv[m];
        for (id = 0; id < G->count; id++) {
            chunk_rec *c = &w->chunks[G->first + id];
            c->maxabs = chunk_maxabs(&w->lv[m], G, id);
            c->energy = 0;
            for (int i = 0; i < G->nb; i++) {
                const sec_stats *a = &w->lv[m].acc[id * (size_t)G->nb + (size_t)i];
                wvol__wvc_sec_merge(&st[wvc2_section(w->g.levels, m, G->bands[i])], a);
                c->energy += a->energy;
            }
        }
    }
    for (s = 0; s < nsec; s++) {
        serr[s] = wvol__wvc_sec_error(&st[s], w->h.step, &d1[s], &d2[s]);
        sse += serr[s];
        energy += st[s].energy;
        nonzero += st[s].n1 + st[s].n2;
    }
    hbytes = WVC2_HEADER_SIZE + (size_t)nsec * WVC2_BAND_SIZE + w->g.nchunks * WVC2_CHUNK_SIZE + 4;
    for (id = 0; id < w->g.nchunks; id++) payload += w->chunks[id].bytes;
    h = calloc(hbytes, 1);
    if (!h) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
        goto fail;
    }
    header_fill(h, w, sse, energy, nonzero, payload, st, d1, d2, serr);
    off = hbytes;
    for (id = 0; id < w->g.nchunks; id++) {
        const chunk_rec *c = &w->chunks[id];
        uint8_t *e = h + WVC2_HEADER_SIZE + (size_t)nsec * WVC2_BAND_SIZE + id * WVC2_CHUNK_SIZE;
        wvc_put_u64(e, c->bytes ? off : 0);
        wvc_put_u32(e + 8, c->bytes);
        wvc_put_u32(e + 12, c->crc);
        wvc_put_f32(e + 16, c->maxabs);
        wvc_put_u32(e + 20, c->nonzero);
        wvc_put_f64(e + 24, c->energy);
        off += c->bytes;
        count += c->bytes > 0;
    }
    wvc_put_u32(h + hbytes - 4, (uint32_t)crc32(0L, h, (uInt)(hbytes - 4)));
    if (w->to_mem) {
        uint8_t *file = malloc(hbytes + (size_t)payload);
        if (!file) {
            status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
            goto fail;
        }
        memcpy(file, h, hbytes);
        off = hbytes;
        for (id = 0; id < w->g.nchunks; id++) {
            const chunk_rec *c = &w->chunks[id];
            if (c->bytes) memcpy(file + off, w->mem + c->spill, c->bytes);
            off += c->bytes;
        }
        *out = file;
        *out_size = hbytes + (size_t)payload;
    } else {
        uint8_t *buf = NULL;
        size_t cap = 0;
        if (fwrite(h, 1, hbytes, w->out.fp) != hbytes) goto io_fail;
        fflush(w->spill);
        for (id = 0; id < w->g.nchunks; id++) {
            const chunk_rec *c = &w->chunks[id];
            if (!c->bytes) continue;
            if (c->bytes > cap) {
                uint8_t *nb = realloc(buf, c->bytes);
                if (!nb) {
                    free(buf);
                    status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc2 writer: out of memory");
                    goto fail;
                }
                buf = nb, cap = c->bytes;
            }
            if (fseeko(w->spill, (off_t)c->spill, SEEK_SET) != 0 || fread(buf, 1, c->bytes, w->spill) != c->bytes ||
                fwrite(buf, 1, c->bytes, w->out.fp) != c->bytes) {
                free(buf);
                goto io_fail;
            }
        }
        free(buf);
        status = wvol_atomic_commit(&w->out, err);
        memset(&w->out, 0, sizeof w->out);
        if (status != WVOL_OK) goto fail;
    }
    if (report) {
        memset(report, 0, sizeof *report);
        report->step = w->h.step;
        report->sse_quant = sse;
        report->nonzero = nonzero;
        report->coefficients = (uint64_t)w->h.px * w->h.py * w->h.pz;
        report->bytes = hbytes + (size_t)payload;
        report->bytes_cabac = w->h.coder == WVOL_WVC_CODER_ZSTD ? 0 : w->alt_cabac;
        report->bytes_zstd = w->h.coder == WVOL_WVC_CODER_CABAC ? 0 : w->alt_zstd;
        report->bytes_rans = w->alt_rans;
        report->seconds_code = w->seconds_code;
    }
    (void)count;
    free(h);
    wvol__wvc2_writer_abort(w);
    return WVOL_OK;
io_fail:
    status = wvol_atomic_fail(&w->out, err);
fail:
    free(h);
    wvol__wvc2_writer_abort(w);
    return status;
}
