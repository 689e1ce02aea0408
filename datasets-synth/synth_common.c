/* SPDX-License-Identifier: MIT
 * Generator plumbing: parameter checks, geometry, the parallel row loop, the table of
 * generators (the PRNG is the library's, core/rng.c). */
#include <math.h>
#include <stdio.h>
#include <stdint.h>
#include <string.h>
#include <stdlib.h>
#include <strings.h>

#include "synth_internal.h"
#include "core/finite.h"
#include "core/source_volume.h"


/* ---- parameters and geometry --------------------------------------------- */

void wvol_synth_params_default(wvol_synth_params *p)
{
    memset(p, 0, sizeof *p);
    p->dims[0] = p->dims[1] = p->dims[2] = 64;
    p->seed = 1;
}

wvol_status wvol__synth_geometry(synth_grid *g, const wvol_synth_params *p, const double default_spacing[3],
                                 const char *kind, wvol_error *err)
{
    int a, given = 0;
    double extent = 0;
    WVOL_RETURN_IF(!g || !p, err, WVOL_ERR_ARG, "synth %s: NULL argument", kind);
    WVOL_RETURN_IF(!(p->noise >= 0) || !isfinite(p->noise), err, WVOL_ERR_ARG,
                   "synth %s: noise sigma %g must be finite and >= 0", kind, p->noise);
    for (a = 0; a < 3; a++) {
        WVOL_RETURN_IF(p->dims[a] == 0, err, WVOL_ERR_DIMS,
                       "synth %s: size %zux%zux%zu: every dimension must be at least 1", kind,
                       p->dims[0], p->dims[1], p->dims[2]);
        WVOL_RETURN_IF(!isfinite(p->spacing[a]) || p->spacing[a] < 0, err, WVOL_ERR_ARG,
                       "synth %s: spacing %g must be finite and positive", kind, p->spacing[a]);
        if (p->spacing[a] > 0) given++;
    }
    WVOL_RETURN_IF(given != 0 && given != 3, err, WVOL_ERR_ARG,
                   "synth %s: spacing (%g, %g, %g): give three positive values, or none (0: the default)", kind,
                   p->spacing[0], p->spacing[1], p->spacing[2]);
    {
        /* the samples' bytes must be countable (a generator's per-axis tables are smaller) */
        size_t bytes;
        WVOL_RETURN_IF(!wvol_size_mul3(p->dims[0], p->dims[1], p->dims[2], sizeof(float), &bytes) ||
                           bytes > (SIZE_MAX >> 1),
                       err, WVOL_ERR_DIMS, "synth %s: size %zux%zux%zu overflows", kind, p->dims[0], p->dims[1],
                       p->dims[2]);
    }
    memset(g, 0, sizeof *g);
    g->nx = p->dims[0];
    g->ny = p->dims[1];
    g->nz = p->dims[2];
    for (a = 0; a < 3; a++) {
        g->spacing[a] = given ? p->spacing[a] : default_spacing ? default_spacing[a] : 1.0;
        g->origin[a] = -0.5 * (double)(p->dims[a] - 1) * g->spacing[a];
        if ((double)p->dims[a] * g->spacing[a] > extent) extent = (double)p->dims[a] * g->spacing[a];
    }
    g->scale = 2.0 / extent;
    for (a = 0; a < 3; a++)
        if (g->spacing[a] * g->scale > g->voxel_u) g->voxel_u = g->spacing[a] * g->scale;
    return WVOL_OK;
}

void *wvol__synth_plan_ctx(synth_plan *pl, size_t bytes, synth_row_fn fn)
{
    pl->ctx = calloc(1, bytes ? bytes : 1);
    pl->fn = fn;
    return pl->ctx;
}

void wvol__synth_plan_free(synth_plan *pl)
{
    if (!pl) return;
    free(pl->ctx);
    pl->ctx = NULL;
}

/* A standard normal from a hash of (seed, index): same value for the same voxel
 * whatever the thread schedule. */
static inline double hashed_normal(uint64_t seed, uint64_t idx)
{
    uint64_t h1 = wvol_hash64(seed ^ wvol_hash64(2 * idx + 0x5851F42D4C957F2Dull));
    uint64_t h2 = wvol_hash64(h1 ^ 0x14057B7EF767814Full);
    double u1 = ((double)(h1 >> 11) + 0.5) * (1.0 / 9007199254740992.0);
    double u2 = (double)(h2 >> 11) * (1.0 / 9007199254740992.0);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

void wvol__synth_rows(const synth_plan *pl, float *values, float *labels, size_t k0, size_t nz,
                      wvol_synth_progress_fn progress, void *progress_user)
{
    wvol__synth_band(pl, values, labels, k0, nz, 0, pl->g.ny, progress, progress_user);
}

void wvol__synth_band(const synth_plan *pl, float *values, float *labels, size_t k0, size_t nz, size_t j0,
                      size_t nj, wvol_synth_progress_fn progress, void *progress_user)
{
    const synth_grid *g = &pl->g;
    long long rows = (long long)(nj * nz), r;
    long long done = 0, reported = 0, step = rows / 100 > 0 ? rows / 100 : 1;
    uint64_t noise_seed = wvol_hash64(pl->seed ^ 0xC0FFEE0DDF00Dull);
    double sigma = pl->noise;

#pragma omp parallel for schedule(dynamic, 4)
    for (r = 0; r < rows; r++) {
        size_t j = j0 + (size_t)r % nj, k = k0 + (size_t)r / nj, i, local = (size_t)r * g->nx;
        size_t base = (j + g->ny * k) * g->nx; /* the voxel's index in the whole volume */
        float *row = values + local;
        pl->fn(pl->ctx, g, j, k, row, labels ? labels + local : NULL);
        if (sigma > 0)
            for (i = 0; i < g->nx; i++)
                row[i] = (float)(row[i] + sigma * hashed_normal(noise_seed, base + i));
        if (progress) {
            long long d;
#pragma omp atomic capture
            d = ++done;
            if (d % step == 0) {
#pragma omp critical(wvol_synth_progress)
                if (d > reported) {
                    reported = d;
                    progress(progress_user, (double)d / (double)rows);
                }
            }
        }
    }
    if (progress) progress(progress_user, 1.0);
}

/* Runs a planner; the plan holds the noise and seed the rows need. Nothing is left
 * allocated on failure. */
static wvol_status make_plan(synth_plan *pl, synth_plan_fn plan, const wvol_synth_params *p, wvol_error *err)
{
    wvol_status s;
    memset(pl, 0, sizeof *pl);
    s = plan(pl, p, err);
    if (s) {
        wvol__synth_plan_free(pl);
        return s;
    }
    pl->noise = p->noise;
    pl->seed = p->seed;
    /* what would make samples or the placement non-finite is refused before any sample is
     * made: a spacing whose centred origin overflows, a noise beyond float32 (the samples'
     * type) at ten standard deviations */
    s = wvol__geometry_check(pl->g.spacing, pl->g.origin, err);
    if (!s && !(fabs(p->noise) <= 3e37))
        s = wvol_error_set(err, WVOL_ERR_ARG, "noise %g: at most 3e37 (the samples are float32)", p->noise);
    if (s) {
        wvol__synth_plan_free(pl);
        return s;
    }
    return WVOL_OK;
}

wvol_status wvol__synth_whole(wvol_volume **out, wvol_volume **labels, synth_plan_fn plan,
                              const wvol_synth_params *p, const char *kind, wvol_error *err)
{
    synth_plan pl;
    wvol_status s;
    WVOL_RETURN_IF(!out || !p, err, WVOL_ERR_ARG, "synth %s: NULL argument", kind);
    *out = NULL;
    if (labels) *labels = NULL;
    WVOL_FORWARD(make_plan(&pl, plan, p, err));
    s = wvol_volume_create(out, pl.g.nx, pl.g.ny, pl.g.nz, err);
    if (!s) {
        (*out)->spacing[0] = pl.g.spacing[0];
        (*out)->spacing[1] = pl.g.spacing[1];
        (*out)->spacing[2] = pl.g.spacing[2];
        memcpy((*out)->origin, pl.g.origin, sizeof pl.g.origin);
        if (labels && pl.has_labels) s = wvol_volume_clone(labels, *out, err);
    }
    if (s) {
        wvol_volume_destroy(*out);
        *out = NULL;
        wvol__synth_plan_free(&pl);
        wvol_error_prefix(err, "synth %s", kind);
        return s;
    }
    wvol__synth_rows(&pl, (*out)->data, labels && *labels ? (*labels)->data : NULL, 0, pl.g.nz, p->progress,
                     p->progress_user);
    wvol__synth_plan_free(&pl);
    /* a generator's parameters (sizes of objects, amplitudes) could still overflow float32 */
    s = wvol_check_finite((*out)->data, pl.g.nx, pl.g.ny, pl.g.nz, "synthetic volume", err);
    if (s) {
        wvol_volume_destroy(*out);
        *out = NULL;
        if (labels) {
            wvol_volume_destroy(*labels);
            *labels = NULL;
        }
        wvol_error_prefix(err, "synth %s", kind);
        return s;
    }
    return WVOL_OK;
}

/* ---- the table of generators --------------------------------------------- */

static const struct {
    const char *name;
    const char *about;
    size_t dims[3];
    int has_labels;
    synth_plan_fn plan;
} kinds[] = {
    {"gaussian", "centred isotropic Gaussian density (the paper's Fig. 15), peak 1", {32, 32, 32}, 0,
     wvol__synth_plan_gaussian},
    {"blobs", "sum of seeded anisotropic Gaussians with different amplitudes", {64, 64, 64}, 0,
     wvol__synth_plan_blobs},
    {"skull", "skull-like CT phantom in Hounsfield-like units, tissue labels", {128, 128, 128}, 1,
     wvol__synth_plan_skull},
    {"textures", "texture regions with curved boundaries, region labels (nz = 1: 2D)", {256, 256, 1},
     1, wvol__synth_plan_textures},
    {"shepp-logan", "3D Shepp-Logan phantom (Kak & Slaney ellipsoids)", {128, 128, 128}, 0,
     wvol__synth_plan_shepp_logan},
    {"turbulence", "turbulence-like field: random-phase Fourier modes, k^(-5/3) spectrum, unit variance",
     {128, 128, 128}, 0, wvol__synth_plan_turbulence},
};
enum { KIND_COUNT = sizeof kinds / sizeof kinds[0] };
#define KNOWN_KINDS "gaussian, blobs, skull, textures, shepp-logan, turbulence"

int wvol_synth_kind_count(void)
{
    return KIND_COUNT;
}

const char *wvol_synth_kind_name(int i)
{
    return i >= 0 && i < KIND_COUNT ? kinds[i].name : NULL;
}

const char *wvol_synth_kind_about(int i)
{
    return i >= 0 && i < KIND_COUNT ? kinds[i].about : NULL;
}

int wvol_synth_kind_find(const char *name)
{
    int i;
    if (!name) return -1;
    for (i = 0; i < KIND_COUNT; i++)
        if (strcasecmp(name, kinds[i].name) == 0) return i;
    if (strcasecmp(name, "shepp_logan") == 0 || strcasecmp(name, "shepplogan") == 0)
        return wvol_synth_kind_find("shepp-logan");
    return -1;
}

int wvol_synth_kind_has_labels(int i)
{
    return i >= 0 && i < KIND_COUNT ? kinds[i].has_labels : 0;
}

void wvol_synth_kind_default_dims(int i, size_t dims[3])
{
    int a;
    if (!dims) return;
    for (a = 0; a < 3; a++) dims[a] = i >= 0 && i < KIND_COUNT ? kinds[i].dims[a] : 64;
}

static wvol_status find_kind(int *i, const char *kind, wvol_error *err)
{
    *i = wvol_synth_kind_find(kind);
    WVOL_RETURN_IF(*i < 0, err, WVOL_ERR_ARG, "unknown generator '%s' (known: " KNOWN_KINDS ")",
                   kind ? kind : "(null)");
    return WVOL_OK;
}

wvol_status wvol_synth_make(wvol_volume **out, wvol_volume **labels, const char *kind,
                            const wvol_synth_params *p, wvol_error *err)
{
    int i;
    if (labels) *labels = NULL;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "synth: output pointer is NULL");
    *out = NULL;
    WVOL_FORWARD(find_kind(&i, kind, err));
    return wvol__synth_whole(out, kinds[i].has_labels ? labels : NULL, kinds[i].plan, p, kinds[i].name, err);
}

/* ---- slabs ------------------------------------------------------------------ */

struct wvol_synth_gen {
    synth_plan plan;
};

wvol_status wvol_synth_gen_open(wvol_synth_gen **out, const char *kind, const wvol_synth_params *p, wvol_error *err)
{
    int i;
    wvol_synth_gen *g;
    wvol_status s;
    WVOL_RETURN_IF(!out || !p, err, WVOL_ERR_ARG, "synth: NULL argument");
    *out = NULL;
    WVOL_FORWARD(find_kind(&i, kind, err));
    g = calloc(1, sizeof *g);
    WVOL_RETURN_IF(!g, err, WVOL_ERR_NOMEM, "synth %s: out of memory", kinds[i].name);
    s = make_plan(&g->plan, kinds[i].plan, p, err);
    if (s) {
        free(g);
        return s;
    }
    *out = g;
    return WVOL_OK;
}

void wvol_synth_gen_geometry(const wvol_synth_gen *g, size_t dims[3], double spacing[3], double origin[3])
{
    if (!g) return;
    if (dims) dims[0] = g->plan.g.nx, dims[1] = g->plan.g.ny, dims[2] = g->plan.g.nz;
    if (spacing) memcpy(spacing, g->plan.g.spacing, sizeof g->plan.g.spacing);
    if (origin) memcpy(origin, g->plan.g.origin, sizeof g->plan.g.origin);
}

int wvol_synth_gen_has_labels(const wvol_synth_gen *g)
{
    return g ? g->plan.has_labels : 0;
}

wvol_status wvol_synth_gen_slab(const wvol_synth_gen *g, float *values, float *labels, size_t z0, size_t nz,
                                wvol_error *err)
{
    WVOL_RETURN_IF(!g || !values, err, WVOL_ERR_ARG, "synth slab: NULL argument");
    WVOL_RETURN_IF(nz == 0 || z0 > g->plan.g.nz || nz > g->plan.g.nz - z0, err, WVOL_ERR_ARG,
                   "synth slab: slices %zu .. %zu outside 0 .. %zu", z0, z0 + nz, g->plan.g.nz);
    WVOL_RETURN_IF(labels && !g->plan.has_labels, err, WVOL_ERR_ARG, "synth slab: this generator makes no labels");
    wvol__synth_rows(&g->plan, values, labels, z0, nz, NULL, NULL);
    return WVOL_OK;
}

void wvol_synth_gen_close(wvol_synth_gen *g)
{
    if (!g) return;
    wvol__synth_plan_free(&g->plan);
    free(g);
}

static wvol_status gen_read(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err)
{
    return wvol_synth_gen_slab(ctx, dst, NULL, z0, nz, err);
}

/* Row bands (core/source_volume.h; the source checked the range): only the rows asked for are
 * made, each as a slab makes it (the noise hashed from the voxel's index in the volume). */
static wvol_status gen_rows(void *ctx, float *dst, size_t z0, size_t nz, size_t y0, size_t ny, wvol_error *err)
{
    const wvol_synth_gen *g = ctx;
    (void)err;
    wvol__synth_band(&g->plan, dst, NULL, z0, nz, y0, ny, NULL, NULL);
    return WVOL_OK;
}

static void gen_close(void *ctx) { wvol_synth_gen_close(ctx); }

wvol_status wvol_synth_source(wvol_source **out, const char *kind, const wvol_synth_params *p, wvol_error *err)
{
    static const wvol_source_ops ops = {gen_read, gen_close};
    wvol_synth_gen *g;
    size_t dims[3];
    double spacing[3], origin[3];
    char name[64];
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "synth: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol_synth_gen_open(&g, kind, p, err));
    wvol_synth_gen_geometry(g, dims, spacing, origin);
    snprintf(name, sizeof name, "synth %s", kind);
    WVOL_FORWARD(wvol_source_create(out, dims, spacing, origin, name, 1, &ops, g, err));
    wvol__source_set_rows(*out, gen_rows);
    return WVOL_OK;
}
