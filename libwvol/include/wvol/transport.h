/* SPDX-License-Identifier: MIT */
/* Wavelet radiative transfer in Nusselt coordinates (Lewis & Fournier 2002): radiance leaving or
 * reaching a planar quadrilateral as a 4D Haar expansion over (u, v, k, l) in [0, 1]^4 — (u, v)
 * the position in the quad's parameter space, (k, l) = ((mu_x + 1)/2, (mu_y + 1)/2) the direction
 * projected onto the unit disc of the quad's frame — kept sparse in a hashed wavelet coefficient
 * tree; transport coefficients T_jk between two quads by the paper's reduction to 2D integrals,
 * with five quadrature families; the oracle-driven propagation of its Figs. 10-11; surface
 * interaction (Lambertian, Phong) as a product of Haar projections; the stained-glass scene of
 * its section 7.3. Conventions and coordinate systems: docs/transport.md.
 *
 * Handles are not shared between threads; read-only functions on a const handle may run
 * concurrently. */
#ifndef WVOL_TRANSPORT_H
#define WVOL_TRANSPORT_H

#include "wvol/export.h"
#include <stddef.h>
#include <stdint.h>

#include "wvol/image.h"
#include "wvol/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Largest level (2^level cells per axis, 16^level finest cells). */
#define WVOL_TRANSPORT_MAX_LEVELS 6

/* A planar parallelogram p0 p1 p2 p3 (world units). Parameter space: x(u, v) = p0 + u (p1 - p0)
 * + v (p3 - p0), u, v in [0, 1] (the paper's rectilinear mapping); its normal n = (p1 - p0) x
 * (p3 - p0), normalised, is the side light leaves (sources) or arrives from (destinations).
 * Refused: non-finite, degenerate (zero area, collinear edges), non-planar, not a parallelogram. */
typedef struct wvol_transport_quad {
    double p[4][3];
} wvol_transport_quad;

/* Checks a quad; the message names the defect. */
WVOL_API wvol_status wvol_transport_quad_check(const wvol_transport_quad *q, wvol_error *err);

/* Rules for the 2D transport integrals (paper §7.1.4). `samples` is the integrand count: the
 * grids take the largest (2^m + 1)^2 (Romberg) or n^2 (trapezoid, stratified) not above it. */
typedef enum wvol_transport_quadrature {
    WVOL_TRANSPORT_QUADRATURE_TRAPEZOID = 0,   /* n x n trapezoidal rule */
    WVOL_TRANSPORT_QUADRATURE_ROMBERG1 = 1,    /* Romberg, linear (one Richardson step) */
    WVOL_TRANSPORT_QUADRATURE_ROMBERG2 = 2,    /* quadratic (two steps) */
    WVOL_TRANSPORT_QUADRATURE_ROMBERG3 = 3,    /* cubic (three steps) */
    WVOL_TRANSPORT_QUADRATURE_MONTE_CARLO = 4, /* plain pseudo-random (xoshiro256**) */
    WVOL_TRANSPORT_QUADRATURE_STRATIFIED = 5,  /* jittered n x n strata */
    WVOL_TRANSPORT_QUADRATURE_HALTON = 6,      /* Halton, bases 2 and 3 */
    WVOL_TRANSPORT_QUADRATURE_HAMMERSLEY = 7,  /* Hammersley, (i + 1/2)/N and base 2 */
    WVOL_TRANSPORT_QUADRATURE_COUNT = 8
} wvol_transport_quadrature;

/* "trapezoid", "romberg1", ... "hammersley" (the CLI's names); NULL for a bad value. */
WVOL_API const char *wvol_transport_quadrature_name(wvol_transport_quadrature q);
/* The value of a name, or -1. */
WVOL_API int wvol_transport_quadrature_find(const char *name);

typedef struct wvol_transport_params {
    int levels;                             /* finest level of the destination tree, 1..MAX (3) */
    wvol_transport_quadrature quadrature;   /* (TRAPEZOID) */
    int samples;                            /* integrand evaluations per T_jk, 1..2^24 (16) */
    uint64_t seed;                          /* Monte Carlo streams (1) */
    int use_oracle;                         /* interval-arithmetic oracle on (1) */
    int threads;                            /* wvol_transport_run's threads, 0 = OpenMP's default (0);
                                             * results depend on the count only through float sums */
} wvol_transport_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_transport_params_default(wvol_transport_params *p);

/* A pure smoothing (n = 0) Haar index: level and cell m = (m_u, m_v, m_k, m_l), 0 <= m < 2^level. */
typedef struct wvol_transport_index {
    int level;
    int m[4];
} wvol_transport_index;

/* ---- the wavelet coefficient tree (paper §7.2.2): RGB, hashed nodes -------------------------- */

typedef struct wvol_transport_tree wvol_transport_tree;

/* An empty tree (all coefficients zero) of `levels` levels (1..MAX). */
WVOL_API wvol_status wvol_transport_tree_create(wvol_transport_tree **out, int levels, wvol_error *err);
WVOL_API void wvol_transport_tree_destroy(wvol_transport_tree *t); /* NULL is fine */
WVOL_API int wvol_transport_tree_levels(const wvol_transport_tree *t);
/* Stored nodes (the root included) and non-zero scalar coefficients (channels counted apart). */
WVOL_API size_t wvol_transport_tree_nodes(const wvol_transport_tree *t);
WVOL_API size_t wvol_transport_tree_coefficients(const wvol_transport_tree *t);

/* Finest cells: 16^levels cells of 3 floats, cell (mu, mv, mk, ml) at
 * 3 * (mu + N (mv + N (mk + N ml))), N = 2^levels: the mean radiance over the cell. */
WVOL_API size_t wvol_transport_cells_count(int levels);

/* Haar analysis of finest cell means into a new tree; wavelet coefficients of magnitude
 * <= threshold (>= 0) are dropped. Refuses NaN/Inf. */
WVOL_API wvol_status wvol_transport_tree_from_cells(wvol_transport_tree **out, const float *cells, int levels,
                                           double threshold, wvol_error *err);
/* Haar synthesis into cells (capacity `cap` floats, at least 3 * cells_count(levels)). */
WVOL_API wvol_status wvol_transport_tree_to_cells(float *cells, size_t cap, const wvol_transport_tree *t, wvol_error *err);
/* Point value of the expansion at q = (u, v, k, l) in [0, 1]^4 (1 belongs to the last cell). */
WVOL_API wvol_status wvol_transport_tree_eval(const wvol_transport_tree *t, const double q[4], float rgb[3], wvol_error *err);
/* Keeps the `keep` fraction (0, 1] of the largest-magnitude wavelet coefficients (the root's
 * smoothing coefficient always stays); *kept (may be NULL) gets how many scalars remain. */
WVOL_API wvol_status wvol_transport_tree_compress(wvol_transport_tree *t, double keep, size_t *kept, wvol_error *err);
/* Power through the quad (paper eq. 14, Haar): 4 * area * b_0, per channel. Exact for radiance
 * that vanishes outside the unit disc (every transported or reflected tree). */
WVOL_API wvol_status wvol_transport_tree_power(double power[3], const wvol_transport_tree *t, const wvol_transport_quad *q,
                                      wvol_error *err);
/* Power of an emitter whose projection extends its radiance outside the unit disc (the window, a
 * constant emitter): 4 * area * sum over finest cells of mean * volume * the cell's disc share. */
WVOL_API wvol_status wvol_transport_tree_power_emitted(double power[3], const wvol_transport_tree *t,
                                              const wvol_transport_quad *q, wvol_error *err);

/* Radiance as a function for projection: rgb at q = (u, v, k, l); values at directions outside
 * the unit disc are never transported (a constant emitter may keep its constant there). Return
 * non-zero to stop with an error. */
typedef int (*wvol_transport_radiance_fn)(void *user, const double q[4], float rgb[3]);

/* Projects a radiance onto the finest cells of `levels` by a g^4-point Gauss-Legendre rule per
 * cell (g = 1..8), then into a tree (threshold as in from_cells). */
WVOL_API wvol_status wvol_transport_project(wvol_transport_tree **out, int levels, wvol_transport_radiance_fn fn, void *user,
                                   int g, double threshold, wvol_error *err);

/* ---- transport --------------------------------------------------------------------------------- */

/* One transport coefficient T_jk (paper eq. 18) between pure smoothing bases j on the source and
 * k on the destination, by the 2D reduction and the chosen rule (the oracle is not used). */
WVOL_API wvol_status wvol_transport_coefficient(double *T, const wvol_transport_quad *src, const wvol_transport_quad *dst,
                                       const wvol_transport_index *j, const wvol_transport_index *k,
                                       const wvol_transport_params *p, wvol_error *err);

typedef struct wvol_transport_stats {
    size_t evaluated;     /* T_jk integrated numerically */
    size_t oracle_zero;   /* pairs the oracle rejected */
    size_t oracle_exact;  /* pairs the oracle found fully inside (exact) */
    size_t samples;       /* integrand evaluations */
    double seconds;       /* wall clock */
} wvol_transport_stats;

/* Transports the source's radiance tree (outgoing, source frame) to the incident radiance tree of
 * the destination (directions pointing back towards where the light comes from, destination frame)
 * with p->levels levels, by wct_transport / tc_propagate (paper Figs. 10-11). No occluders. */
WVOL_API wvol_status wvol_transport_run(wvol_transport_tree **out, const wvol_transport_tree *src,
                               const wvol_transport_quad *src_quad, const wvol_transport_quad *dst_quad,
                               const wvol_transport_params *p, wvol_transport_stats *stats, wvol_error *err);

/* ---- surface interaction ------------------------------------------------------------------------ */

typedef enum wvol_transport_brdf_kind {
    WVOL_TRANSPORT_BRDF_LAMBERT = 0,  /* albedo / pi */
    WVOL_TRANSPORT_BRDF_PHONG = 1     /* kd / pi + ks (n + 2) / (2 pi) max(0, r . v)^n, r the mirror of l */
} wvol_transport_brdf_kind;

typedef struct wvol_transport_brdf {
    wvol_transport_brdf_kind kind;
    float kd[3];      /* diffuse albedo per channel, >= 0 */
    float ks[3];      /* specular (Phong), >= 0; kd + ks <= 1 keeps energy */
    double exponent;  /* Phong n, >= 0 */
} wvol_transport_brdf;

/* Reflected (outgoing) radiance tree from an incident tree: per position cell, the reflected
 * direction cells are the product of the incident cells with the level's Haar projection of the
 * BRDF (paper eqs. 22-27, whose delta tensors reduce to one level for Haar). brdf_of(user, u, v)
 * picks the BRDF at a position cell's centre (NULL: brdfs[0] everywhere). */
typedef const wvol_transport_brdf *(*wvol_transport_brdf_at)(void *user, double u, double v);
WVOL_API wvol_status wvol_transport_reflect(wvol_transport_tree **out, const wvol_transport_tree *incident,
                                   const wvol_transport_brdf *brdf, wvol_transport_brdf_at brdf_of, void *user,
                                   double threshold, wvol_error *err);

/* ---- the stained-glass window scene (paper §7.3, Figs. 12-16) ------------------------------------ */

/* An RGB window image, linear floats rgb[3 * (x + width * y)], row 0 at the top (far edge). The
 * entry points taking one check that rgb is set and the sizes positive, and trust rgb to hold
 * 3 width height floats, as a pointer and a length are trusted (a window made by the readers
 * above always does). */
typedef struct wvol_transport_window {
    int width, height;
    float *rgb;
} wvol_transport_window;

/* The built-in synthetic window (size x size, 8..4096): coloured panes, lead lines, a rose. */
WVOL_API wvol_status wvol_transport_window_synthetic(wvol_transport_window *w, int size, wvol_error *err);
/* Reads an 8-bit or 16-bit RGB(A) or palette PNG (sRGB decoded to linear); refuses greyscale,
 * unreadable or oversized files with a message. */
WVOL_API wvol_status wvol_transport_window_read_png(wvol_transport_window *w, const char *path, wvol_error *err);
WVOL_API void wvol_transport_window_free(wvol_transport_window *w);

typedef struct wvol_transport_scene {
    wvol_transport_quad window;   /* horizontal square, normal down */
    wvol_transport_quad floor;    /* below it, normal up */
    double peak[3];               /* unit travel direction of the peak (45 degrees down) */
    double lobe_exponent;         /* radiance ~ max(0, cos(angle to peak))^e (4) */
    double source_threshold;      /* window tree threshold (0) */
    int tiles;                    /* floor checkerboard tiles per side (4) */
    wvol_transport_brdf diffuse, glossy;  /* the two tile BRDFs */
} wvol_transport_scene;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_transport_scene_default(wvol_transport_scene *s);

/* The window's outgoing radiance as a tree: image (mean of 8 x 8 nearest-pixel
 * samples per position cell) times the lobe (mean of 8 x 8 Gauss points per direction cell). */
WVOL_API wvol_status wvol_transport_scene_source(wvol_transport_tree **out, const wvol_transport_scene *s,
                                        const wvol_transport_window *w, int levels, wvol_error *err);

/* The whole computation of §7.3: the window's radiance tree, its transport to the floor (incident
 * radiance), the floor's reflection (checkerboard of s->diffuse and s->glossy tiles). The trees
 * belong to the result: wvol_transport_scene_result_free releases them (a zeroed result is fine). */
typedef struct wvol_transport_scene_result {
    wvol_transport_tree *source, *incident, *reflected;
    wvol_transport_stats transport;
    double seconds_source, seconds_reflect;
} wvol_transport_scene_result;

WVOL_API wvol_status wvol_transport_scene_run(wvol_transport_scene_result *r, const wvol_transport_scene *s,
                                     const wvol_transport_window *w, const wvol_transport_params *p, wvol_error *err);
WVOL_API void wvol_transport_scene_result_free(wvol_transport_scene_result *r);

/* Views (paper Figs. 14-16). grid: one tile of 2^L x 2^L position cells (cell_px pixels each) per
 * direction cell, tiles in a 2^L x 2^L matrix (k right, l down), 1-pixel gaps; img is created.
 * exposure (> 0) scales the radiance. */
WVOL_API wvol_status wvol_transport_grid_image(wvol_image **img, const wvol_transport_tree *t, int cell_px,
                                      double exposure, wvol_error *err);
/* The brightest direction cell's position tile, cell_px pixels per cell. */
WVOL_API wvol_status wvol_transport_detail_image(wvol_image **img, const wvol_transport_tree *t, int cell_px,
                                        double exposure, wvol_error *err);
/* A perspective frame of the floor from `eye` looking at `center` (fov_y degrees), sampling the
 * reflected tree at each pixel's floor point towards the eye. */
WVOL_API wvol_status wvol_transport_floor_image(wvol_image **img, const wvol_transport_tree *reflected,
                                       const wvol_transport_quad *floor, const double eye[3], const double center[3],
                                       double fov_y, int width, int height, double exposure, wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
