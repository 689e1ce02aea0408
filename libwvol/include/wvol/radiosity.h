/* SPDX-License-Identifier: MIT
 * Wavelet radiosity: the radiosity integral equation of scenes of planar quadrilaterals projected
 * onto tree wavelets on each patch's parameter square (Haar = M1, Alpert multiwavelets M2-M4,
 * flatlets F2 F3), links refined by a kernel-smoothness oracle, solved by gather and push-pull.
 * Based on: Gortler, Schroeder, Cohen, Hanrahan 1993 (wavelet radiosity); Hanrahan, Salzman,
 * Aupperle 1991 (hierarchical radiosity); Alpert 1993 (multiwavelets). docs/radiosity.md.
 * Threading: handles are not shared between threads; const handles may be read concurrently. */
#ifndef WVOL_RADIOSITY_H
#define WVOL_RADIOSITY_H

#include "wvol/export.h"
#include <stddef.h>
#include "wvol/image.h"
#include "wvol/render.h"
#include "wvol/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One patch: corners in counter-clockwise order seen from the lit (front) side; the patch's
 * parameter square maps bilinearly, x(u, v) = p0 + u (p1 - p0) + v (p3 - p0) + u v (p0 - p1 + p2 - p3). */
typedef struct wvol_radiosity_quad {
    double p[4][3];
    double emission[3];     /* radiant exitance, RGB, >= 0 */
    double reflectance[3];  /* Lambertian reflectance, RGB, in [0, 1] */
} wvol_radiosity_quad;

typedef struct wvol_radiosity_scene wvol_radiosity_scene;

/* A scene from n >= 1 quads (copied). Refuses NaN/Inf, degenerate, non-planar or non-convex quads,
 * emission < 0 and reflectance outside [0, 1], naming the quad and field. */
WVOL_API wvol_status wvol_radiosity_scene_create(wvol_radiosity_scene **out, const wvol_radiosity_quad *quads, size_t n,
                                        wvol_error *err);
/* Built-in scenes: "parallel" (emitter of side 1, 0.1 above a receiver of side 2), "perpendicular"
 * (emitter of width 1 standing on the middle of an edge-sharing receiver of side 2), "box" (a closed
 * Cornell-like box of side 1 with two blocks and a ceiling light). Unknown names are refused. */
WVOL_API wvol_status wvol_radiosity_scene_builtin(wvol_radiosity_scene **out, const char *name, wvol_error *err);
/* Wavefront OBJ with its MTL (mtllib): quads only (f with 4 vertices), materials by usemtl with Kd
 * (reflectance) and Ke (emission). A missing MTL, a face without material, triangles and malformed
 * lines are refused with the file, line and face. */
WVOL_API wvol_status wvol_radiosity_scene_load_obj(wvol_radiosity_scene **out, const char *path, wvol_error *err);
WVOL_API void wvol_radiosity_scene_destroy(wvol_radiosity_scene *s); /* NULL is fine */

WVOL_API size_t wvol_radiosity_scene_count(const wvol_radiosity_scene *s);
/* The i-th quad (NULL when i is out of range). */
WVOL_API const wvol_radiosity_quad *wvol_radiosity_scene_quad(const wvol_radiosity_scene *s, size_t i);
/* Area and unit front normal of quad i (either pointer may be NULL). */
WVOL_API void wvol_radiosity_scene_quad_geometry(const wvol_radiosity_scene *s, size_t i, double *area, double normal[3]);
/* Axis-aligned bounds of all corners (untouched for a NULL scene). */
WVOL_API void wvol_radiosity_scene_bounds(const wvol_radiosity_scene *s, double lo[3], double hi[3]);

/* Closed-form (Lambert) differential-area-to-quad form factor from point x with unit normal n to
 * quad i, without occlusion; the part of the quad behind x's plane is clipped away. */
WVOL_API double wvol_radiosity_point_form_factor(const wvol_radiosity_scene *s, size_t i, const double x[3],
                                        const double n[3]);
/* Patch-to-patch form factor F_ij (fraction of i's power reaching j) by an n x n x n x n
 * Gauss-Legendre rule (1 <= n <= 16) with visibility by rays against the scene. */
WVOL_API wvol_status wvol_radiosity_form_factor(const wvol_radiosity_scene *s, size_t i, size_t j, int n, double *out,
                                       wvol_error *err);

typedef enum wvol_radiosity_basis {
    WVOL_RADIOSITY_BASIS_HAAR = 0, /* M1: piecewise constant */
    WVOL_RADIOSITY_BASIS_M2 = 1,
    WVOL_RADIOSITY_BASIS_M3 = 2,
    WVOL_RADIOSITY_BASIS_M4 = 3,
    WVOL_RADIOSITY_BASIS_F2 = 4,
    WVOL_RADIOSITY_BASIS_F3 = 5
} wvol_radiosity_basis;

/* "haar" (or "m1"), "m2", "m3", "m4", "f2", "f3". */
WVOL_API wvol_status wvol_radiosity_basis_parse(const char *name, wvol_radiosity_basis *out, wvol_error *err);
WVOL_API const char *wvol_radiosity_basis_name(wvol_radiosity_basis b);
/* Coefficients per node (M*M) of a basis. */
WVOL_API int wvol_radiosity_basis_size(wvol_radiosity_basis b);

typedef struct wvol_radiosity_params {
    wvol_radiosity_basis basis; /* default haar */
    double epsilon;             /* oracle threshold on the estimated L1 transport error (area units); 1e-3 */
    int max_level;              /* finest level: cells of 2^-max_level of each patch side; 5 */
    int brightness;             /* 1: weight the oracle by receiver reflectance x source radiosity (Fig. 8) */
    int refine_passes;          /* with brightness: refine-solve passes; 2 */
    int full_matrix;            /* 1: classical radiosity, every finest cell linked to every other (no oracle) */
    int max_iterations;         /* Jacobi gather/push-pull sweeps; 200 */
    double tolerance;           /* stop when the largest coefficient change <= tolerance x largest; 1e-7 */
} wvol_radiosity_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_radiosity_params_default(wvol_radiosity_params *p);

typedef struct wvol_radiosity_stats {
    size_t links;          /* interactions (links between nodes) */
    size_t link_terms;     /* coefficients on them (links x (M*M)^2) */
    size_t nodes, leaves;  /* quadtree nodes over all patches */
    size_t kernel_evals;   /* point-to-point kernel evaluations (oracle and quadrature) */
    size_t closed_form_evals; /* point-to-polygon form factors (touching flatlet/Haar links) */
    size_t rays;           /* visibility rays cast */
    int iterations;        /* sweeps run by the last solve */
    double change;         /* last relative change */
    double seconds_refine, seconds_solve;
    double emitted[3];     /* power emitted, RGB */
    double absorbed[3];    /* power absorbed at convergence, RGB */
    double energy_error;   /* max over channels |absorbed - emitted| / emitted (0 when nothing emits) */
} wvol_radiosity_stats;

typedef struct wvol_radiosity wvol_radiosity;

/* Solves the scene (which must outlive the solution). stats may be NULL. WVOL_ERR_NUMERIC, and no
 * solution, when the sweeps do not settle within max_iterations. */
WVOL_API wvol_status wvol_radiosity_solve(wvol_radiosity **out, const wvol_radiosity_scene *scene,
                                 const wvol_radiosity_params *p, wvol_radiosity_stats *stats, wvol_error *err);
WVOL_API void wvol_radiosity_destroy(wvol_radiosity *r); /* NULL is fine */

/* Radiosity (RGB) at n parameter points uv[2k], uv[2k+1] in [0, 1] of patch i, from the basis
 * functions of the leaf holding each point: rgb[3k + c]. */
WVOL_API wvol_status wvol_radiosity_eval(const wvol_radiosity *r, size_t patch, size_t n, const double *uv, double *rgb,
                                wvol_error *err);
/* Radiosity on a res x res grid of cell centres of each patch: rgb[((i * res + iv) * res + iu) * 3 + c]
 * (count * res * res * 3 doubles). */
WVOL_API wvol_status wvol_radiosity_sample(const wvol_radiosity *r, int res, double *rgb, wvol_error *err);

/* Renders the radiosity seen by the camera (front faces only), straight from the basis functions;
 * alpha 1 where a patch is hit. img must exist with the camera's size. */
WVOL_API wvol_status wvol_radiosity_render(const wvol_radiosity *r, wvol_image *img, const wvol_camera *cam, wvol_error *err);
/* World geometry of the scene, for wvol_camera_parse framing. */
WVOL_API void wvol_radiosity_geometry(const wvol_radiosity_scene *s, wvol_geometry *g);

/* Writes each patch as res x res quads with per-cell RGB radiosity ("radiosity")
 * and the patch index: .ply (binary; four unshared vertices per cell carry its radiosity_r/g/b floats and
 * sRGB red/green/blue bytes) or .vtp (ASCII VTK
 * XML, CellData). Atomic. */
WVOL_API wvol_status wvol_radiosity_write_mesh(const wvol_radiosity *r, const char *path, int res, wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
