/* SPDX-License-Identifier: MIT */
/* .wvc files: wavelet coefficients quantised and entropy-coded, coarse to fine,
 * behind a versioned header, with a CRC-32 per section (DESIGN.md sections 5-6;
 * the byte layout is in docs/wvc-format.md).
 *
 * Quantiser: uniform with a dead zone, q = sign(c) floor(|c|/step + rounding),
 * reconstructed at sign(q) (|q| + delta) step with delta the centroid offset of each
 * section (one for |q| = 1, one for |q| >= 2). The transform is orthonormal, so the
 * squared error of the volume equals the squared error of the coefficients
 * (Parseval): the encoder knows it exactly and can choose the step that meets a
 * target error.
 * Coder: per sub-band, a context-adaptive binary range coder; the contexts are
 * the quantised parent (same band, next coarser level) and the causal neighbours,
 * over 2x2x2 groups (the children of one parent). zstd on the same symbols is the
 * alternative; each section keeps the smaller.
 *
 * Threading: functions are reentrant; they use OpenMP threads internally. */
#ifndef WVOL_WVC_H
#define WVOL_WVC_H

#include <stddef.h>
#include <stdint.h>
#include "wvol/status.h"
#include "wvol/wavelet.h"

#ifdef __cplusplus
extern "C" {
#endif

#define WVOL_WVC_FORMAT_VERSION 2
#define WVOL_WVC_MAX_LEVELS 30
#define WVOL_WVC_MAX_SECTIONS (1 + 7 * WVOL_WVC_MAX_LEVELS)

typedef enum wvol_wvc_coder {
    WVOL_WVC_CODER_AUTO = 0,  /* encoder only: version 2, chunk mode 4 wherever a chunk has no
                                 low-pass cube (the decoder's speed first), else as COMPACT;
                                 version 1, per section the smaller of CABAC and zstd */
    WVOL_WVC_CODER_EMPTY = 0, /* in a file: all coefficients of the section are zero */
    WVOL_WVC_CODER_CABAC = 1, /* context-adaptive binary range coder */
    WVOL_WVC_CODER_ZSTD = 2,  /* zigzag varints of the same symbols, zstd */
    WVOL_WVC_CODER_RANS = 3,  /* encoder only, version 2: static-model rANS chunks (mode 3)
                                 wherever a chunk has no low-pass cube */
    WVOL_WVC_CODER_RANS4 = 4, /* encoder only, version 2: chunk mode 4 (rANS with contexts from
                                 the rows before, a vector decoder) wherever a chunk has no
                                 low-pass cube */
    WVOL_WVC_CODER_COMPACT = 5 /* encoder only: per chunk the smallest of modes 0, 2 and 3
                                  (version 2; the rule --coder auto had before mode 4);
                                  version 1 as AUTO */
} wvol_wvc_coder;

typedef struct wvol_wvc_params {
    double step;         /* > 0: this quantiser step; 0: choose from target_sse */
    double target_sse;   /* wanted sum of squared coefficient errors (quantisation only) */
    double rounding;     /* dead-zone rounding offset in [0, 0.5] (default 0.38) */
    wvol_wvc_coder coder;/* AUTO (default), CABAC, ZSTD or RANS */
    int zstd_level;      /* default 3 */
    double value_min, value_max; /* range of the original samples (header; PSNR peak) */
    double dropped_energy;       /* energy the caller zeroed before encoding (header; reports) */
    int version;         /* file format: 0 = WVOL_WVC_FORMAT_VERSION (2, chunked, random access), 1 */
    int tile;            /* version 2: chunk edge along x and y in coefficients, a power of two
                            in 8..256 (0: 64) */
    int tile_z;          /* version 2: chunk depth along z, the same range (0: 32) */
} wvol_wvc_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_wvc_params_default(wvol_wvc_params *p);

/* One section of a file (the low-pass cube is level == levels, band 0). In a
 * version-2 file a band is spread over the chunks: offset and crc are 0, coder is
 * CABAC for a band with non-zeros (each chunk picks its own mode:
 * wvol_wvc_file_chunk_modes), bytes its share. */
typedef struct wvol_wvc_section {
    int level, band;
    int coder;               /* wvol_wvc_coder */
    uint64_t bytes;          /* payload bytes */
    uint64_t count;          /* coefficients in the band */
    uint64_t nonzero;        /* quantised coefficients != 0 */
    float delta1, delta2;    /* reconstruction offsets */
    double energy;           /* sum c^2 of the coefficients as given to the encoder */
    double error;            /* sum (c - c_hat)^2 */
    uint32_t crc;
    uint64_t offset;         /* of the payload in the file */
} wvol_wvc_section;

/* What the header and the section table say (no payload decoded). */
typedef struct wvol_wvc_info {
    int version;
    char filter[16];
    int levels;
    size_t nx, ny, nz, px, py, pz;
    double spacing[3], origin[3];
    double value_min, value_max;
    double step, rounding;
    double sse;              /* quantisation error sum (c - c_hat)^2 (the prediction adds dropped_energy) */
    double energy;           /* sum c^2 as given to the encoder */
    double dropped_energy;
    uint64_t nonzero;
    uint64_t file_bytes;     /* header + table + payloads */
    uint64_t header_bytes;   /* version 2: header, band table and chunk index */
    int tile, tile_z;        /* version 2: chunk edge along x and y, depth along z (0 in version 1) */
    uint64_t chunks;         /* version 2: chunks in the index (0 in version 1) */
    int nsections;
    wvol_wvc_section sections[WVOL_WVC_MAX_SECTIONS];
} wvol_wvc_info;

/* What encoding did. */
typedef struct wvol_wvc_report {
    double step;
    int step_iterations;     /* exact error evaluations while searching the step */
    double sse_quant;        /* sum (c - c_hat)^2 over the given coefficients */
    uint64_t nonzero, coefficients;
    size_t bytes;            /* the whole file */
    size_t bytes_cabac;      /* payload bytes if every section used CABAC (0: not tried) */
    size_t bytes_zstd;       /* ... if every section used zstd (0: not tried) */
    size_t bytes_rans;       /* version 2: the mode-3 payloads of the chunks where mode 3 was
                                tried (0: none; docs/wvc-format.md, chunk mode 3) */
    double seconds_step, seconds_quantise, seconds_code;
} wvol_wvc_report;

/* The largest |c - c_hat| the file's quantiser can leave on any coefficient, from its
 * step, rounding and reconstruction offsets (0 when the info has no step). Coefficients a
 * selection dropped before coding (info->dropped_energy > 0) are not covered: their values
 * are not in the file. The per-pixel error bound (wvol_render_bound) takes it. */
WVOL_API double wvol_wvc_max_coeff_error(const wvol_wvc_info *info);

/* Encodes coefficients (zero the ones a selection dropped before calling) into a
 * heap buffer *out of *out_size bytes (free with free()). report may be NULL. */
WVOL_API wvol_status wvol_wvc_encode(void **out, size_t *out_size, const wvol_coeffs *c,
                                     const wvol_wvc_params *p, wvol_wvc_report *report, wvol_error *err);

typedef struct wvol_wvc_read_options {
    int stop_level;          /* 0: everything; m: decode the levels above m only (then
                                wvol_idwt3_level(c, m) gives the coarser volume) */
    uint64_t max_voxels;     /* refuse larger padded grids (0: 2^34) */
} wvol_wvc_read_options;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_wvc_read_options_default(wvol_wvc_read_options *o);

/* Parses and checks the header and section table of a buffer (the whole file,
 * or at least its first info->header_bytes). */
WVOL_API wvol_status wvol_wvc_parse_info(wvol_wvc_info *info, const void *buf, size_t size, wvol_error *err);

/* Decodes a whole file held in memory. The coefficients of levels <= stop_level
 * are zero. info may be NULL. Free the result with wvol_coeffs_destroy. */
WVOL_API wvol_status wvol_wvc_decode(wvol_coeffs **out, const void *buf, size_t size,
                                     const wvol_wvc_read_options *opt, wvol_wvc_info *info, wvol_error *err);

/* Files. save is atomic (temporary name, then rename). read reads the header, the
 * table and only the sections it needs; a file whose size differs from what its
 * header declares is refused. read_info parses the header and the table and checks
 * every section's checksum, without decoding. */
WVOL_API wvol_status wvol_wvc_save(const char *path, const void *buf, size_t size, wvol_error *err);
WVOL_API wvol_status wvol_wvc_read_info(wvol_wvc_info *info, const char *path, wvol_error *err);
WVOL_API wvol_status wvol_wvc_read(wvol_coeffs **out, const char *path, const wvol_wvc_read_options *opt,
                                   wvol_wvc_info *info, wvol_error *err);

/* ---- random access (version 2) --------------------------------------------------- */

/* An open .wvc file whose chunks are decoded on demand into a cache of at most
 * `budget` bytes of decoded chunks (least recently used first out). A version-1
 * file has no index: it is decoded whole at open, refused when that exceeds the
 * budget. One handle may serve several threads (the cache has a lock); each region,
 * piece or level read reports its own errors (a damaged chunk fails the reads that need
 * it and no other). */
typedef struct wvol_wvc_file wvol_wvc_file;

#define WVOL_WVC_DEFAULT_BUDGET ((size_t)1 << 30) /* 1 GiB */

typedef struct wvol_wvc_cache_stats {
    size_t budget;           /* bytes */
    size_t held, peak;       /* decoded chunk bytes held now, and at most so far */
    size_t chunk_bytes;      /* decoded size of the largest chunk */
    uint64_t decoded;        /* chunk decodes (a chunk evicted and needed again counts twice) */
    uint64_t decoded_narrow; /* of those, held as 16-bit values (half the bytes): the chunks whose
                                index maximum bounds every quantised value by 32767 */
    uint64_t hits;           /* requests served from the cache */
    uint64_t bytes_read;     /* payload bytes read from the file */
} wvol_wvc_cache_stats;

/* Opens path, reads and checks the header and the chunk index (no payload). budget
 * 0 means WVOL_WVC_DEFAULT_BUDGET; a budget below what one chain of chunks (one per
 * level, the parents a chunk is decoded with) needs is refused with a message. */
WVOL_API wvol_status wvol_wvc_open(wvol_wvc_file **out, const char *path, size_t budget, wvol_error *err);
WVOL_API void wvol_wvc_close(wvol_wvc_file *f); /* NULL is fine */
/* What the header, band table and index say (the file's info). */
WVOL_API const wvol_wvc_info *wvol_wvc_file_info(const wvol_wvc_file *f);
/* A NULL f zeroes *st; a NULL st does nothing. */
WVOL_API void wvol_wvc_file_stats(const wvol_wvc_file *f, wvol_wvc_cache_stats *st);
/* How a version-2 file's chunks are coded: counts (at least levels + 1 rows; rows 0 ..
 * levels are written) gets in counts[m][k] the number of level-m chunks (m = 1 .. levels;
 * row 0 zero) whose payload is in chunk mode k (0 bands coded apart,
 * 1 one CABAC stream, 2 CABAC with block flags, 3 static rANS, 4 rANS with contexts from the
 * rows above; docs/wvc-format.md), counts[m][5] the chunks without a payload (all zero).
 * Reads each chunk's first byte (the index says where). A version-1 file has no chunks: all
 * zero. A mode byte that no reader knows is refused, naming the chunk. */
#define WVOL_WVC_CHUNK_MODES 6
WVOL_API wvol_status wvol_wvc_file_chunk_modes(wvol_wvc_file *f, uint64_t counts[][WVOL_WVC_CHUNK_MODES],
                                               wvol_error *err);
/* The name of counts' column k ("bands_apart", "cabac", "cabac_blocks", "rans", "rans4",
 * "empty"); NULL outside 0 .. WVOL_WVC_CHUNK_MODES - 1. */
WVOL_API const char *wvol_wvc_chunk_mode_name(int k);

/* Level `level`'s grid of a file (0: the original voxels; s: the grid of
 * wvol_idwt3_level(c, s)), without decoding: its samples per axis (ceil(n / 2^s) along an
 * axis the transform halves, n along one it leaves alone), its spacing, and the position
 * of its first sample (origin + spacing * wvol_level_offset along a halved axis: the first
 * scaling function's centre in the first cell; wvol_idwt3_level's convention, which the region
 * and piece reads follow, a level with a wvol_level_shift being read as a region). Any of
 * grid, spacing and origin may be NULL; a level outside 0..levels is refused. */
WVOL_API wvol_status wvol_wvc_level_geometry(const wvol_wvc_info *info, int level, size_t grid[3], double spacing[3],
                                             double origin[3], wvol_error *err);

/* The samples of the box [lo, hi) of level `level`'s grid (0: the original voxels;
 * s: the grid of wvol_idwt3_level(c, s), ceil(n / 2^s) per transformed axis), with
 * its values, spacing and origin (the box's first sample), decoding only the chunks
 * whose basis functions' supports meet the box, then reconstructing locally. Equal
 * to the same box of wvol_idwt3_level on the whole decoded file up to float rounding. */
WVOL_API wvol_status wvol_wvc_read_region(wvol_volume **out, wvol_wvc_file *f, const size_t lo[3],
                                          const size_t hi[3], int level, wvol_error *err);
/* Slices of the box [lo, hi) a region read makes at a time (wvol_wvc_read_region_into): about
 * 1/16 of the file's chunk budget in samples (at least 8 slices, at most the tile depth, at most
 * the box's); 0 for an empty box. A reader that writes its output slab by slab takes as many. */
WVOL_API size_t wvol_wvc_region_slab_slices(const wvol_wvc_file *f, const size_t lo[3], const size_t hi[3]);
/* The same box into the caller's array dst ((hi - lo) samples, x fastest), made slab by slab
 * along z (wvol_wvc_region_slab_slices), with `threads`
 * threads reconstructing parts of each slab along y (0: OpenMP's default; 1 in a build without
 * OpenMP; each part holds a copy of its samples while it is made), so that a reader can fill its output in place, slab by slab. spacing and
 * origin (either may be NULL) receive the box's. The values equal wvol_wvc_read_region's
 * bit for bit whatever the thread count: every sample is synthesised from the same
 * coefficients in the same order. */
WVOL_API wvol_status wvol_wvc_read_region_into(float *dst, wvol_wvc_file *f, const size_t lo[3],
                                               const size_t hi[3], int level, int threads, double spacing[3],
                                               double origin[3], wvol_error *err);

/* A piece that spans level `level`'s grid along x and y (a z slab, or the whole volume: what
 * a parallel reader's rank gets) decoded straight into the caller's work array: the chunks
 * that the slab's synthesis needs are dequantised into the Mallat layout of its coefficient
 * windows there, and the inverse transform runs in place, level by level. The samples of
 * the box come out at work[0 .. (hi - lo) samples), x fastest, equal to
 * wvol_wvc_read_region's up to float rounding. Working memory beyond the box: the work
 * array's few planes of filter margins (wvol_wvc_piece_samples), the cache's decoded chunks
 * (a chain of parents and `threads` chunks in flight: wvol_wvc_piece_budget, which the
 * file's budget must hold) and a z-pass buffer per thread; each chunk is decoded once (on a
 * file's first reconstruction of data far from 0, the coarsest level's once more, one at a
 * time, to find its low-pass offset: docs/wavelets.md, "Data on an offset").
 * threads: 0 for OpenMP's default. */
WVOL_API wvol_status wvol_wvc_read_piece_into(float *work, size_t cap, wvol_wvc_file *f, const size_t lo[3],
                                              const size_t hi[3], int level, int threads, double spacing[3],
                                              double origin[3], wvol_error *err);
/* Samples (floats) of the work array wvol_wvc_read_piece_into needs for the box: its planes
 * (x-y planes of the level's grid) and those the coarser levels' margins add; 0 when the box
 * is not such a piece (it must span the level's grid along x and y with no padding to crop,
 * every axis transformed, level < levels, a version-2 file): wvol_wvc_read_region_into
 * reads any box. */
WVOL_API size_t wvol_wvc_piece_samples(const wvol_wvc_file *f, int level, const size_t lo[3], const size_t hi[3]);
/* Bytes of decoded chunks a piece read with `threads` threads pins at once (one chain of
 * parents, one chunk per level, and `threads` chunks of the largest size); 0 for a
 * version-1 file. */
WVOL_API size_t wvol_wvc_piece_budget(const wvol_wvc_file *f, int threads);

/* Bytes of decoded chunks the cache must hold for a read of the box [lo, hi) of level
 * `level`'s grid in z slabs, in order, to decode each chunk about once: for every level
 * m > level, the chunks over the box's x-y range (widened by the filter's length) in two
 * consecutive tile layers, which hold a slab no thicker than the tile depth (info.tile_z
 * samples of the grid) and its filters' halo. A cache below it evicts
 * chunks that the next slab decodes again (with 2048^2 slices, each chunk once per slab).
 * 0 for a version-1 file (decoded whole at open) or a bad argument. */
WVOL_API size_t wvol_wvc_slab_budget(const wvol_wvc_file *f, int level, const size_t lo[3], const size_t hi[3]);

/* Sets an open file's chunk cache budget (0: WVOL_WVC_DEFAULT_BUDGET), e.g. to what
 * wvol_wvc_slab_budget says a read needs, without opening the file again. A budget below one
 * chain of decoded chunks (one per level; a version-1 file: its whole decode) is refused as at
 * open, and the budget is unchanged. A lower budget evicts unpinned chunks at once. Other
 * threads may be reading f meanwhile: a read in progress goes on under the new budget and
 * fails as over it (WVOL_ERR_NOMEM) where that cannot hold what the read pins. */
WVOL_API wvol_status wvol_wvc_set_budget(wvol_wvc_file *f, size_t budget, wvol_error *err);

/* Predicted and measured error. sse is a sum of squared errors over n samples;
 * PSNR uses peak = value range (infinite for sse 0). */
WVOL_API double wvol_wvc_psnr(double sse, double n, double vmin, double vmax);
/* The sum of squared errors that gives this PSNR over n samples. */
WVOL_API double wvol_wvc_sse_for_psnr(double psnr, double n, double vmin, double vmax);

/* Compares two volumes of equal size: sum of squared differences and max |a-b|. */
WVOL_API wvol_status wvol_wvc_compare(double *sse, double *maxabs, const wvol_volume *a,
                                      const wvol_volume *b, wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
