/* SPDX-License-Identifier: MIT */
/* Dense scalar volumes. Index (i, j, k), x fastest: data[i + nx*(j + ny*k)].
 * World position = origin + index * spacing (DESIGN.md section 2).
 * wvol_volume is a plain descriptor (like zfp_field) so NumPy arrays and other
 * modules can map onto it; `owns` says whether wvol_volume_destroy frees data. */
#ifndef WVOL_VOLUME_H
#define WVOL_VOLUME_H

#include <stddef.h>
#include "wvol/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A volume: made by wvol_volume_create, _wrap, _clone or a loader, whose sizes and data
 * agree (nx ny nz samples at data). Callers may change the samples, spacing and origin; the
 * entry points trust the sizes to describe the array, as a pointer and a length are trusted,
 * so a descriptor assembled with other sizes is outside their contract. */
typedef struct wvol_volume {
    size_t nx, ny, nz;
    double spacing[3];
    double origin[3];
    float *data;
    int owns; /* 1: data was allocated by the library and is freed with the volume */
} wvol_volume;

/* Multiplies a*b*c (and element size) with overflow checks; returns 0 on overflow or a
 * NULL out. */
WVOL_API int wvol_size_mul3(size_t a, size_t b, size_t c, size_t elem, size_t *out);

/* Allocates a zero-filled volume, spacing 1, origin 0. Dimensions must be >= 1
 * and their product (in bytes) must fit size_t. */
WVOL_API wvol_status wvol_volume_create(wvol_volume **out, size_t nx, size_t ny, size_t nz, wvol_error *err);

/* Wraps caller memory without copying (owns = 0). */
WVOL_API wvol_status wvol_volume_wrap(wvol_volume **out, float *data, size_t nx, size_t ny, size_t nz,
                                      wvol_error *err);

/* Deep copy. */
WVOL_API wvol_status wvol_volume_clone(wvol_volume **out, const wvol_volume *v, wvol_error *err);

WVOL_API void wvol_volume_destroy(wvol_volume *v); /* NULL is fine */

WVOL_API size_t wvol_volume_count(const wvol_volume *v);

/* Checks spacing > 0 and finite, origin finite. */
WVOL_API wvol_status wvol_volume_set_geometry(wvol_volume *v, const double spacing[3], const double origin[3],
                                              wvol_error *err);

/* Refuses NaN/Inf, naming the first one's (i, j, k). `what` names the input in the message. */
WVOL_API wvol_status wvol_check_finite(const float *data, size_t nx, size_t ny, size_t nz, const char *what,
                                       wvol_error *err);

/* Min, max, mean (float64 accumulation) of the samples. Any output may be NULL. */
WVOL_API void wvol_volume_range(const wvol_volume *v, double *vmin, double *vmax, double *mean);

#ifdef __cplusplus
}
#endif
#endif
