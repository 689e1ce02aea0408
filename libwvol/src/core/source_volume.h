/* SPDX-License-Identifier: MIT */
/* Declared internal interface of core/source.c for the other modules (not installed): the
 * slab read of a source over a wvol_volume in memory (ctx: the volume), which io's
 * whole-file sources share. */
#ifndef WVOL_CORE_SOURCE_VOLUME_H
#define WVOL_CORE_SOURCE_VOLUME_H

#include <stddef.h>

#include "wvol/status.h"

wvol_status wvol__source_volume_read(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err);

#endif
