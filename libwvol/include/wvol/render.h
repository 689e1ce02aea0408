/* SPDX-License-Identifier: MIT */
/* Volume rendering of the low-albedo integral (DESIGN.md section 8; paper eqs 32-47).
 *
 *   I = integral over [t1, t2] of C(t) exp(-integral over [t1, t] of kappa(s) ds) dt
 *
 * Modes: X-ray (I = integral of f dt, in value x world length), emission-absorption with the
 * transfer function (colour c(f), opacity kappa(f) per unit world length; emission c*kappa, so
 * that compositing alpha = 1 - exp(-kappa dt) converges to it), and the paper's linearised
 * exponential. Methods: the reference integrator (eq 33) on a dense volume, and the
 * spline-projected integrator from wavelet coefficients (eqs 34-46), exact for the spline model.
 *
 * Geometry: the rendered domain is the box of voxel cells, index coordinates
 * [-1/2, n-1/2] per axis (each sample owns the cell of size `spacing` around it), in world
 * units origin + index * spacing. Images are linear, premultiplied RGBA floats (wvol/image.h);
 * alpha = 1 - transmittance (X-ray: 1 where the ray meets the domain). Docs: docs/render.md.
 * Threading: the render calls run OpenMP over image tiles; the inputs are read only. */
#ifndef WVOL_RENDER_H
#define WVOL_RENDER_H

#include "wvol/export.h"
#include <stddef.h>
#include "wvol/image.h"
#include "wvol/volume.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Where the data sits in the world: sample (i, j, k) at origin + (i, j, k) * spacing. */
typedef struct wvol_geometry {
    size_t dims[3];
    double spacing[3];
    double origin[3];
} wvol_geometry;

WVOL_API void wvol_geometry_of_volume(wvol_geometry *g, const wvol_volume *v);
/* A NULL c zeroes *g; a NULL g does nothing. */
WVOL_API void wvol_geometry_of_coeffs(wvol_geometry *g, const wvol_coeffs *c);
/* World box of the rendered domain: lo = origin - spacing/2, hi = origin + (n - 1/2) spacing.
 * A NULL g zeroes lo and hi; a NULL lo or hi does nothing. */
WVOL_API void wvol_geometry_bounds(const wvol_geometry *g, double lo[3], double hi[3]);

/* ---- cameras ---------------------------------------------------------------------------- */

typedef enum wvol_projection {
    WVOL_PROJECTION_ORTHOGRAPHIC = 0,
    WVOL_PROJECTION_PERSPECTIVE = 1
} wvol_projection;

/* A look-at camera in world units. Pixel (x, y), row 0 at the top, has its centre at image
 * coordinates u = (x + 1/2)/width * 2 - 1 (right), v = 1 - (y + 1/2)/height * 2 (up).
 * Orthographic: rays start on the plane through `eye` normal to the view direction at
 * eye + u*(view_height*aspect/2)*right + v*(view_height/2)*up, all parallel to the view.
 * Perspective: rays leave `eye` towards forward + u*tan(fov/2)*aspect*right + v*tan(fov/2)*up.
 * forward = normalise(center - eye); right = normalise(forward x up); true up = right x forward.
 * Rays are whole lines clipped to the volume's box: an orthographic eye inside or in front of
 * the volume still sees all of it; a perspective ray starts at the eye. */
typedef struct wvol_camera {
    wvol_projection projection;
    int width, height;      /* pixels, 1..65536 */
    double eye[3];          /* world */
    double center[3];       /* look-at point, world */
    double up[3];           /* need not be orthogonal to the view; must not be parallel to it */
    double fov_y;           /* perspective: vertical field of view in degrees, (0, 180) */
    double view_height;     /* orthographic: world height the image covers, > 0 */
} wvol_camera;

/* Refuses non-finite values, eye == center, up parallel to the view, bad sizes. */
WVOL_API wvol_status wvol_camera_check(const wvol_camera *cam, wvol_error *err);

/* A camera looking along `view_dir` (from the camera towards the volume; need not be unit)
 * at the centre of the volume's box, framing the box exactly (orthographic: the projected
 * box fits the image; perspective: its bounding sphere fits the field of view fov_y, default
 * 30 degrees when fov_y <= 0). Up is +z, or +y when the view is along z. For a view along an
 * axis with width x height = the two other dimensions, pixel centres fall on voxel centres. */
WVOL_API wvol_status wvol_camera_frame(wvol_camera *cam, const wvol_geometry *g, const double view_dir[3],
                              wvol_projection projection, int width, int height, double fov_y,
                              wvol_error *err);

/* Parses a camera description (docs/render.md), for example
 *   "+z"   "-x"   "ortho dir=1,1,0.5"   "persp fov=40 from=-y zoom=1.5"
 *   "persp eye=300,200,100 center=64,64,64 up=0,0,1 fov=35"   "ortho eye=.. center=.. height=180"
 * Words: ortho|persp, an axis (+x -x +y -y +z -z: the side the camera looks from), from=AXIS,
 * dir=X,Y,Z (view direction), eye= center= up= (world), fov= (degrees), height= (ortho world
 * height), zoom= (> 1 magnifies the framed view). Unknown words and malformed values are refused
 * with a message naming them. */
WVOL_API wvol_status wvol_camera_parse(wvol_camera *cam, const char *spec, const wvol_geometry *g, int width,
                              int height, wvol_error *err);

/* World ray of pixel position (px, py) in pixel units (px = x + 0.5 is pixel x's centre):
 * origin and unit direction. The camera must have passed wvol_camera_check. A NULL cam zeroes
 * origin and dir; a NULL origin or dir does nothing. */
WVOL_API void wvol_camera_ray(const wvol_camera *cam, double px, double py, double origin[3], double dir[3]);

/* ---- transfer functions ------------------------------------------------------------------- */

#define WVOL_TF_MAX_POINTS 64

typedef struct wvol_tf_point {
    double value;           /* scalar value of the volume */
    double rgb[3];          /* linear colour, >= 0 */
    double opacity;         /* kappa, extinction per unit length (>= 0) */
} wvol_tf_point;

/* Piecewise-linear map value -> (colour, kappa); constant beyond the first and last points.
 * Units of kappa: per world unit, or per length of the volume's box diagonal when
 * per_diagonal is set (kappa_world = opacity / diagonal), which makes one TF fit any size. */
typedef struct wvol_tf {
    int count;              /* 1..WVOL_TF_MAX_POINTS, values strictly increasing */
    int per_diagonal;
    wvol_tf_point points[WVOL_TF_MAX_POINTS];
} wvol_tf;

WVOL_API wvol_status wvol_tf_check(const wvol_tf *tf, wvol_error *err);

/* Presets: "gaussian" (linear ramp over [vmin, vmax], the data range: blue to warm white,
 * kappa from 0 to 16 per diagonal), "ct-bone" and "ct-soft" (Hounsfield units; vmin/vmax
 * unused), "grey" (white, kappa linear 0..8 per diagonal over [vmin, vmax]). vmin and vmax
 * must be finite with vmin <= vmax (WVOL_ERR_ARG), for every preset. */
WVOL_API wvol_status wvol_tf_preset(wvol_tf *tf, const char *name, double vmin, double vmax, wvol_error *err);

/* Parses the text form: one point per line "value r g b opacity", '#' comments, and optional
 * lines "units world" (default) or "units diagonal"; or the JSON form
 *   {"units": "world"|"diagonal", "points": [[value, r, g, b, opacity], ...]}.
 * `what` names the source in messages (a file name). */
WVOL_API wvol_status wvol_tf_parse(wvol_tf *tf, const char *text, const char *what, wvol_error *err);
/* Reads a file in either form (JSON when its first non-blank character is '{'). */
WVOL_API wvol_status wvol_tf_load(wvol_tf *tf, const char *path, wvol_error *err);
/* A transfer function from what a user types: the path of an existing regular file is loaded
 * (wvol_tf_load; its errors keep their status), anything else is a preset name
 * (wvol_tf_preset with vmin, vmax; an unknown name is WVOL_ERR_ARG). */
WVOL_API wvol_status wvol_tf_resolve(wvol_tf *tf, const char *spec, double vmin, double vmax, wvol_error *err);

/* Colour and kappa (in the TF's own units) at value v. Either output may be NULL. The
 * per-sample call checks nothing: tf must be one wvol_tf_check accepts (what the wvol_tf_*
 * constructors make, and what the renderers check once per frame). */
WVOL_API void wvol_tf_eval(const wvol_tf *tf, double v, double rgb[3], double *kappa);

/* ---- rendering ------------------------------------------------------------------------------ */

typedef enum wvol_render_mode {
    WVOL_RENDER_MODE_XRAY = 0,              /* I = integral of f dt (grey; R = G = B) */
    WVOL_RENDER_MODE_ABSORPTION = 1,        /* emission-absorption, exact exponential */
    WVOL_RENDER_MODE_ABSORPTION_LINEAR = 2  /* the paper's linearised exponential (eqs 33, 45) */
} wvol_render_mode;

/* What wvol_render runs. AUTO is resolved by the library: a dense volume renders with
 * REFERENCE; a store with AXIS where that path is exact (X-ray, orthographic along an axis
 * whose extent is a multiple of 2^levels, no colour volume), else with BRICKS. SPLINE (exact
 * for the wavelet model, minutes per large frame), SPLAT and REFERENCE_FHAT run only when
 * asked. A store rendered with REFERENCE or REFERENCE_FHAT is first reconstructed whole
 * (dense volume, or dense coefficients): the reference's price of a store. */
typedef enum wvol_render_method {
    WVOL_RENDER_METHOD_AUTO = 0,
    WVOL_RENDER_METHOD_REFERENCE = 1,       /* eq 33 on trilinear samples of a dense volume */
    WVOL_RENDER_METHOD_REFERENCE_FHAT = 2,  /* eq 33 on samples of f^ (store only) */
    WVOL_RENDER_METHOD_BRICKS = 3,          /* eq 33 on bricks reconstructed on demand (store only) */
    WVOL_RENDER_METHOD_SPLINE = 4,          /* analytic integration of the kept functions (store only) */
    WVOL_RENDER_METHOD_AXIS = 5,            /* X-ray along an axis from 2D coefficients (store only) */
    WVOL_RENDER_METHOD_SPLAT = 6            /* X-ray of an orthographic view by splatting (store only) */
} wvol_render_method;

/* Names as the CLI and Python spell them ("auto", "reference", "reference-fhat", "bricks",
 * "spline", "axis", "splat"; "xray", "absorption", "absorption-linear"). parse refuses an
 * unknown name with WVOL_ERR_ARG and a message listing the valid ones. */
WVOL_API const char *wvol_render_method_name(wvol_render_method m);
WVOL_API wvol_status wvol_render_method_parse(wvol_render_method *m, const char *name, wvol_error *err);
WVOL_API const char *wvol_render_mode_name(wvol_render_mode m);
WVOL_API wvol_status wvol_render_mode_parse(wvol_render_mode *m, const char *name, wvol_error *err);

/* Settings read by one method only. Defaults (wvol_render_params_default) are the library's
 * and are defined there once. */
typedef struct wvol_render_reference_params {
    int brick;              /* min/max brick side for empty-space skipping, voxels (default 8;
                               0 = off) */
} wvol_render_reference_params;

typedef struct wvol_render_bricks_params {
    int brick;              /* side of the reconstructed bricks in voxel cells (default 32;
                               2..4096; 0 reads as the default) */
    int skip_inside;        /* 1 (default): inside a brick of at least 16 cells, skip the
                               samples in its sub-cells (8 per axis) where kappa (X-ray: the
                               value) is 0, exactly as whole bricks are skipped; 0: whole
                               bricks only (the images are the same; docs/render.md) */
} wvol_render_bricks_params;

typedef struct wvol_render_spline_params {
    int gauss_nodes;        /* Gauss-Legendre nodes per polynomial piece for the exponential
                               (default 5; 1..10) */
} wvol_render_spline_params;

typedef struct wvol_render_params {
    wvol_render_mode mode;
    wvol_render_method method; /* wvol_render only (default AUTO); the per-method calls ignore it */
    double step;            /* reference: step in voxels of the smallest spacing (default 0.5) */
    double termination;     /* stop a ray once transmittance < this (default 1e-6; 0 = never) */
    int shading;            /* 1: headlight diffuse shading from the gradient (eq 47); default 0 */
    double ambient;         /* shading: ambient share in [0, 1] (default 0.3) */
    int threads;            /* 0: OpenMP's default */
    int tile;               /* tile side in pixels; 0 (default): 16, or for the bricked path
                               the largest tile whose rays fit a quarter of the dense
                               volume's size (a tile's rays walk its bricks together and
                               build each once; the threads share a tile: 256 for a 512^2
                               frame of a 256^3 volume) */
    const float *colors;    /* optional colour volume (the segmentation's, DESIGN.md section 10):
                               linear RGB per voxel, 3 floats, x fastest, same grid as the
                               volume; replaces the TF's colour (kappa still comes from the TF).
                               Looked up at the nearest voxel, so classes keep crisp edges.
                               Absorption modes of the reference methods only; default NULL */
    size_t colors_count;    /* floats in colors: must be 3 * nx * ny * nz */
    double skip_tolerance;  /* reference and bricks: what a ray may skip, default 0 (skip only
                               what adds nothing). A brick whose bound on kappa (X-ray: on |f|)
                               times the ray's length in it fits in what is left of this
                               budget is skipped, so each pixel's optical depth (X-ray: its
                               integral) changes by at most skip_tolerance: alpha by at most
                               that much, a colour channel by at most that times the largest
                               colour. For stores whose ringing leaves near-transparent
                               haze where the original was empty. Needs the brick grid
                               (reference.brick > 0 for a dense volume); the spline methods
                               refuse it. */
    int preintegrate;       /* 1: pre-integrated transfer function (Engel, Kraus, Ertl 2001): the
                               scalar linear between consecutive samples, each segment's
                               emission-absorption integral exact for the piecewise-linear TF
                               (split at the knots it crosses), so a steep TF is not
                               under-sampled at a large step. Mode absorption, the sampling
                               methods (reference, reference-fhat, bricks), no colour volume;
                               default 0 (docs/render.md, "Pre-integration") */
    int gradient_levels;    /* shading from a store (bricks): the gradient of the wavelet
                               model's low-pass approximation with the details of the
                               gradient_levels finest levels dropped (1..the store's levels),
                               which smooths the noise and the voxel terracing a gradient of
                               the samples shows; the samples themselves are unchanged. 0
                               (default): the gradient of the sampled field. Other methods
                               refuse it (they have no wavelet model at hand) */
    wvol_render_reference_params reference;
    wvol_render_bricks_params bricks;
    wvol_render_spline_params spline;
} wvol_render_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_render_params_default(wvol_render_params *p);

typedef struct wvol_render_stats {
    wvol_render_method method; /* the method that ran (AUTO resolved) */
    double seconds;         /* wall clock */
    double cpu_seconds;     /* CPU time of the process during the render (all threads) */
    double reconstruct_cpu_seconds; /* wvol_render, REFERENCE(_FHAT) from a store: the part of
                               cpu_seconds spent reconstructing the dense volume (or
                               coefficients) before the integrator ran; else 0 */
    size_t rays, rays_hit;
    size_t samples;         /* reference: field samples taken; spline: quadrature nodes */
    size_t pieces;          /* spline: polynomial pieces integrated */
    size_t functions;       /* spline: basis-function / ray pairs integrated */
    size_t skipped;         /* reference: bricks skipped as empty; spline: pieces with no kept
                               function */
    size_t terminated;      /* rays stopped early by the termination threshold */
    size_t clamped;         /* absorption-linear: factors (1 - dtau) clamped at 0 */
    size_t bricks_built;    /* bricks: bricks reconstructed (cache misses, all threads) */
    size_t bricks_bound_skipped; /* bricks: bricks skipped on their coefficient bound alone
                                    (bound kappa 0; under skip_tolerance others may be too) */
    size_t skipped_tolerance; /* reference, bricks: brick runs skipped under skip_tolerance
                                 (their contribution not 0; counted in skipped too) */
    double skip_bound;      /* reference, bricks: the largest optical depth (X-ray: integral
                               bound) skipped on any pixel, <= skip_tolerance: the image's
                               bound on what skipping changed */
    int brick;              /* bricks: the brick side used (params->bricks.brick, or the default) */
    size_t bytes;           /* bricks: memory the call allocated (coefficient blocks, bounds,
                               brick caches and scratch, the tiles' rays; the image and the
                               store excluded); through a render context, what the context
                               holds (its brick cache included) and the frame's walk */
    /* Through a render context (wvol_render_context_frame); 0 from the one-shot calls. */
    int context_frame;      /* the context's frame number, 1 for the first (which builds the
                               block view and the bounds: its times include them); later frames
                               reuse them */
    int rates_reused;       /* bricks: 1 when the per-brick rates of earlier frames were kept
                               (the same kappa and mode); 0 after a TF change or in frame 1 */
    size_t bricks_reused;   /* bricks: bricks taken from the context's cache (built in an
                               earlier frame, or by another tile of this one) */
    size_t cache_bytes;     /* bricks: bytes of voxels the context's brick cache holds after
                               the frame (<= its budget) */
    int tiles_own;          /* bricks, two or more threads: 1 when each thread walked tiles of
                               its own (the context's cache held the bricks built so far), 0
                               when the threads shared each tile (docs/render.md, "The bricked
                               path"); the image is the same either way */
} wvol_render_stats;

/* What wvol_render renders: a dense volume or a store (wvol_render_source_volume / _store). */
typedef enum wvol_render_source_kind {
    WVOL_RENDER_SOURCE_VOLUME = 1,
    WVOL_RENDER_SOURCE_STORE = 2
} wvol_render_source_kind;

typedef struct wvol_render_source {
    wvol_render_source_kind kind;
    const wvol_volume *volume;  /* VOLUME */
    const wvol_store *store;    /* STORE */
} wvol_render_source;

WVOL_API wvol_render_source wvol_render_source_volume(const wvol_volume *v);
WVOL_API wvol_render_source wvol_render_source_store(const wvol_store *s);

/* The rendering entry point: params->method on the source (AUTO resolved as described at
 * wvol_render_method; stats->method says what ran). img must exist with the camera's size;
 * tf may be NULL in X-ray mode; params and stats may be NULL. A method the source cannot
 * serve (a store method on a dense volume, axis off an axis, splat in perspective) is
 * WVOL_ERR_UNSUPPORTED with the reason. The per-method functions below do the work; they
 * stay public for callers that want one method and nothing else. */
WVOL_API wvol_status wvol_render(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                        const wvol_tf *tf, const wvol_render_params *params, wvol_render_stats *stats,
                        wvol_error *err);

/* ---- a render context: set-up kept across frames ------------------------------------------ */

/* A source and settings rendered frame after frame (a user rotating the view): what does not
 * depend on the camera is built once and kept. For the bricked path (a store rendered by
 * `bricks`, or by AUTO where it picks bricks): the store's block view and coefficient bounds,
 * the per-brick rates (while the TF's kappa and the mode stay the same), and a cache of
 * reconstructed bricks shared by the threads, at most cache_bytes of voxels (0: the default,
 * WVOL_RENDER_CONTEXT_CACHE_DEFAULT of the dense volume's float32 size, at least 8 MiB), a brick
 * built in one frame taken again in the next. Other methods and a dense volume render as
 * wvol_render does (nothing kept). Every frame's image is wvol_render's for the same source,
 * camera, TF and params, bit for bit: what the context holds changes what is built, never
 * what is sampled. The source (and its store or volume) must outlive the context; a store is
 * not modified while a context uses it (wvol_render_context_set_source for another). Not for
 * two threads at once (a frame uses params->threads itself). */
typedef struct wvol_render_context wvol_render_context;

/* The default cache budget as a fraction of the dense volume's float32 bytes: the whole size,
 * what a dense renderer holds for the scalars alone (VTK's fixed-point mapper adds its gradient
 * tables), so that the bricks a turning view needs stay built; a viewer short of memory sets
 * less (the cache then keeps what it can: frames stay correct, later ones build more). */
#define WVOL_RENDER_CONTEXT_CACHE_DEFAULT 1.0

/* params NULL: defaults (the frame's params replace them: wvol_render_context_frame). Nothing is
 * built before the first frame, whose time includes the set-up. */
WVOL_API wvol_status wvol_render_context_create(wvol_render_context **out, const wvol_render_source *source,
                                                const wvol_render_params *params, size_t cache_bytes,
                                                wvol_error *err);
/* One frame: wvol_render(img, source, cam, tf, params) with the context's source. params NULL:
 * the context's (from create or the last frame). A change of the settings the kept state
 * depends on (threads, bricks.brick, bricks.skip_inside, shading with gradient_levels) builds
 * it again; a TF whose kappa or a mode that differs recomputes the rates (the cached bricks'
 * voxels stay). stats->context_frame, rates_reused, bricks_reused and cache_bytes say what was
 * reused. */
WVOL_API wvol_status wvol_render_context_frame(wvol_render_context *ctx, wvol_image *img, const wvol_camera *cam,
                                               const wvol_tf *tf, const wvol_render_params *params,
                                               wvol_render_stats *stats, wvol_error *err);
/* Another source (or the same store after it changed): everything kept is dropped. */
WVOL_API wvol_status wvol_render_context_set_source(wvol_render_context *ctx, const wvol_render_source *source,
                                                    wvol_error *err);
/* The context's source and params (for wvol_render_lod_context). */
WVOL_API const wvol_render_source *wvol_render_context_source(const wvol_render_context *ctx);
WVOL_API const wvol_render_params *wvol_render_context_params(const wvol_render_context *ctx);
/* Bytes the context holds (block view, bounds, rates, brick caches); 0 before a bricked frame. */
WVOL_API size_t wvol_render_context_bytes(const wvol_render_context *ctx);
WVOL_API void wvol_render_context_destroy(wvol_render_context *ctx); /* NULL is fine */

/* Reference integrator (eq 33) on a dense volume. img must exist with the camera's size.
 * Trilinear samples clamp to the edge voxels within the box. params/stats may be NULL. */
WVOL_API wvol_status wvol_render_reference(wvol_image *img, const wvol_volume *v, const wvol_camera *cam,
                                  const wvol_tf *tf, const wvol_render_params *params,
                                  wvol_render_stats *stats, wvol_error *err);

/* Reference integrator sampling f^ (all coefficients of c, zeros count as dropped) through
 * the spline tables b: the converged reference of the spline model (DESIGN.md section 8). */
WVOL_API wvol_status wvol_render_reference_fhat(wvol_image *img, const wvol_coeffs *c, const wvol_basis *b,
                                       const wvol_camera *cam, const wvol_tf *tf,
                                       const wvol_render_params *params, wvol_render_stats *stats,
                                       wvol_error *err);

/* Spline-projected integrator from a store (DESIGN.md section 8), never touching a dense
 * volume. Along a ray f^ is an exact piecewise polynomial (degree <= 9) on the lattice where
 * any axis crosses a spline knot of the finest level (x + s in 2^{1-J} Z). Each ray asks the
 * store for the kept basis functions whose support it crosses (wvol_store_query_ray descends
 * the octree) and adds each one's product of three composed cubic pieces to the polynomial of
 * every lattice piece it covers. X-ray integrates the polynomials exactly. The absorption
 * modes split each piece where f^ crosses a transfer-function knot (polynomial roots on the
 * piece), integrate the optical depth exactly (primitive of the polynomial) and the emission
 * with gauss_nodes Gauss-Legendre nodes per sub-piece; absorption-linear replaces exp(-dtau)
 * by max(0, 1 - dtau) per sub-piece (eq 45) and counts the clamps. Shading uses the analytic
 * gradient (eq 47), accumulated the same way from the derivative splines. */
WVOL_API wvol_status wvol_render_spline(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                               const wvol_tf *tf, const wvol_render_params *params,
                               wvol_render_stats *stats, wvol_error *err);

/* wvol_render_spline with each pixel's ray ending at world depth stop[x + width*y] (the ray
 * parameter t of wvol_camera_ray: world distance from the ray's origin); NaN or +inf (or a
 * depth past the box) integrates the whole ray, a depth before the box's entry gives nothing.
 * With the depth of an opaque surface this is the volume in front of it (the hybrid picture,
 * wvol_iso_render_hybrid). stop may be NULL. */
WVOL_API wvol_status wvol_render_spline_until(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                                     const wvol_tf *tf, const wvol_render_params *params, const float *stop,
                                     wvol_render_stats *stats, wvol_error *err);

/* The reference integrator (same samples, weights, compositing, termination) on the
 * trilinear interpolation of the store's reconstruction, which is never formed whole:
 * bricks of params->bricks.brick^3 voxel cells are reconstructed on demand by local
 * inverse transforms from a block-sparse view of the kept coefficients; a tile's rays walk
 * the bricks in front-to-back order, so each brick they need is reconstructed once per tile
 * into a small cache per thread; a brick whose coefficient bound shows kappa = 0 throughout
 * (or within the skip tolerance) is skipped unreconstructed. Equals wvol_render_reference on wvol_idwt3 of the same coefficients to
 * float rounding. stats->bytes reports what the call allocated. */
WVOL_API wvol_status wvol_render_bricks(wvol_image *img, const wvol_store *s, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err);

/* Fast path: X-ray along a coordinate axis (orthographic camera looking along an axis whose
 * extent is a multiple of 2^levels, so the ray covers whole periods of the model) from 2D
 * coefficients alone: each kept coefficient's ray-axis factor integrates to 2^{m/2} times the
 * integral of phi or psi (the spline's own, ~1 and ~0), leaving a 2D pyramid whose multi-level
 * expansion is evaluated at the pixel centres (O(kept + pixels * levels * 4 (L-1)^2)). Equals wvol_render_spline in X-ray mode to rounding. WVOL_ERR_UNSUPPORTED (with
 * the reason) for other cameras. */
WVOL_API wvol_status wvol_render_xray_axis(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                                  const wvol_render_params *params, wvol_render_stats *stats,
                                  wvol_error *err);

/* Fast path: X-ray for any orthographic view by footprint splatting. Every kept function is a
 * dilate and translate of one of 8 unit functions (band), whose X-ray along the view is a 2D
 * footprint shared by all levels; per view the footprints are tabulated once (integrals of
 * the spline model along lines: a fine 2D table, and a coarser 3D one of partial integrals
 * for the functions the box clips), then each function is splatted (bilinear, or trilinear
 * where clipped) onto the pixels its support projects to. Its error against wvol_render_spline
 * is the tables' interpolation error (docs/render.md). Cost O(sum of footprint areas),
 * independent of the ray length. WVOL_ERR_UNSUPPORTED (with the reason) for other modes,
 * perspective cameras, an untransformed axis, and filters of more than 10 taps (bl3). */
WVOL_API wvol_status wvol_render_xray_splat(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                                   const wvol_render_params *params, wvol_render_stats *stats,
                                   wvol_error *err);

/* ---- per-pixel error bounds (docs/render.md, "Error bounds") ---------------- */

/* Which per-pixel bound (wvol_render_bound or wvol_render_bound_coarse). */
typedef enum wvol_bound_method {
    WVOL_BOUND_NONE = 0,
    WVOL_BOUND_EXACT = 1,   /* wvol_render_bound */
    WVOL_BOUND_COARSE = 2   /* wvol_render_bound_coarse */
} wvol_bound_method;

typedef struct wvol_render_bound_stats {
    double max;             /* largest bound of any pixel (colour channels) */
    double mean;            /* mean over all pixels of the largest colour channel's bound */
    size_t functions;       /* spline path: dropped function / ray pairs integrated */
    size_t rays_hit;
    wvol_render_method method; /* the exact X-ray path that ran: AXIS or SPLINE; AUTO for the
                                  coarse bound */
    double coeff_error_density; /* coeff_error x the bound of sum_j |B_j| (per unit of ray) */
    double seconds;
} wvol_render_bound_stats;

/* A bound, per pixel, on how far the image of the kept coefficients can be from the image of
 * all of them: `residual` is the majorant store of the dropped coefficients (wvol_compress
 * with build_residual), `coeff_error` >= 0 a further error of every coefficient (a .wvc
 * quantiser's largest, wvol_wvc_max_coeff_error; 0 for none). X-ray: R = G = B >= sum over
 * dropped functions of |c| int |B| along the ray (+ coeff_error times the bound of sum |B|),
 * computed by the exact X-ray paths on the residual (axis where it applies, else spline: its
 * cost is that of a spline render of the residual), A = 0. Absorption:
 * per channel (L_E + c_max L_kappa) times that, A: L_kappa times it, each clipped to the
 * channel's range. It bounds the models' exact integrals (the spline integrator's), not the
 * sampling error of the sampled paths. Absorption-linear, shading and colour volumes are
 * refused (WVOL_ERR_UNSUPPORTED). Never NaN or negative; rounded up to float. */
WVOL_API wvol_status wvol_render_bound(wvol_image *bound, const wvol_store *residual, double coeff_error,
                                       const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *params,
                                       wvol_render_bound_stats *stats, wvol_error *err);

/* A coarser bound at the cost of one pass over the residual and O(1) per pixel, for any camera
 * (where the exact one would need the spline path: oblique and perspective views): each pixel's
 * chord times the sum over levels and bands of the band's largest dropped |c| times the bound
 * of sum |B| of that band (docs/render.md, "Error bounds"). Same inputs, output and refusals. */
WVOL_API wvol_status wvol_render_bound_coarse(wvol_image *bound, const wvol_store *residual, double coeff_error,
                                              const wvol_camera *cam, const wvol_tf *tf,
                                              const wvol_render_params *params, wvol_render_bound_stats *stats,
                                              wvol_error *err);

/* Image error: RMSE over all pixels and the 4 channels (or only `channel` 0..3 if >= 0) of a
 * against b, relative to the max |b| of those channels when relative is set. Same sizes. */
WVOL_API double wvol_image_rmse(const wvol_image *a, const wvol_image *b, int channel, int relative);

/* Deprecated names (one release; docs/conventions.md). */
#define WVOL_ORTHOGRAPHIC WVOL_PROJECTION_ORTHOGRAPHIC
#define WVOL_PERSPECTIVE WVOL_PROJECTION_PERSPECTIVE
#define WVOL_MODE_XRAY WVOL_RENDER_MODE_XRAY
#define WVOL_MODE_ABSORPTION WVOL_RENDER_MODE_ABSORPTION
#define WVOL_MODE_ABSORPTION_LINEAR WVOL_RENDER_MODE_ABSORPTION_LINEAR

#ifdef __cplusplus
}
#endif
#endif
