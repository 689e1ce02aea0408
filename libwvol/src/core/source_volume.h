/* SPDX-License-Identifier: MIT */
/* Declared internal interface of core/source.c for the other modules (not installed): the
 * slab read of a source over a wvol_volume in memory (ctx: the volume), which io's
 * whole-file sources share, and the range of what a source's reads returned. */
#ifndef WVOL_CORE_SOURCE_VOLUME_H
#define WVOL_CORE_SOURCE_VOLUME_H

#include <stddef.h>

#include "wvol/source.h"
#include "wvol/status.h"

wvol_status wvol__source_volume_read(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err);

/* The range of every value a source's reads returned since it was made or since the last
 * reset (range[0] > range[1] when nothing was read): wvol_source_read takes it in the same
 * pass as its check for NaN and Inf (core/finite.h), so a caller needing the volume's range
 * does not scan the slabs again. The sign of a zero extreme is not specified. */
void wvol__source_seen_reset(wvol_source *s);
void wvol__source_seen_range(const wvol_source *s, float range[2]);

/* Row bands: rows y0 .. y0 + ny - 1 of slices z0 .. z0 + nz - 1 into dst (nx * ny * nz floats,
 * x fastest), for a reader that needs a small box of a large volume (the wavelet trial's
 * cubes) without the slices' other rows. A source gives it when it can reach any row (a raw
 * file, NRRD raw data, a volume in memory, a generator: wvol__source_set_rows);
 * wvol__source_read_rows then refuses a range outside the volume and non-finite samples as
 * wvol_source_read does, and returns WVOL_ERR_UNSUPPORTED, with no message, for a source
 * without it (gzip data, sources of one's own: read whole slices instead). */
typedef wvol_status (*wvol__source_rows_fn)(void *ctx, float *dst, size_t z0, size_t nz, size_t y0, size_t ny,
                                             wvol_error *err);
void wvol__source_set_rows(wvol_source *s, wvol__source_rows_fn fn);
wvol_status wvol__source_read_rows(wvol_source *s, float *dst, size_t z0, size_t nz, size_t y0, size_t ny,
                                   wvol_error *err);
wvol_status wvol__source_volume_rows(void *ctx, float *dst, size_t z0, size_t nz, size_t y0, size_t ny,
                                     wvol_error *err);

#endif
