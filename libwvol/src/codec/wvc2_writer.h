/* SPDX-License-Identifier: MIT
 * The .wvc version-2 slab writer: the one chunk coder behind every v2 file, fed
 * with coefficient planes in increasing z per level (a streamed transform), or with
 * a whole pyramid (wvol_wvc_encode). Declared internal interface of the codec
 * module (not installed); docs/wvc-format.md describes the bytes it writes.
 *
 * Contract
 * - open() takes everything the header needs up front: the grid, the family, the
 *   quantiser's step and dead zone (chosen beforehand, e.g. from the magnitude
 *   histograms of a first pass, wvc_internal.h), the tile sizes. Nothing is written
 *   under the final name before close(): the file goes to a temporary name and is
 *   renamed by close(); abort() (or any failed call) removes it.
 * - put(level, z0, nz, planes) hands over rows z0 .. z0+nz-1 (along z) of every
 *   band of one level: for level m < levels the 7 detail bands, for m == levels
 *   also the low-pass cube (band 0). Band b of level m has the extent of the Mallat
 *   layout (wvol.h / wavelet.h: px >> m per transformed axis, 1 along an axis of
 *   padded size 1, where the bands with a high-pass along that axis are empty and
 *   their pointers are ignored). Rows of one level must arrive in increasing z,
 *   each exactly once, without gaps; levels may be interleaved in any order (fine
 *   to coarse as a streamed transform emits them, or coarse to fine). The planes
 *   are read during the call only (the caller may reuse them at once), unless the
 *   header asks for the quantisation in place (in_place).
 * - The writer quantises each row as it arrives (q = sign(c) floor(|c|/step + f);
 *   NaN/Inf refused), keeps the quantised rows of the current tile row, and codes
 *   a chunk (one level x one tile of tile x tile x tile_z coefficients in every band of that
 *   level) as soon as all its rows and the rows of its parent region (the same
 *   tile's half-size region in the next coarser level, whose quantised values are
 *   the coder's context) have arrived. Memory held: per level about
 *   (tile_z + the coarser level's lag) rows of int32 quantised values (int16 for
 *   the levels h.narrow names), plus the
 *   parent tile row until both of its child tile rows are coded; with coarse-to-
 *   fine arrival the whole quantised pyramid (what wvol_wvc_encode holds anyway).
 *   Coded chunk payloads are spilled to a temporary file (or kept in memory for
 *   wvol__wvc2_writer_open_mem) and copied coarsest level first by close().
 * - The output does not depend on the order of arrival, on nz, or on the number
 *   of threads: the same coefficients, step and options give the same bytes.
 * - Chunks of a tile row are coded in parallel (OpenMP, `threads`); run() codes them
 *   as tasks beside a producer (a streamed transform), so the two overlap.
 * - close() writes the header, the per-band table (reconstruction offsets, energy,
 *   error, non-zero counts), the chunk index and the payloads, then renames. It
 *   refuses (and removes the file) if a level is incomplete. close() and abort()
 *   free the writer; a failed put() leaves it to be aborted.
 *
 * Thread safety: one writer per thread; put() must not be called concurrently on
 * the same writer. */
#ifndef WVOL_CODEC_WVC2_WRITER_H
#define WVOL_CODEC_WVC2_WRITER_H

#include <stddef.h>
#include <stdint.h>

#include "wvol/status.h"
#include "wvol/wvc.h"

/* Tile edge in coefficients (per level; x and y, and z apart): a power of two in
 * [WVC2_TILE_MIN, WVC2_TILE_MAX]. The depth along z sets how many rows a streamed
 * writer holds; the rest the cost of the chunk's contexts starting afresh. */
#define WVC2_TILE_DEFAULT 64
#define WVC2_TILE_Z_DEFAULT 32
#define WVC2_TILE_MIN 8
#define WVC2_TILE_MAX 256

typedef struct wvc2_writer wvc2_writer;

typedef struct wvc2_header {
    char filter[16];            /* family name as wvol_filter_name gives it, NUL-terminated */
    int levels;                 /* 1 .. WVOL_WVC_MAX_LEVELS, <= wvol_dwt_max_levels */
    size_t nx, ny, nz;          /* original grid */
    size_t px, py, pz;          /* padded grid of the transform (wvol_dwt_padded_size) */
    double spacing[3], origin[3];
    double value_min, value_max;/* range of the original samples (PSNR peak) */
    double step;                /* quantiser step, > 0 */
    double rounding;            /* dead-zone rounding f of the detail bands in [0, 0.5]
                                   (the low-pass cube uses 0.5) */
    const double *zero_edge;    /* NULL, or per section in v1 file order (low-pass cube, then
                                   level = levels..1, bands 1..7): a detail coefficient with
                                   |c| < zero_edge[s] * step quantises to 0 (a widened dead
                                   zone; values below 1 - rounding change nothing). How the
                                   encoder spends an unused error budget. */
    double dropped_energy;      /* energy the caller removed before encoding (header, reports) */
    int tile;                   /* chunk edge along x and y; 0: WVC2_TILE_DEFAULT */
    int tile_z;                 /* chunk depth along z; 0: WVC2_TILE_Z_DEFAULT */
    wvol_wvc_coder coder;       /* AUTO (per band of a chunk, the smaller), CABAC or ZSTD */
    int zstd_level;             /* 0: 3 */
    int threads;                /* 0: OpenMP's default */
    size_t lag_rows;            /* streamed arrival: rows a level may run ahead of the next
                                   coarser one (0: unknown); a level's rows are first reserved
                                   for tile_z + lag_rows + a few, as wvol__wvc2_writer_memory
                                   counts them, so they are not regrown and copied */
    unsigned narrow;            /* bit m (1 .. levels): level m's rows of the writer's own are
                                   held as int16, the caller having bounded every |q| of the
                                   level by 32767 (a value beyond it fails the put); half the
                                   memory of int32 rows, the file the same */
    int in_place;               /* put() quantises the rows where they are: each coefficient's
                                   q (int32) is written over its float and the chunks are coded
                                   from there, so the writer holds no rows of its own. A level's
                                   rows then keep one layout (band[b] of rows from z0 at z0 *
                                   sz[b] past the first put's, the same strides), and stay in
                                   place, untouched by the caller, until close() or abort() */
} wvc2_header;

/* header with the defaults: rounding 0.38, tile 64 x 64 x 32, coder AUTO, zstd level 3; the
 * rest zero (the caller fills grid, family, step). */
void wvol__wvc2_header_default(wvc2_header *h);

/* One level's rows for put(): band[b] points at coefficient (x, y, z0) of band b,
 * element (x, y, z0 + k) at band[b][x + y * sy[b] + k * sz[b]] (floats). band[0]
 * is read only at level == levels. */
typedef struct wvc2_planes {
    const float *band[8];
    size_t sy[8], sz[8];
} wvc2_planes;

/* Opens a writer to path (atomic: temporary name until close). */
wvol_status wvol__wvc2_writer_open(wvc2_writer **w, const char *path, const wvc2_header *h, wvol_error *err);
/* The same, into memory: close() hands the whole file in *out (malloc'ed). */
wvol_status wvol__wvc2_writer_open_mem(wvc2_writer **w, const wvc2_header *h, wvol_error *err);

/* Rows z0 .. z0 + nz - 1 of every band of `level` (see the contract above). */
wvol_status wvol__wvc2_writer_put(wvc2_writer *w, int level, size_t z0, size_t nz, const wvc2_planes *planes,
                                  wvol_error *err);

/* Runs produce(user, err), which puts rows into w, with the writer's threads split: the
 * calling thread runs produce (anything it parallelises with OpenMP runs on it alone, as a
 * nested region), while the others code the chunks that become ready, as tasks, and the
 * producer helps when they fall behind (at most a few chunks per thread wait, each a copy
 * of its rows: the rows themselves move on). With one thread, or called inside a parallel
 * region, it is produce(user, err) with the tile rows coded in parallel as put() goes. The
 * bytes are those of put() alone (the spill's order differs, the file's does not). Returns
 * produce's status, or a chunk's coding failure. */
wvol_status wvol__wvc2_writer_run(wvc2_writer *w, wvol_status (*produce)(void *user, wvol_error *err), void *user,
                                  wvol_error *err);

/* Finishes the file and frees the writer (also on failure). report may be NULL:
 * step, sse_quant (exact, with the stored offsets), nonzero, coefficients, bytes,
 * bytes_cabac / bytes_zstd (the payload if every band used that coder; 0 when not
 * tried), bytes_rans (the mode-3 payloads of the chunks where it was tried), seconds_code. For a writer opened with open_mem, *out and *out_size receive
 * the file; for one opened on a path they must be NULL. */
wvol_status wvol__wvc2_writer_close(wvc2_writer *w, void **out, size_t *out_size, wvol_wvc_report *report,
                                    wvol_error *err);

/* Drops everything (no file is left); NULL does nothing. */
void wvol__wvc2_writer_abort(wvc2_writer *w);

/* Bytes the writer holds at most for a grid (quantised rows and buffers, the chunks being
 * coded, not the caller's planes), for a streamed (fine-to-coarse, lag <= h->lag_rows rows
 * per level) arrival, with h->threads threads (0: OpenMP's default). For callers who plan
 * memory. */
size_t wvol__wvc2_writer_memory(const wvc2_header *h);

/* The levels (bit m, 1 .. levels) whose quantised values all fit int16 for the step, given
 * each level's largest |c| (maxabs[m]): what wvc2_header.narrow may name. The file cache
 * holds a chunk's values as int16 by the same rule on the index's maximum. */
unsigned wvol__wvc2_narrow_levels(const double *maxabs, int levels, double step);

#endif
