/* SPDX-License-Identifier: MIT
 * Shared by the .wvc version-2 writer and reader (not installed): the byte layout's
 * constants, the chunk geometry (levels x spatial tiles of coefficients) and the
 * chunk coder (wvc2_chunk.c) over the band coders of version 1. docs/wvc-format.md
 * describes the bytes. */
#ifndef WVOL_CODEC_WVC2_INTERNAL_H
#define WVOL_CODEC_WVC2_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "wvc_internal.h"

#define WVC2_VERSION 2
#define WVC2_HEADER_SIZE 224
#define WVC2_BAND_SIZE 48
#define WVC2_CHUNK_SIZE 32

/* Chunks: per level m (levels .. 1, coarsest first) a grid of tiles of tile[a]
 * coefficients along axis a over the level's band extent e (px >> m, 1 on an untransformed
 * axis); tile t covers [t T, min(e, (t + 1) T)). A chunk holds that box of every
 * band of the level (the low-pass cube too at m == levels). Chunk ids: level `levels`
 * first, then finer; within a level x fastest. */
typedef struct wvc2_level {
    size_t e[3];         /* band extent */
    size_t nt[3];        /* tiles per axis */
    size_t first, count; /* chunk ids first .. first + count - 1 */
    int nb;              /* bands present, increasing */
    int bands[8];
} wvc2_level;

typedef struct wvc2_geom {
    int levels;
    int tile[3];         /* tile edge per axis (x and y equal) */
    size_t p[3];
    int tr[3];           /* axis transformed (p > 1) */
    size_t nchunks;
    wvc2_level lv[WVOL_WVC_MAX_LEVELS + 1]; /* [1 .. levels] */
} wvc2_geom;

/* Fills g; returns -1 when the chunk count overflows. */
int wvol__wvc2_geom(wvc2_geom *g, const size_t p[3], int levels, int tile_xy, int tile_z);

/* The section (v1 file order: low-pass cube, then level = levels..1, bands 1..7) of a band. */
static inline int wvc2_section(int levels, int level, int band)
{
    return band == 0 ? 0 : 1 + 7 * (levels - level) + (band - 1);
}

/* Tile box of chunk coordinate t along axis a at level m. */
static inline void wvc2_tile_box(const wvc2_geom *g, int m, const size_t t[3], size_t off[3], size_t ext[3])
{
    for (int a = 0; a < 3; a++) {
        size_t T = (size_t)g->tile[a], o = t[a] * T, e = g->lv[m].e[a];
        off[a] = o;
        ext[a] = e - o < T ? e - o : T;
    }
}

/* The chunk coordinates of id (which must be < g->nchunks) and its level. */
int wvol__wvc2_chunk_coords(const wvc2_geom *g, size_t id, size_t t[3]);

static inline size_t wvc2_chunk_id(const wvc2_geom *g, int m, const size_t t[3])
{
    const wvc2_level *L = &g->lv[m];
    return L->first + t[0] + L->nt[0] * (t[1] + L->nt[1] * t[2]);
}

/* Parent region of a tile box: along a transformed axis [off/2, (off + ext)/2), else
 * the same single row. The parent chunk is the tile containing it (tile coordinate t/2). */
static inline void wvc2_parent_box(const wvc2_geom *g, const size_t off[3], const size_t ext[3], size_t poff[3],
                                   size_t pext[3])
{
    for (int a = 0; a < 3; a++) {
        poff[a] = g->tr[a] ? off[a] / 2 : 0;
        pext[a] = g->tr[a] ? (ext[a] + 1) / 2 : 1;
    }
}

/* A strided box of quantised values: element (x, y, z) at q[x + y sy + z sz], or, when q is
 * NULL, at q16[x + y sy + z sz] (a writer's narrow rows, wvc2_writer.h, copied in as int32;
 * a file cache's narrow chunk, decoded into with every value checked to fit). */
typedef struct wvc2_qbox {
    int32_t *q;
    size_t sy, sz;
    int16_t *q16;
} wvc2_qbox;

/* Whether every quantised value of coefficients with |c| <= maxabs fits int16 for the step:
 * |q| <= floor(maxabs / step + 1/2) (the quantiser's rounding is at most 1/2), and that
 * floor at most 32766, one below INT16_MAX for the rounding of the division. */
static inline int wvc2_fits_int16(double maxabs, double step)
{
    return step > 0 && maxabs / step + 0.5 < (double)INT16_MAX;
}

/* A row of n quantised values into int16 (the writer's narrow rows, the file cache's narrow
 * chunks): 0 when every |v| <= INT16_MAX, else 1 (what wvc2_fits_int16 promised was wrong; the
 * values written are then meaningless). *nz, when given, gains the row's non-zero count. */
static inline int wvc2_row_to_int16(int16_t *restrict d, const int32_t *restrict s, size_t n, uint64_t *nz)
{
    uint32_t out = 0;
    uint64_t k = 0;
    for (size_t x = 0; x < n; x++) {
        const int32_t v = s[x];
        out |= (uint32_t)v + (uint32_t)INT16_MAX > 2u * (uint32_t)INT16_MAX; /* unsigned: no overflow */
        d[x] = (int16_t)v;
        k += v != 0;
    }
    if (nz) *nz += k;
    return out != 0;
}

/* Results of coding one chunk. */
typedef struct wvc2_coded {
    uint8_t *payload;    /* malloc'ed, NULL when every band is zero */
    size_t bytes;
    uint32_t crc;
    uint64_t nonzero;
    size_t alt_cabac, alt_zstd; /* what all-CABAC / all-zstd would have taken */
    size_t alt_rans;            /* mode 3's payload when it was tried, else 0 */
    size_t band_bytes[8];       /* per band (index into the level's band list) */
} wvc2_coded;

/* The local grid of one band of a chunk being coded: the tile at (0, 0, 0), its parent
 * region beside it along x at (ext0, 0, 0); dims (ext0 + pext0) x ext1 x ext2. */
typedef struct wvc2_local {
    int32_t *q;
    size_t p[3];
    wvc_band b;
} wvc2_local;

/* One chunk's coding job: its non-zero bands copied out of the writer's rows (with their
 * parent regions), so that it can be coded after those rows have moved on. */
typedef struct wvc2_job {
    int m;
    size_t ext[3];
    uint8_t mask;          /* bands with a non-zero value (index into the level's list) */
    int nused;
    uint64_t nzb[8], nonzero;
    wvc2_local lg[8];
    int32_t *block; /* the grids, one after another */
    size_t cap;     /* block's size in int32 values */
} wvc2_job;

/* Grid blocks of coded jobs kept for the next ones: a fresh block per chunk paid its
 * first page touches every time, about as much as copying the chunk out. Blocks are
 * taken and given back from any thread. Zero-initialised with max (at most
 * WVC2_POOL_MAX): how many it keeps; freed with wvol__wvc2_job_pool_free. */
enum { WVC2_POOL_MAX = 64 };
typedef struct wvc2_job_pool {
    int32_t *block[WVC2_POOL_MAX];
    size_t cap[WVC2_POOL_MAX];
    int n, max;
} wvc2_job_pool;
void wvol__wvc2_job_pool_free(wvc2_job_pool *pool);

/* Fills job from child/parent (as wvol__wvc2_chunk_encode takes them), its grids in a
 * block from pool (NULL: a new block); nonzero: each child box's count of non-zero values
 * where the caller has it (the writer's quantiser counts them), NULL to count them here;
 * 0 or -1 (memory, job left empty). */
int wvol__wvc2_job_make(wvc2_job *job, const wvc2_geom *g, int m, const size_t ext[3], const wvc2_qbox child[8],
                        const wvc2_qbox parent[8], const uint64_t *nonzero, wvc2_job_pool *pool);
/* Codes a job (as wvol__wvc2_chunk_encode) and gives its grids back to pool (NULL:
 * frees them); 0 or -1 (memory). */
int wvol__wvc2_job_code(wvc2_coded *out, wvc2_job *job, const wvc2_geom *g, int coder, int zstd_level,
                        wvc_rans_scratch *scratch, wvc2_job_pool *pool);
/* Gives a job's grids back to pool, or frees them (pool NULL or full); NULL or an
 * emptied job does nothing. */
void wvol__wvc2_job_free(wvc2_job *job, wvc2_job_pool *pool);

/* Codes the bands of one chunk: child[i] is band g->lv[m].bands[i]'s box of extent
 * ext, parent[i] its parent region (extent from wvc2_parent_box; ignored at m ==
 * levels), nonzero as wvol__wvc2_job_make's. coder: AUTO, CABAC, ZSTD or RANS (mode 3
 * wherever the chunk has no low-pass cube, else as CABAC). Returns 0 or -1 (memory). */
int wvol__wvc2_chunk_encode(wvc2_coded *out, const wvc2_geom *g, int m, const size_t ext[3],
                            const wvc2_qbox child[8], const wvc2_qbox parent[8], const uint64_t *nonzero,
                            int coder, int zstd_level, wvc_rans_scratch *scratch, wvc2_job_pool *pool);

/* A chunk decoded in place in a dense quantised pyramid Q (padded grid p, x fastest):
 * band i's tile at off[i], its parent region at poff[i] (both in Q's coordinates).
 * The tile boxes must hold zeros; the coder then needs no copy. */
typedef struct wvc2_direct {
    int32_t *Q;
    size_t p[3];
    size_t off[8][3], poff[8][3];
} wvc2_direct;

/* Memory for a chunk decode's local grids (the bands beside their parent regions), kept
 * by a caller that decodes many chunks so that each decode reuses pages already mapped
 * instead of faulting in fresh ones (on a VM the first touch of a page costs more than
 * the decoding of its coefficients). Starts zeroed; free q with free(). */
typedef struct wvc2_scratch {
    int32_t *q;
    size_t cap; /* int32 values */
} wvc2_scratch;

/* Decodes a chunk's payload (already checked against its CRC) into child[i] (the
 * boxes are written entirely, zeros included), with the parents' values as
 * context, or into direct (not NULL: child, parent and scratch are ignored).
 * scratch may be NULL (the local grids are then allocated per call). *nonzero
 * receives the non-zero count. Returns 0, or -1 with *why (child's contents then
 * unspecified). */
int wvol__wvc2_chunk_decode(const wvc2_geom *g, int m, const size_t ext[3], const wvc2_qbox child[8],
                            const wvc2_qbox parent[8], const wvc2_direct *direct, wvc2_scratch *scratch,
                            const uint8_t *payload, size_t bytes, uint64_t *nonzero, const char **why);

/* wvol_wvc_encode's version-2 path: the pyramid c through the slab writer, coarse to
 * fine, with the step chosen and the dead zones widened (zero_edge, may be NULL) as the
 * caller decided; fills the writer's part of rep. */
wvol_status wvol__wvc2_encode_dense(void **out, size_t *out_size, const wvol_coeffs *c, const wvol_wvc_params *p,
                                    double step, const double *zero_edge, wvol_wvc_report *rep, wvol_error *err);

/* LEB128 helpers. */
static inline size_t wvc2_put_varint(uint8_t *d, uint64_t v)
{
    size_t n = 0;
    while (v >= 0x80) {
        d[n++] = (uint8_t)(v | 0x80);
        v >>= 7;
    }
    d[n++] = (uint8_t)v;
    return n;
}

#endif
