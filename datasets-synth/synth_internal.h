/* SPDX-License-Identifier: MIT
 * Shared internals of the generators: parameter checks, grid geometry, the
 * parallel row loop (with progress and seeded noise). Not installed. */
#ifndef WVOL_SYNTH_INTERNAL_H
#define WVOL_SYNTH_INTERNAL_H

#include <math.h>

#include "wvol_synth.h"
#include "core/status_internal.h"

typedef struct synth_grid {
    size_t nx, ny, nz;
    double spacing[3];
    double origin[3];
    double scale;      /* normalised coordinate u = world * scale = world / (E / 2) */
    double voxel_u;    /* largest voxel edge in normalised units (anti-aliasing width) */
} synth_grid;

/* World position of index n along axis a, and its normalised coordinate. */
static inline double synth_u(const synth_grid *g, int a, size_t n)
{
    return (g->origin[a] + (double)n * g->spacing[a]) * g->scale;
}

/* Checks p, picks spacing (default_spacing when p's is all zero; NULL = 1),
 * centres the origin, creates the volume and (if labels) a label volume of the same
 * geometry. On failure nothing is left allocated. */
wvol_status wvol__synth_setup(wvol_volume **out, wvol_volume **labels, synth_grid *g,
                              const wvol_synth_params *p, const double default_spacing[3],
                              const char *kind, wvol_error *err);

/* Fills one row (fixed j, k) of values (and labels when label_row is not NULL). */
typedef void (*synth_row_fn)(const void *ctx, const synth_grid *g, size_t j, size_t k, float *row,
                             float *label_row);

/* Runs fn over every row in parallel, then adds p->noise * N(0, 1) per voxel from
 * a hash of (seed, voxel index), and reports progress. */
void wvol__synth_run_rows(const synth_grid *g, wvol_volume *v, wvol_volume *labels, synth_row_fn fn,
                          const void *ctx, const wvol_synth_params *p);

/* Uniform in [0, 1) from a hash of its arguments (stateless, thread-safe). */
static inline double synth_hash_unit(uint64_t seed, uint64_t a, uint64_t b)
{
    uint64_t h = wvol_hash64(seed ^ wvol_hash64(a * 0x9E3779B97F4A7C15ull + b));
    return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}

static inline double synth_clamp(double x, double lo, double hi)
{
    return x < lo ? lo : x > hi ? hi : x;
}

static inline double synth_smoothstep(double e0, double e1, double x)
{
    double t = synth_clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

#endif
