/* SPDX-License-Identifier: MIT */
/* Small helpers several C tests share. */
#ifndef WVOL_TEST_FIXTURES_H
#define WVOL_TEST_FIXTURES_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "wvol/store.h"
#include "wvol/volume.h"
#include "wvol/wavelet.h"

/* xorshift64 on the caller's state (each test seeds its own): deterministic, [0, 1)
 * from the top 53 bits. */
static inline double fixture_urand(uint64_t *state)
{
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    return (double)(*state >> 11) * (1.0 / 9007199254740992.0);
}

/* A filter by name; NULL if unknown (the tests name filters that exist). */
static inline const wvol_filter *fixture_filter(const char *name)
{
    const wvol_filter *f = NULL;
    wvol_filter_get(&f, name, NULL);
    return f;
}

/* A new nx x ny x nz volume holding value(v, i, j, k, ctx) at voxel (i, j, k); the voxels
 * are visited x fastest, then y, then z, so a value that draws random numbers draws them
 * in a fixed order. NULL when the volume cannot be made. */
typedef double (*fixture_voxel_fn)(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx);
static inline wvol_volume *fixture_volume(size_t nx, size_t ny, size_t nz, fixture_voxel_fn value, const void *ctx)
{
    wvol_volume *v = NULL;
    if (wvol_volume_create(&v, nx, ny, nz, NULL) != WVOL_OK) return NULL;
    for (size_t k = 0; k < nz; k++)
        for (size_t j = 0; j < ny; j++)
            for (size_t i = 0; i < nx; i++) v->data[i + nx * (j + ny * k)] = (float)value(v, i, j, k, ctx);
    return v;
}

/* A store of v's transform (filter, levels) keeping the largest fraction `keep` of the
 * coefficients (all when keep >= 1), splines with 2^J knots per unit; NULL on failure (with
 * the message on stderr). */
static inline wvol_store *fixture_store(const wvol_volume *v, const char *filter, int levels, double keep, int J)
{
    const wvol_filter *f = fixture_filter(filter);
    wvol_coeffs *c = NULL;
    wvol_selection *sel = NULL;
    wvol_store *s = NULL;
    wvol_select_params sp;
    wvol_select_params_default(&sp);
    wvol_store_params stp;
    wvol_store_params_default(&stp);
    wvol_error err;
    if (!f || wvol_dwt3(&c, v, f, levels, &err) != WVOL_OK) return NULL;
    if (keep < 1.0) {
        sp.mode = WVOL_SELECT_FRACTION;
        sp.fraction = keep;
        wvol_select(&sel, c, &sp, NULL, NULL, &err);
    }
    stp.spline_J = J;
    if (wvol_store_build(&s, c, sel, &stp, &err) != WVOL_OK) fprintf(stderr, "store: %s\n", err.message);
    wvol_selection_destroy(sel);
    wvol_coeffs_destroy(c);
    return s;
}

#endif
