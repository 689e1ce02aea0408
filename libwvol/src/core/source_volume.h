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

#endif
