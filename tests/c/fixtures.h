/* SPDX-License-Identifier: MIT */
/* Small helpers several C tests share. */
#ifndef WVOL_TEST_FIXTURES_H
#define WVOL_TEST_FIXTURES_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "wvol/compress.h"
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

/* v with voxel spacing sp (origin 0), or NULL (v destroyed) when it cannot be set. */
static inline wvol_volume *fixture_with_spacing(wvol_volume *v, const double sp[3])
{
    const double org[3] = {0, 0, 0};
    if (v && wvol_volume_set_geometry(v, sp, org, NULL) != WVOL_OK) {
        wvol_volume_destroy(v);
        return NULL;
    }
    return v;
}

/* A thick shell (radius 0.35..0.6 of the half size, smooth edges) and a blob: structure at
 * every scale a few levels cover, and bricks far from both are empty (fixture_volume's value). */
static inline double fixture_shell_blob(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double x = (i - (v->nx - 1) / 2.0) / (v->nx / 2.0), y = (j - (v->ny - 1) / 2.0) / (v->ny / 2.0),
           z = (k - (v->nz - 1) / 2.0) / (v->nz / 2.0), r = sqrt(x * x + y * y + z * z);
    double shell = 0.5 * (tanh((r - 0.35) / 0.05) - tanh((r - 0.6) / 0.05));
    (void)ctx;
    return shell + 0.3 * exp(-((x - 0.1) * (x - 0.1) + y * y + z * z) / 0.02);
}

/* The library's pipeline (wvol_compress) on v: filter, levels, the largest fraction `keep` of
 * the coefficients (all when keep >= 1), splines with 2^J knots per unit (0: the default), the
 * store when `store` is set. 0 on success; on failure the message goes to stderr (a refusal may
 * be what a test expects: callers that need the result CHECK it). */
static inline int fixture_compress(wvol_compressed *out, const wvol_volume *v, const char *filter, int levels,
                                   double keep, int J, int store)
{
    wvol_compress_params p;
    wvol_error err;
    wvol_compress_params_default(&p);
    p.wavelet = filter;
    p.levels = levels;
    p.store.spline_J = J;
    p.build_store = store;
    if (keep < 1.0) {
        p.select.mode = WVOL_SELECT_FRACTION;
        p.select.fraction = keep;
    }
    if (wvol_compress(out, v, &p, &err) == WVOL_OK) return 0;
    fprintf(stderr, "fixture compress (%s, %d levels, keep %g): %s\n", filter, levels, keep, err.message);
    return -1;
}

/* The store alone of fixture_compress (the caller destroys it); NULL on failure. */
static inline wvol_store *fixture_store(const wvol_volume *v, const char *filter, int levels, double keep, int J)
{
    wvol_compressed c;
    wvol_store *s;
    if (fixture_compress(&c, v, filter, levels, keep, J, 1) != 0) return NULL;
    s = c.store;
    c.store = NULL;
    wvol_compressed_free(&c);
    return s;
}

#endif
