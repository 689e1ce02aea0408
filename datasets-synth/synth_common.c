/* SPDX-License-Identifier: MIT
 * Generator plumbing: parameter checks, geometry, the parallel row loop, the table of
 * generators (the PRNG is the library's, core/rng.c). */
#include <math.h>
#include <stdint.h>
#include <string.h>
#include <strings.h>

#include "synth_internal.h"


/* ---- parameters and geometry --------------------------------------------- */

void wvol_synth_params_default(wvol_synth_params *p)
{
    memset(p, 0, sizeof *p);
    p->dims[0] = p->dims[1] = p->dims[2] = 64;
    p->seed = 1;
}

wvol_status wvol__synth_setup(wvol_volume **out, wvol_volume **labels, synth_grid *g,
                              const wvol_synth_params *p, const double default_spacing[3],
                              const char *kind, wvol_error *err)
{
    int a, given = 0;
    double extent = 0;
    wvol_status s;
    WVOL_RETURN_IF(!out || !p, err, WVOL_ERR_ARG, "synth %s: NULL argument", kind);
    *out = NULL;
    if (labels) *labels = NULL;
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
                   "synth %s: spacing (%g, %g, %g): give all three or none", kind, p->spacing[0],
                   p->spacing[1], p->spacing[2]);
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

    s = wvol_volume_create(out, g->nx, g->ny, g->nz, err);
    if (s) {
        wvol_error_prefix(err, "synth %s", kind);
        return s;
    }
    (*out)->spacing[0] = g->spacing[0];
    (*out)->spacing[1] = g->spacing[1];
    (*out)->spacing[2] = g->spacing[2];
    memcpy((*out)->origin, g->origin, sizeof g->origin);
    if (labels) {
        s = wvol_volume_clone(labels, *out, err);
        if (s) {
            wvol_volume_destroy(*out);
            *out = NULL;
            wvol_error_prefix(err, "synth %s labels", kind);
            return s;
        }
    }
    return WVOL_OK;
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

void wvol__synth_run_rows(const synth_grid *g, wvol_volume *v, wvol_volume *labels, synth_row_fn fn,
                          const void *ctx, const wvol_synth_params *p)
{
    long long rows = (long long)(g->ny * g->nz), r;
    long long done = 0, reported = 0, step = rows / 100 > 0 ? rows / 100 : 1;
    uint64_t noise_seed = wvol_hash64(p->seed ^ 0xC0FFEE0DDF00Dull);
    double sigma = p->noise;

#pragma omp parallel for schedule(dynamic, 4)
    for (r = 0; r < rows; r++) {
        size_t j = (size_t)r % g->ny, k = (size_t)r / g->ny, i, base = (size_t)r * g->nx;
        float *row = v->data + base;
        fn(ctx, g, j, k, row, labels ? labels->data + base : NULL);
        if (sigma > 0)
            for (i = 0; i < g->nx; i++)
                row[i] = (float)(row[i] + sigma * hashed_normal(noise_seed, base + i));
        if (p->progress) {
            long long d;
#pragma omp atomic capture
            d = ++done;
            if (d % step == 0) {
#pragma omp critical(wvol_synth_progress)
                if (d > reported) {
                    reported = d;
                    p->progress(p->progress_user, (double)d / (double)rows);
                }
            }
        }
    }
    if (p->progress) p->progress(p->progress_user, 1.0);
}

/* ---- the table of generators --------------------------------------------- */

static wvol_status make_gaussian(wvol_volume **o, wvol_volume **l, const wvol_synth_params *p,
                                 wvol_error *e)
{
    (void)l;
    return wvol_synth_gaussian(o, p, e);
}
static wvol_status make_blobs(wvol_volume **o, wvol_volume **l, const wvol_synth_params *p,
                              wvol_error *e)
{
    (void)l;
    return wvol_synth_blobs(o, p, e);
}
static wvol_status make_shepp(wvol_volume **o, wvol_volume **l, const wvol_synth_params *p,
                              wvol_error *e)
{
    (void)l;
    return wvol_synth_shepp_logan(o, p, e);
}

static const struct {
    const char *name;
    const char *about;
    size_t dims[3];
    int has_labels;
    wvol_status (*make)(wvol_volume **, wvol_volume **, const wvol_synth_params *, wvol_error *);
} kinds[] = {
    {"gaussian", "centred isotropic Gaussian density (the paper's Fig. 15), peak 1", {32, 32, 32}, 0,
     make_gaussian},
    {"blobs", "sum of seeded anisotropic Gaussians with different amplitudes", {64, 64, 64}, 0,
     make_blobs},
    {"skull", "skull-like CT phantom in Hounsfield-like units, tissue labels", {128, 128, 128}, 1,
     wvol_synth_skull},
    {"textures", "texture regions with curved boundaries, region labels (nz = 1: 2D)", {256, 256, 1},
     1, wvol_synth_textures},
    {"shepp-logan", "3D Shepp-Logan phantom (Kak & Slaney ellipsoids)", {128, 128, 128}, 0,
     make_shepp},
};
enum { KIND_COUNT = sizeof kinds / sizeof kinds[0] };

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
    for (a = 0; a < 3; a++) dims[a] = i >= 0 && i < KIND_COUNT ? kinds[i].dims[a] : 64;
}

wvol_status wvol_synth_make(wvol_volume **out, wvol_volume **labels, const char *kind,
                            const wvol_synth_params *p, wvol_error *err)
{
    int i = wvol_synth_kind_find(kind);
    if (labels) *labels = NULL;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "synth: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(i < 0, err, WVOL_ERR_ARG,
                   "unknown generator '%s' (known: gaussian, blobs, skull, textures, shepp-logan)",
                   kind ? kind : "(null)");
    return kinds[i].make(out, kinds[i].has_labels ? labels : NULL, p, err);
}
