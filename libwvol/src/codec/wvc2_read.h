/* SPDX-License-Identifier: MIT
 * Reading .wvc version 2 (not installed): the parsed chunk index, the checks, whole
 * levels into a dense quantised pyramid (wvc2_read.c). The file-backed chunk cache
 * (wvc2_file.c) reads single chunks through the same checks. */
#ifndef WVOL_CODEC_WVC2_READ_H
#define WVOL_CODEC_WVC2_READ_H

#include <stdio.h>

#include "wvc2_internal.h"

typedef struct wvc2_chunk {
    uint64_t offset;     /* in the file; 0 for an all-zero chunk */
    uint32_t bytes, crc, nonzero;
    float maxabs;        /* max |c| of the coefficients given to the encoder */
    double energy;       /* sum c^2 of the same */
} wvc2_chunk;

typedef struct wvc2_index {
    wvc2_geom g;
    wvc2_chunk *chunks;
    uint64_t hbytes;     /* header + band table + index + CRC */
    double step;
    float d1[WVOL_WVC_MAX_SECTIONS], d2[WVOL_WVC_MAX_SECTIONS];
} wvc2_index;

/* Bytes of header + band table + index + CRC that the fixed header at h declares
 * (0 when h is shorter than the fixed header or the counts are absurd). */
uint64_t wvol__wvc2_prefix_bytes(const uint8_t *h, size_t avail);

/* The whole header check of wvc_decode.c (any version) on the file's first avail bytes
 * (for version 2 at least the header, table and index), for a file of file_size bytes. */
wvol_status wvol__wvc_parse_prefix(wvol_wvc_info *I, const uint8_t *h, size_t avail, uint64_t file_size,
                                   wvol_error *err);

/* Checks the version-2 part of a header whose common fields (magic, version, filter,
 * levels, sizes, spacing, origin, range, step, rounding, totals) were parsed into I,
 * then the band table and the chunk index; fills I's sections (offset 0, coder
 * CABAC for a non-empty band, bytes = its share of the chunks' payloads), tile and
 * chunks. out (may be NULL) receives the index. */
wvol_status wvol__wvc2_parse(wvol_wvc_info *I, wvc2_index **out, const uint8_t *h, size_t avail, uint64_t file_size,
                             wvol_error *err);
void wvol__wvc2_index_free(wvc2_index *x);

/* 0 when the chunk's payload matches its CRC-32, else -1 with *why. */
int wvol__wvc2_chunk_check(const wvc2_index *x, size_t id, const uint8_t *payload, const char **why);

/* "chunk N (level m, tile x,y,z)" for error messages. */
void wvol__wvc2_describe(char *buf, size_t n, const wvc2_index *x, size_t id);

/* Called for each chunk of the finest level decoded (stop_level + 1, when stop_level <
 * levels) as soon as it is decoded, by the thread that decoded it: nothing reads that
 * level's quantised values afterwards (a chunk's contexts stay inside its tile and its
 * parent), so the caller may turn the tile's values (off, ext in the level's band
 * coordinates, every band of the level) into floats while they are in its cache. */
typedef void (*wvc2_tile_done_fn)(void *ctx, int level, const size_t off[3], const size_t ext[3]);

/* Decodes the levels above stop_level into the dense quantised pyramid Q (padded
 * grid p, zeroed by the caller) from buf, the file's first avail bytes; done (may be
 * NULL) as above. */
wvol_status wvol__wvc2_decode_dense(int32_t *Q, const size_t p[3], const wvc2_index *x, const uint8_t *buf,
                                    size_t avail, int stop_level, wvc2_tile_done_fn done, void *ctx,
                                    wvol_error *err);

/* ---- an open file's chunk cache (wvc2_file.c), for the piece reader (wvc2_piece.c) ---- */

/* The first error one read met (pins and gathers cannot return one; the read takes it at the
 * end). Each region, piece and offset read keeps its own, so that reads of one file from several
 * threads neither take nor clear each other's errors; the stores opened on the file share the
 * file's own (wvol__wvc_file_error). Written under the file's lock; start it zeroed. */
typedef struct wvc2_read_errors {
    wvol_status status;
    char message[sizeof(((wvol_error *)0)->message)];
} wvc2_read_errors;
/* E's error, if any, into err (naming the file) and E cleared; the status. */
wvol_status wvol__wvc_file_read_error(wvol_wvc_file *f, wvc2_read_errors *E, wvol_error *err);

/* The index of an open version-2 file; NULL for version 1 (decoded whole at open). */
const wvc2_index *wvol__wvc_file_index(const wvol_wvc_file *f);
/* Decoded chunk id (index bytes > 0), pinned in the cache: *q receives its bands'
 * quantised values (the level's band list order, the tile box x fastest each), *es their
 * size (int32, or int16 where the index's maximum allows); NULL after recording an error
 * in E. Unpin it with wvol__wvc_file_unpin. */
void *wvol__wvc_file_pin(wvol_wvc_file *f, wvc2_read_errors *E, size_t id, void *const **q, int *es);
void wvol__wvc_file_unpin(wvol_wvc_file *f, void *pinned);
/* Bytes of decoded chunks the cache holds while a chain of parents (one per level) and
 * `pinned` more chunks are pinned at once; the current budget. */
size_t wvol__wvc_file_pin_need(const wvol_wvc_file *f, int pinned);
size_t wvol__wvc_file_budget(const wvol_wvc_file *f);
/* dst[i] = the dequantised value of q[i], i < n, with a section's constants (o1 for +-1,
 * (|v| + d2) * step beyond, in double as the full decoder computes them: bit-equal values);
 * whether one is non-zero. The region read's gather and the piece reader's scatter. */
int wvol__wvc_dequant_run(float *dst, const int32_t *q, size_t n, double o1, double d2, double step);
int wvol__wvc_dequant_run16(float *dst, const int16_t *q, size_t n, double o1, double d2, double step);
/* The same on values of size es (4 or 2 bytes) from element `at` of q. */
int wvol__wvc_dequant_any(float *dst, const void *q, int es, size_t at, size_t n, double o1, double d2, double step);

#endif
