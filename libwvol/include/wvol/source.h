/* SPDX-License-Identifier: MIT */
/* Volume sources: a volume read slab by slab (slices z0 .. z0 + nz - 1, x fastest), so
 * that a volume larger than memory can be transformed and compressed with memory for a
 * few slabs (wvol_dwt3_stream, wvol_compress_stream). Files in raw and NRRD (raw or
 * gzip encoding) are read slab by slab; the synthetic generators make each slab on
 * demand (wvol_synth_source in wvol_synth.h); every other format is read whole on
 * open (wvol_source_streams says which; docs/formats.md lists them).
 *
 * Reads may go forward in any steps; a raw file also reads backwards (it seeks), a
 * gzip NRRD restarts from the beginning when asked for an earlier slab. Every slab is
 * checked for NaN/Inf (refused naming the voxel). A source is not shared between
 * threads. */
#ifndef WVOL_SOURCE_H
#define WVOL_SOURCE_H
#include "wvol/export.h"
#include <stddef.h>
#include "wvol/io.h"
#include "wvol/status.h"
#include "wvol/volume.h"
#ifdef __cplusplus
extern "C" {
#endif

typedef struct wvol_source wvol_source;

/* What a source of one's own provides: read() fills dst with nx * ny * nz floats of
 * slices z0 .. z0 + nz - 1 (the arguments are checked before the call); close() frees
 * ctx (may be NULL). */
typedef struct wvol_source_ops {
    wvol_status (*read)(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err);
    void (*close)(void *ctx);
} wvol_source_ops;

/* A source over callbacks; streams: 1 when a slab read does not hold the whole volume
 * (reported by wvol_source_streams). On failure ops->close(ctx) has been called. */
WVOL_API wvol_status wvol_source_create(wvol_source **out, const size_t dims[3], const double spacing[3],
                                        const double origin[3], const char *name, int streams,
                                        const wvol_source_ops *ops, void *ctx, wvol_error *err);
/* A source over a volume in memory (borrowed: it must outlive the source). */
WVOL_API wvol_status wvol_source_of_volume(wvol_source **out, const wvol_volume *v, wvol_error *err);
/* A source over a file (format by extension, as wvol_volume_load; opt as there, may be
 * NULL): raw and NRRD raw/gzip stream, the rest is loaded whole here. */
WVOL_API wvol_status wvol_source_open(wvol_source **out, const char *path, const wvol_load_options *opt,
                                      wvol_error *err);
/* 1 if the file's format is read slab by slab (raw, .nrrd/.nhdr with raw or gzip data). */
WVOL_API int wvol_source_format_streams(const char *path);

/* Geometry (each output may be NULL), the name for messages, and whether slabs stream. */
WVOL_API void wvol_source_geometry(const wvol_source *s, size_t dims[3], double spacing[3], double origin[3]);
WVOL_API const char *wvol_source_name(const wvol_source *s);
WVOL_API int wvol_source_streams(const wvol_source *s);
/* Slices z0 .. z0 + nz - 1 into dst (nx * ny * nz floats); refuses a range outside the
 * volume and non-finite samples. A read callback's failure without a message gets one naming
 * the source and the slices. */
WVOL_API wvol_status wvol_source_read(wvol_source *s, float *dst, size_t z0, size_t nz, wvol_error *err);
/* The whole volume (for the in-memory paths and tests). */
WVOL_API wvol_status wvol_source_read_volume(wvol_source *s, wvol_volume **out, wvol_error *err);
WVOL_API void wvol_source_destroy(wvol_source *s); /* NULL is fine */

#ifdef __cplusplus
}
#endif
#endif
