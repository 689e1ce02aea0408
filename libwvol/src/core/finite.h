/* SPDX-License-Identifier: MIT */
/* Declared internal interface of core/volume.c for the other modules (not installed): the
 * test for NaN and Inf (refused at the door, and wherever values may overflow), and the one
 * pass over a slab that the checked reads make, which gives the slab's range as well, so a
 * caller that needs both reads the data once. */
#ifndef WVOL_CORE_FINITE_H
#define WVOL_CORE_FINITE_H

#include <stddef.h>

#include "wvol/status.h"

/* 1 when d[0..n) is all finite (no NaN, no Inf), else 0; in eight lanes. */
int wvol__all_finite(const float *d, size_t n);

/* 1 when d[0..n) is all finite, with range[0] and range[1] its smallest and largest value
 * (the sign of a zero extreme is not specified: compare them as numbers); 0 when a NaN or
 * an Inf is among them (range then unspecified). n = 0 gives 1 and the range (+Inf, -Inf).
 * From 1 Mi values, outside a parallel region, split among the OpenMP threads. */
int wvol__finite_range(const float *d, size_t n, float range[2]);

/* WVOL_OK when every spacing is finite and > 0 and every origin finite (either array may be
 * NULL), else WVOL_ERR_ARG naming the first bad value: wvol_volume_set_geometry's test, which
 * a volume source makes when it is created, before any of its data is read. */
wvol_status wvol__geometry_check(const double spacing[3], const double origin[3], wvol_error *err);

#endif
