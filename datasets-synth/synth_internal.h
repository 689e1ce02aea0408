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

/* Checks p, picks spacing (default_spacing when p's is all zero; NULL = 1) and
 * centres the origin. */
wvol_status wvol__synth_geometry(synth_grid *g, const wvol_synth_params *p, const double default_spacing[3],
                                 const char *kind, wvol_error *err);

/* Fills one row (fixed j, k) of values (and labels when label_row is not NULL). */
typedef void (*synth_row_fn)(const void *ctx, const synth_grid *g, size_t j, size_t k, float *row,
                             float *label_row);

/* A generator ready to fill any slab: its grid, its row function and the context the
 * row function reads (heap, owned by the plan), the noise to add. Each generator's
 * planner fills one (wvol__synth_geometry, then wvol__synth_plan_ctx); whole volumes
 * and slabs are both made from it, so they hold the same bytes. */
typedef struct synth_plan {
    synth_grid g;
    synth_row_fn fn;
    void *ctx;
    double noise;
    uint64_t seed;
    int has_labels;
} synth_plan;
typedef wvol_status (*synth_plan_fn)(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);

/* Allocates the plan's context (zeroed, `bytes`) and sets its row function; NULL when
 * out of memory (the plan keeps nothing then). */
void *wvol__synth_plan_ctx(synth_plan *pl, size_t bytes, synth_row_fn fn);
void wvol__synth_plan_free(synth_plan *pl);

/* Fills rows k0 .. k0 + nz - 1 of every (j) into values (and labels when not NULL),
 * nx * ny * nz each, in parallel, adding the plan's noise * N(0, 1) per voxel from a
 * hash of (seed, global voxel index); progress (may be NULL) as in wvol_synth_params. */
void wvol__synth_rows(const synth_plan *pl, float *values, float *labels, size_t k0, size_t nz,
                      wvol_synth_progress_fn progress, void *progress_user);
/* The same for rows j0 .. j0 + nj - 1 of each slice (nx * nj * nz values): the same values as
 * those rows of a slab. */
void wvol__synth_band(const synth_plan *pl, float *values, float *labels, size_t k0, size_t nz, size_t j0,
                      size_t nj, wvol_synth_progress_fn progress, void *progress_user);

/* The planners, one per generator. */
wvol_status wvol__synth_plan_gaussian(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);
wvol_status wvol__synth_plan_blobs(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);
wvol_status wvol__synth_plan_skull(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);
wvol_status wvol__synth_plan_textures(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);
wvol_status wvol__synth_plan_shepp_logan(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);
wvol_status wvol__synth_plan_turbulence(synth_plan *pl, const wvol_synth_params *p, wvol_error *err);

/* The whole volume of a planner: plan, create the volume(s), fill, free the plan.
 * kind names the generator in messages. On failure nothing is left allocated. */
wvol_status wvol__synth_whole(wvol_volume **out, wvol_volume **labels, synth_plan_fn plan,
                              const wvol_synth_params *p, const char *kind, wvol_error *err);

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
