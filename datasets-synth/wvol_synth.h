/* SPDX-License-Identifier: MIT
 * Deterministic synthetic volumes: the paper's Gaussian density, a multi-blob
 * variant, a skull-like CT phantom, texture mosaics with ground-truth labels,
 * and the 3D Shepp-Logan phantom (docs/datasets.md describes each one).
 *
 * Every generator is a pure function of (parameters, seed): the same parameters
 * and seed give the same bytes, whatever the number of threads. Each voxel's value
 * depends only on its index, the parameters and the seed (noise included: a
 * counter-based hash of (seed, voxel index), never rand()).
 *
 * Geometry (all generators): voxel (i, j, k) sits at world position
 * origin + (i, j, k) * spacing, with the origin chosen so the volume is centred on
 * world (0, 0, 0). The object is defined in normalised coordinates u in [-1, 1]
 * across the LARGEST world extent E = max_a(n_a * spacing_a), u = x / (E / 2), so it
 * looks the same at any resolution, and anisotropic spacing keeps its true shape
 * (a shorter axis shows a centred slab of it).
 *
 * Threading: generators use OpenMP over rows; the params struct is only read. */
#ifndef WVOL_SYNTH_H
#define WVOL_SYNTH_H

#include <stddef.h>
#include <stdint.h>

#include "wvol/rng.h" /* the generators' PRNG and hash (wvol_rng, wvol_hash64) */
#include "wvol/source.h"
#include "wvol/volume.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Called with the fraction of rows done so far (0..1), from any thread but never
 * from two at once, with rising fractions, ending with 1. */
typedef void (*wvol_synth_progress_fn)(void *user, double fraction);

typedef struct wvol_synth_params {
    size_t dims[3];        /* nx, ny, nz, each >= 1; nz = 1 makes a 2D image */
    double spacing[3];     /* world size of a voxel; all 0 = the generator's default
                              (1 per axis; skull: 240 mm / max(n), isotropic) */
    uint64_t seed;         /* drives blobs, textures, the skull's bone texture, noise */
    double noise;          /* sigma of additive Gaussian noise in the generator's units
                              (skull: HU); 0 = none */
    double sigma;          /* gaussian: sigma in normalised units; 0 = 0.25 */
    int count;             /* blobs: number of Gaussians (1..64, 0 = 5);
                              textures: number of regions (2..16, 0 = 4) */
    const char *variant;   /* textures: "gratings" (default), "frequencies", "dots", "mixed";
                              shepp-logan: "kak-slaney" (default), "yu-ye-wang"; NULL = default */
    wvol_synth_progress_fn progress; /* may be NULL */
    void *progress_user;
} wvol_synth_params;

/* dims 64^3, spacing 0 (default), seed 1, no noise, defaults for the rest. */
WVOL_API void wvol_synth_params_default(wvol_synth_params *p);

/* Centred isotropic Gaussian, the density of the paper's Fig. 15:
 * f(u) = exp(-|u|^2 / (2 sigma^2)), peak 1, u normalised (sigma 0.25 by default,
 * so the f = 0.5 isosurface is a sphere of radius 0.294 E/2). */
WVOL_API wvol_status wvol_synth_gaussian(wvol_volume **out, const wvol_synth_params *p, wvol_error *err);

/* Sum of `count` anisotropic, rotated Gaussians with different amplitudes
 * (0.3..1), widths (0.06..0.22) and centres (|u| <= 0.45 per axis), all drawn
 * from the seed: not symmetric. */
WVOL_API wvol_status wvol_synth_blobs(wvol_volume **out, const wvol_synth_params *p, wvol_error *err);

/* Skull-like CT phantom in Hounsfield-like units (air -1000, soft tissue 0..80,
 * CSF 8, brain 30..40, bone 700..1800). labels (may be NULL): tissue classes as
 * float, WVOL_SKULL_* below. */
WVOL_API wvol_status wvol_synth_skull(wvol_volume **out, wvol_volume **labels, const wvol_synth_params *p,
                                      wvol_error *err);

enum {
    WVOL_SKULL_AIR = 0,   /* outside the head, and the air cavities inside it */
    WVOL_SKULL_SOFT = 1,  /* skin, muscle, eyes, orbital and other soft tissue */
    WVOL_SKULL_BRAIN = 2, /* grey and white matter, brainstem, spinal cord */
    WVOL_SKULL_CSF = 3,   /* ventricles and the layer under the skull */
    WVOL_SKULL_BONE = 4,  /* skull, face bones, jaw, teeth, vertebrae */
    WVOL_SKULL_CLASSES = 5
};

/* Texture mosaic: `count` regions separated by curved boundaries (a warped
 * Voronoi partition drawn from the seed), each filled with its own texture,
 * values in [0, 1]. labels (may be NULL): region index 0..count-1 as float.
 * Grating periods and dot sizes are in voxels (index space). */
WVOL_API wvol_status wvol_synth_textures(wvol_volume **out, wvol_volume **labels, const wvol_synth_params *p,
                                         wvol_error *err);

/* 3D Shepp-Logan phantom: Kak & Slaney's ellipsoid table (Principles of
 * Computerized Tomographic Imaging, 1988, Table 3.2, with the published errata),
 * point-sampled at voxel centres. variant "kak-slaney": the book's densities
 * (2.0, -0.98, ...; brain 1.0..1.04); "yu-ye-wang": the higher-contrast densities
 * of Yu, Ye & Wang 2004 (1.0, -0.8, ...). */
WVOL_API wvol_status wvol_synth_shepp_logan(wvol_volume **out, const wvol_synth_params *p, wvol_error *err);

/* Turbulence-like field: a sum of random-phase Fourier modes (random directions, log-
 * spaced wavenumber shells jittered by the seed) whose energy spectrum is k^(-5/3) from the
 * box scale down to a period of 4 voxels, scaled to unit variance (docs/datasets.md). */
WVOL_API wvol_status wvol_synth_turbulence(wvol_volume **out, const wvol_synth_params *p, wvol_error *err);
/* ---- by name: "gaussian", "blobs", "skull", "textures", "shepp-logan", "turbulence" ---- */

/* Runs the generator called `kind`. labels may be NULL; when it is not, *labels is
 * set to the label map, or NULL for kinds without one. */
WVOL_API wvol_status wvol_synth_make(wvol_volume **out, wvol_volume **labels, const char *kind,
                                     const wvol_synth_params *p, wvol_error *err);

WVOL_API int wvol_synth_kind_count(void);
WVOL_API const char *wvol_synth_kind_name(int i);     /* NULL when out of range */
WVOL_API const char *wvol_synth_kind_about(int i);    /* one line */
/* Index of a kind by name, -1 if unknown. */
WVOL_API int wvol_synth_kind_find(const char *name);
/* 1 if the kind makes a label map. */
WVOL_API int wvol_synth_kind_has_labels(int i);
/* The kind's default size (used when the caller has none); NULL dims: does nothing. */
WVOL_API void wvol_synth_kind_default_dims(int i, size_t dims[3]);

/* ---- slab by slab -------------------------------------------------------------
 * A generator made ready once (its tables and context), then asked for any slab of
 * slices z0 .. z0 + nz - 1: the slab holds the same bytes as those slices of the whole
 * volume (each voxel depends only on its index, the parameters and the seed), so a
 * volume of any size is made with memory for one slab. The progress callback of the
 * parameters is not called. A wvol_synth_gen may be read from several threads at once
 * (wvol_synth_gen_slab only reads it). */
typedef struct wvol_synth_gen wvol_synth_gen;
WVOL_API wvol_status wvol_synth_gen_open(wvol_synth_gen **out, const char *kind, const wvol_synth_params *p,
                                         wvol_error *err);
/* dims, spacing, origin (each may be NULL) of the whole volume. */
WVOL_API void wvol_synth_gen_geometry(const wvol_synth_gen *g, size_t dims[3], double spacing[3],
                                      double origin[3]);
WVOL_API int wvol_synth_gen_has_labels(const wvol_synth_gen *g);
/* values (and labels, NULL or only for a kind with labels): nx * ny * nz floats each. */
WVOL_API wvol_status wvol_synth_gen_slab(const wvol_synth_gen *g, float *values, float *labels, size_t z0,
                                         size_t nz, wvol_error *err);
WVOL_API void wvol_synth_gen_close(wvol_synth_gen *g); /* NULL is fine */
/* The generator as a volume source (wvol/source.h) of its values, for the streamed
 * transform and compression: each read makes the slab asked for. */
WVOL_API wvol_status wvol_synth_source(wvol_source **out, const char *kind, const wvol_synth_params *p,
                                       wvol_error *err);
#ifdef __cplusplus
}
#endif
#endif
