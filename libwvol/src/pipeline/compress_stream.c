/* SPDX-License-Identifier: MIT */
/* Streamed compression (wvol_compress_stream, wvol/compress.h): a volume source into a
 * .wvc version-2 file with memory that does not grow with the number of slices.
 *
 * Two passes, no spill: selection and the quantiser's step need statistics of every
 * coefficient, so pass 1 runs the streamed transform (wavelet/dwt3_stream.c) into the
 * magnitude histograms the in-memory encoder takes of the whole pyramid (codec's
 * wvc_stream.h), and the step comes from them exactly as the in-memory encoder's first
 * guess does; pass 2 runs the transform again into the v2 slab writer
 * (codec/wvc2_writer.h), which quantises and codes chunks as their rows arrive and
 * reports the exact quantisation error. When that error misses an error target (the
 * histograms predict it to within about 1%), a further pass writes with a step scaled
 * down by the miss. A spill of the coefficients to a temporary file would cost the
 * volume's size on disk and its read-back; a second transform costs less than reading
 * 4 bytes per voxel back on the machines we measure (docs/store.md). When the pyramid
 * fits the caller's memory budget, pass 1 also keeps the rows the transform emits (made
 * in place in a buffer laid out level by level, wvol_dwt3_source_hooked), and pass 2
 * replays them into the writer instead of reading and transforming the source again: each
 * level's rows in the same order (a chunk row per call), so the same bytes. The
 * writer quantises them where they lie (its rows would be as much fresh memory again, whose
 * first touch costs more than the quantiser's arithmetic); a further pass, rare, reads and
 * transforms the source again. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "codec/wvc2_writer.h"
#include "codec/wvc_stream.h"
#include "core/alloc.h"
#include "core/source_volume.h"
#include "core/clock.h"
#include "core/status_internal.h"
#include "wvol/compress.h"
#include "pipeline/compress_floor.h"
#include "wvol/source.h"

/* ---- the rows of a level as the writer's planes ----------------------------------- */

/* The pyramid kept for the replay, level by level: row r of level m at level[m] + r * row[m]
 * (its low plane, then its high plane when z is transformed), where the transform makes it
 * (wvol_dwt3_source_hooked), so that a run of a level's rows is planes a fixed stride apart.
 * `order` lists the rows as the transform emitted them. */
typedef struct kept_row {
    int level;
    size_t r;
} kept_row;

typedef struct kept_rows {
    float *data;
    size_t level[32], row[32], rows[32]; /* offset, floats per row, rows, per level */
    kept_row *order;
    size_t n, nmax;
} kept_rows;

typedef struct pass_ctx {
    int levels;
    size_t p[3];
    size_t tile_z;           /* the writer's chunk depth: the replay's batches of level-1 rows */
    wvc_stream_stats *stats; /* pass 1 */
    kept_rows *keep;         /* pass 1, when the rows fit the budget: the pyramid */
    wvc2_writer *writer;     /* pass 2 */
} pass_ctx;

/* the extent of level m's input along an axis of padded size p (1: not transformed) */
static size_t level_extent(size_t p, int m) { return p == 1 ? 1 : p >> (m - 1); }

/* The planes of a level's row call; consecutive rows' planes `zstride` floats apart. */
static void planes_of(wvc2_planes *pl, const pass_ctx *c, int m, const float *low, const float *high,
                      size_t zstride)
{
    size_t cx = level_extent(c->p[0], m), cy = level_extent(c->p[1], m);
    size_t hx = cx > 1 ? cx / 2 : 0, hy = cy > 1 ? cy / 2 : 0;
    memset(pl, 0, sizeof *pl);
    for (int b = 0; b < 8; b++) {
        const float *src = b & 4 ? high : low;
        if (!src || (b == 0 && m < c->levels)) continue;
        /* a band with a high-pass along an untransformed axis is empty: its pointer is ignored */
        pl->band[b] = src + (b & 1 ? hx : 0) + (b & 2 ? hy * cx : 0);
        pl->sy[b] = cx;
        pl->sz[b] = zstride;
    }
}

/* wvol_dwt3_place_fn: row r of level m's place in the kept pyramid */
static float *place_row(void *user, int level, size_t r)
{
    const kept_rows *k = ((const pass_ctx *)user)->keep;
    return r < k->rows[level] ? k->data + k->level[level] + r * k->row[level] : NULL;
}

/* wvol_dwt3_piece_fn: pass 1 counts the rows as each thread makes them (the planes of the
 * whole row start y0 rows before the piece) */
static void on_piece(void *user, int level, size_t r, size_t y0, size_t y1, const float *low, const float *high)
{
    pass_ctx *c = user;
    size_t cx = level_extent(c->p[0], level);
    wvc2_planes pl;
    (void)r;
    planes_of(&pl, c, level, low - y0 * cx, high ? high - y0 * cx : NULL, 0);
    wvol__wvc_stream_stats_add_rows(c->stats, level, y0, y1, &pl);
}

static wvol_status on_rows(void *user, int level, size_t r, const float *low, const float *high, wvol_error *err)
{
    pass_ctx *c = user;
    wvc2_planes pl;
    if (c->stats) {
        kept_rows *k = c->keep;
        if (!k) return WVOL_OK;
        WVOL_RETURN_IF(k->n == k->nmax, err, WVOL_ERR_INTERNAL,
                       "compress: the transform emitted more rows than a %zux%zux%zu pyramid holds", c->p[0],
                       c->p[1], c->p[2]);
        k->order[k->n].level = level, k->order[k->n].r = r;
        k->n++;
        return WVOL_OK;
    }
    planes_of(&pl, c, level, low, high, 0);
    return wvol__wvc2_writer_put(c->writer, level, r, 1, &pl, err);
}

/* The planes of the kept pyramid's level from its row r on (consecutive rows row[level]
 * floats apart). */
static void kept_planes(wvc2_planes *pl, const pass_ctx *c, int level, size_t r)
{
    const kept_rows *k = c->keep;
    const float *low = k->data + k->level[level] + r * k->row[level];
    size_t plane = level_extent(c->p[0], level) * level_extent(c->p[1], level);
    planes_of(pl, c, level, low, k->row[level] > plane ? low + plane : NULL, k->row[level]);
}

/* Rows r .. r + nz - 1 of a level of the kept pyramid into the writer. */
static wvol_status put_kept(pass_ctx *c, int level, size_t r, size_t nz, wvol_error *err)
{
    wvc2_planes pl;
    kept_planes(&pl, c, level, r);
    return wvol__wvc2_writer_put(c->writer, level, r, nz, &pl, err);
}

/* pass 2's producer: the streamed transform into the writer (wvol__wvc2_writer_run) */
typedef struct write_pass {
    wvol_source *src;
    const wvol_filter *f;
    pass_ctx *pc;
} write_pass;

static wvol_status write_rows(void *user, wvol_error *err)
{
    write_pass *wp = user;
    pass_ctx *c = wp->pc;
    const kept_rows *k = c->keep;
    size_t run[32] = {0}, run_r[32] = {0};
    if (!k) return wvol_dwt3_source(wp->src, wp->f, c->levels, on_rows, c, NULL, err);
    /* The replay: each level's rows in the order the transform made them, in whole chunk
     * rows (level 1 holds seven eighths of the coefficients; level 2 one eighth), so that
     * the writer's quantiser has a chunk row's tasks to share among its threads. A level's
     * chunk row goes in when its last row was made; a chunk is coded once its own rows and
     * its parent's are in, whatever the order of the levels' calls, and a chunk's sums are
     * taken in the same order whatever the rows per call: the same bytes. */
    for (size_t i = 0; i < k->n; i++) {
        const kept_row *e = &k->order[i];
        const int m = e->level;
        if (!run[m]) run_r[m] = e->r;
        run[m]++;
        if ((e->r + 1) % c->tile_z == 0 || e->r + 1 == k->rows[m]) {
            WVOL_FORWARD(put_kept(c, m, run_r[m], run[m], err));
            run[m] = 0;
        }
    }
    for (int m = 1; m <= c->levels; m++)
        WVOL_RETURN_IF(run[m], err, WVOL_ERR_INTERNAL, "compress: the replay ended inside a chunk row of level %d", m);
    return WVOL_OK;
}

/* ---- the pipeline ------------------------------------------------------------------ */

/* The kept pyramid of a levels-deep transform of a p[0] x p[1] x p[2] grid, when it fits
 * `budget` bytes; *out stays NULL when it does not (or memory is short: the source is then
 * read twice, as without a budget). */
static void keep_create(kept_rows **out, const size_t p[3], int levels, size_t budget)
{
    size_t floats = 0, calls = 0;
    kept_rows *k;
    *out = NULL;
    if (!(k = calloc(1, sizeof *k))) return;
    for (int m = 1; m <= levels; m++) {
        size_t cz = level_extent(p[2], m), rows = cz > 1 ? cz / 2 : 1;
        size_t row = level_extent(p[0], m) * level_extent(p[1], m) * (cz > 1 ? 2 : 1);
        if ((double)floats + (double)rows * (double)row > (double)budget / sizeof(float)) {
            free(k);
            return;
        }
        k->level[m] = floats, k->row[m] = row, k->rows[m] = rows;
        floats += rows * row;
        calls += rows;
    }
    k->data = wvol__malloc_large(floats * sizeof(float));
    k->order = malloc(calls * sizeof *k->order);
    if (!k->data || !k->order) {
        free(k->data);
        free(k->order);
        free(k);
        return;
    }
    k->nmax = calls;
    *out = k;
}

static size_t keep_bytes(const kept_rows *k, int levels)
{
    return k ? (k->level[levels] + k->rows[levels] * k->row[levels]) * sizeof(float) : 0;
}

static void keep_destroy(kept_rows *k)
{
    if (!k) return;
    free(k->data);
    free(k->order);
    free(k);
}

/* Each level's largest |c| from pass 1 (maxabs[1 .. levels]). */
static void level_maxabs(wvc_stream_stats *st, int levels, double *maxabs)
{
    for (int m = 1; m <= levels; m++) maxabs[m] = wvol__wvc_stream_level_maxabs(st, m);
}

int wvol_compress_streams(const wvol_compress_params *p)
{
    if (!p) return 1;
    return p->select.mode == WVOL_SELECT_ALL && p->select.drop_levels == 0 && p->select.n_ellipsoids == 0 &&
           p->quant.format_version != 1;
}

wvol_status wvol_compress_stream(const char *path, wvol_source *src, const wvol_compress_params *params,
                                 wvol_compress_stream_report *rep, wvol_error *err)
{
    wvol_compress_params p;
    wvol_compress_stream_report out;
    const wvol_filter *f = NULL;
    float range[2];
    pass_ctx pc;
    wvol_wvc_params wp;
    wvc2_header h;
    size_t dims[3], bytes = 0;
    double spacing[3], origin[3], voxels, t0, scale = 0.9925, maxabs[32] = {0};
    int maxl;
    wvol_status s;

    WVOL_RETURN_IF(!path || !src, err, WVOL_ERR_ARG, "compress: no output path or no source");
    if (params) p = *params;
    else wvol_compress_params_default(&p), p.for_file = 1;
    memset(&out, 0, sizeof out);
    WVOL_RETURN_IF(!wvol_compress_streams(&p), err, WVOL_ERR_UNSUPPORTED,
                   "compress: the streamed path keeps every coefficient and writes .wvc version 2 (a selection, "
                   "dropped levels or version 1 need the volume in memory: wvol_compress)");
    if (wvol_compress_wavelet_is_auto(p.wavelet)) {
        wvol_wavelet_choice wc;
        WVOL_FORWARD(wvol_compress_choose_wavelet(&wc, src, &p, err));
        p.wavelet = wc.wavelet;
    }
    WVOL_FORWARD(wvol_filter_get(&f, p.wavelet && p.wavelet[0] ? p.wavelet : "db2", err));
    wvol_source_geometry(src, dims, spacing, origin);
    maxl = wvol_dwt_max_levels(dims[0], dims[1], dims[2]);
    WVOL_RETURN_IF(maxl < 1, err, WVOL_ERR_DIMS, "compress: a %zux%zux%zu volume cannot be transformed", dims[0],
                   dims[1], dims[2]);
    if (p.levels == 0) p.levels = maxl < WVOL_COMPRESS_LEVELS_FILE ? maxl : WVOL_COMPRESS_LEVELS_FILE;
    WVOL_RETURN_IF(p.levels < 1 || p.levels > maxl, err, WVOL_ERR_ARG,
                   "compress: levels %d: a %zux%zux%zu volume allows 1..%d", p.levels, dims[0], dims[1], dims[2], maxl);
    out.levels = p.levels;
    memset(&pc, 0, sizeof pc);
    pc.levels = p.levels;
    for (int a = 0; a < 3; a++) pc.p[a] = wvol_dwt_padded_size(dims[a], p.levels);

    /* pass 1: statistics (and the volume's range), and the pyramid when it fits */
    t0 = wvol__now();
    out.source_reads = 1;
    wvol__source_seen_reset(src);
    s = wvol__wvc_stream_stats_create(&pc.stats, pc.p[0], pc.p[1], pc.p[2], p.levels, err);
    if (!s) keep_create(&pc.keep, pc.p, p.levels, p.memory ? p.memory : WVOL_WVC_DEFAULT_BUDGET);
    out.kept_bytes = keep_bytes(pc.keep, p.levels);
    if (!s)
        s = wvol_dwt3_source_hooked(src, f, p.levels, on_rows, pc.keep ? place_row : NULL, on_piece, &pc, &bytes,
                                    err);
    out.window_bytes = bytes;
    /* the range of what the pass read (the checked reads take it); + 0.0: a zero extreme as
     * +0, whichever zero the scan kept (as wvol_compress) */
    wvol__source_seen_range(src, range);
    out.value_min = (double)range[0] + 0.0, out.value_max = (double)range[1] + 0.0;
    voxels = (double)dims[0] * (double)dims[1] * (double)dims[2];
    if (!s) s = wvol_compress_wvc_params(&wp, &p.quant, 0.0, voxels, out.value_min, out.value_max, err);
    if (!s) s = wvol__compress_float_floors(&wp, &p.quant, f, p.levels, pc.p, voxels, out.value_min, out.value_max, err);
    if (!s) s = wvol__wvc_stream_step(pc.stats, &wp, scale, &out.step, NULL, err);
    /* Haar with every coefficient at hand: the in-memory encoder's exact refinement. Haar's
     * coefficients of a piecewise-constant or integer-valued volume take a few distinct
     * magnitudes, which the histograms' model of values spread within a bin misses by about
     * 2 dB; the longer filters spread them, and there the exact pass, a tenth of a compression,
     * only confirmed the guess on every volume measured (docs/wvc-format.md). */
    if (!s && pc.keep && f->length == 2) {
        wvc2_planes pl[32];
        size_t nz[32] = {0};
        int passes;
        for (int m = 1; m <= p.levels; m++) {
            kept_planes(&pl[m], &pc, m, 0);
            nz[m] = pc.keep->rows[m];
        }
        s = wvol__wvc_stream_refine(pc.stats, pl, nz, &wp, &out.step, &passes, err);
    }
    if (!s) level_maxabs(pc.stats, p.levels, maxabs);
    out.seconds_stats = wvol__now() - t0;
    out.target_sse = wp.step > 0 ? 0 : wp.target_sse;

    /* pass 2 (and more if the exact error misses the target) */
    wvol__wvc2_header_default(&h);
    snprintf(h.filter, sizeof h.filter, "%s", f->name);
    h.levels = p.levels;
    h.nx = dims[0], h.ny = dims[1], h.nz = dims[2];
    h.px = pc.p[0], h.py = pc.p[1], h.pz = pc.p[2];
    memcpy(h.spacing, spacing, sizeof h.spacing);
    memcpy(h.origin, origin, sizeof h.origin);
    h.value_min = out.value_min, h.value_max = out.value_max;
    h.rounding = wp.rounding;
    h.tile = wp.tile;
    h.tile_z = wp.tile_z;
    h.coder = wp.coder;
    h.zstd_level = wp.zstd_level;
    pc.tile_z = (size_t)(h.tile_z ? h.tile_z : WVC2_TILE_Z_DEFAULT);
    h.lag_rows = (size_t)f->length + 8;
    h.in_place = pc.keep != NULL;
    h.narrow = wvol__wvc2_narrow_levels(maxabs, p.levels, out.step);
    out.writer_bytes = wvol__wvc2_writer_memory(&h);
    wvol__wvc_stream_stats_free(pc.stats);
    pc.stats = NULL;
    for (int attempt = 0; !s; attempt++) {
        wvol_wvc_report wr;
        t0 = wvol__now();
        h.step = out.step;
        /* the kept pyramid is quantised where it lies (no rows of the writer's own to fill):
         * a further pass reads and transforms the source again */
        h.in_place = pc.keep != NULL;
        h.narrow = wvol__wvc2_narrow_levels(maxabs, p.levels, h.step);
        out.source_reads += !pc.keep;
        s = wvol__wvc2_writer_open(&pc.writer, path, &h, err);
        if (!s) {
            write_pass wpass = {src, f, &pc};
            s = wvol__wvc2_writer_run(pc.writer, write_rows, &wpass, err);
        }
        if (!s) s = wvol__wvc2_writer_close(pc.writer, NULL, NULL, &wr, err);
        else wvol__wvc2_writer_abort(pc.writer);
        pc.writer = NULL;
        out.passes = attempt + 2;
        keep_destroy(pc.keep);
        pc.keep = NULL;
        out.seconds_write += wvol__now() - t0;
        if (s) break;
        out.wvc = wr;
        out.sse_quant = wr.sse_quant;
        out.bytes = wr.bytes;
        if (wp.step > 0 || wr.sse_quant <= wp.target_sse || !(wr.sse_quant > 0)) break;
        if (attempt == 3) {
            remove(path);
            s = wvol_error_set(err, WVOL_ERR_ARG,
                               "compress: the error target (%g) is still missed after %d passes (%g): give a step",
                               wp.target_sse, out.passes, wr.sse_quant);
            break;
        }
        /* the error grows about as step^2 near the target: aim a little below it */
        out.step *= 0.995 * sqrt(wp.target_sse / wr.sse_quant);
    }
    keep_destroy(pc.keep);
    out.wvc.step = out.step;
    if (rep) *rep = out;
    return s;
}
