/* SPDX-License-Identifier: MIT */
/* Coefficient store: energy selection with Parseval error bounds, local level of
 * detail, and the sparse octree of kept coefficients with per-subtree bounds
 * (DESIGN.md sections 5 and 6; docs/store.md explains layout and bounds).
 *
 * Coordinates. Every position in this header is in VOXEL coordinates of the
 * original grid: x = i at sample i (world = origin + x * spacing). Gradients and
 * gradient bounds are derivatives with respect to voxel coordinates; divide
 * component a by spacing[a] for world units. A ray o + t d given in voxel
 * coordinates keeps the parameter t of the world ray whose origin and direction
 * were mapped the same way (wvol_store_world_to_voxel / _dir_to_voxel).
 *
 * Basis functions. Coefficient (level m = 1..M, band l = 0..7, p, q, r) stands
 * for w(x) = norm * B_x((x0 - lo0) / 2^m) * B_y((x1 - lo1) / 2^m) * B_z((x2 - lo2) / 2^m)
 * where B_a = psi if bit a of l is set, phi otherwise (both on [0, L-1]),
 * lo_a = 2^m p_a - s (s = filter->center), hi_a = lo_a + 2^m (L-1), and
 * norm = 2^{-m d / 2} with d the number of transformed axes. An axis of extent 1
 * is not transformed: its factor is the constant 1 (lo = -inf, hi = +inf).
 * The model is periodic with the padded size P_a per axis: a function whose box
 * passes P_a wraps around. Queries handle this exactly by returning one hit per
 * periodic image of a support box that meets the query (lo shifted by n P_a).
 *
 * Threading: a store is immutable after wvol_store_build; every function taking
 * a const wvol_store* may run concurrently (queries use caller-owned hit lists). */
#ifndef WVOL_STORE_H
#define WVOL_STORE_H

#include <stddef.h>
#include <stdint.h>
#include "wvol/status.h"
#include "wvol/volume.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

#ifdef __cplusplus
extern "C" {
#endif

#define WVOL_SELECT_MAX_LEVELS 32
#define WVOL_LOD_MAX_ELLIPSOIDS 16

/* ---- selection (DESIGN.md section 5) ------------------------------------- */

typedef enum wvol_select_mode {
    WVOL_SELECT_ALL = 0,       /* keep every coefficient (subject to drop_levels) */
    WVOL_SELECT_COUNT,         /* keep the `count` largest (count includes the low-pass cube) */
    WVOL_SELECT_FRACTION,      /* keep round(fraction * N) largest, N = all coefficients */
    WVOL_SELECT_ENERGY,        /* smallest set (by rank) whose kept energy >= energy * total energy */
    WVOL_SELECT_THRESHOLD,     /* keep rank key > threshold */
    WVOL_SELECT_PSNR           /* drop the most (by rank) whose dropped energy keeps PSNR >= psnr */
} wvol_select_mode;

/* A Gaussian ellipsoid of interest, in world units:
 * G(x) = exp(-1/2 d^(2 power)), d^2 = sum_a ((x_a - center_a) / radii_a)^2.
 * power 1 is the Gaussian (radii are the standard deviations); power > 1 gives
 * a flatter top (super-Gaussian), so the weight stays ~1 inside d < 1. */
typedef struct wvol_lod_ellipsoid {
    double center[3];
    double radii[3];   /* > 0 */
    double power;      /* >= 1; 0 is read as 1 */
} wvol_lod_ellipsoid;

/* Ranking key of a detail coefficient: |c| * w(centre of its support), in float,
 * so the ranking is by c^2 w^2; w(x) = floor + (1 - floor) max_e G_e(x) when
 * ellipsoids are given, else 1. Coefficients of levels 1..drop_levels are never
 * kept. The low-pass cube of the coarsest level is always kept and not ranked.
 * Ties at the cut are broken by position in the Mallat array (lower index first). */
typedef struct wvol_select_params {
    wvol_select_mode mode;
    size_t count;          /* COUNT: coefficients to keep, low-pass cube included */
    double fraction;       /* FRACTION: in [0, 1] */
    double energy;         /* ENERGY: share of the total energy in [0, 1] */
    double threshold;      /* THRESHOLD: >= 0, on the key |c| w */
    double psnr;           /* PSNR: target in dB (peak = data range, RMSE over nx ny nz voxels) */
    double peak;           /* data range for PSNR; <= 0: from the original volume when given,
                              else from a full reconstruction */
    int drop_levels;       /* global cut: 0..levels-1 finest levels dropped entirely */
    int n_ellipsoids;      /* 0..WVOL_LOD_MAX_ELLIPSOIDS */
    wvol_lod_ellipsoid ellipsoids[WVOL_LOD_MAX_ELLIPSOIDS];
    double lod_floor;      /* weight far from every ellipsoid, in [0, 1] */
    int measure;           /* 1: reconstruct and fill the measured_* fields of the report */
} wvol_select_params;

/* Everything zero except mode = WVOL_SELECT_ALL (and power 1 in each ellipsoid). NULL: does nothing. */
WVOL_API void wvol_select_params_default(wvol_select_params *p);

typedef struct wvol_select_report {
    size_t total;            /* N: all coefficients of the padded grid */
    size_t kept;             /* kept, low-pass cube included */
    size_t kept_lowpass;     /* size of the low-pass cube */
    size_t candidates;       /* ranked coefficients (detail bands not cut by drop_levels) */
    double key_cut;          /* smallest key kept among ranked ones (0 if none kept) */
    double energy_total;     /* sum c^2 over all coefficients */
    double energy_kept;
    double energy_dropped;   /* summed directly over the dropped coefficients */
    double predicted_l2;     /* sqrt(energy_dropped): ||f - f^||_2 over the padded grid (Parseval),
                                an upper bound over the original voxels, equal without padding */
    double predicted_rmse;   /* predicted_l2 / sqrt(nx ny nz) */
    double predicted_psnr;   /* 20 log10(peak / predicted_rmse); +inf when nothing is dropped,
                                0 when the peak is 0 (unknown or a constant volume) */
    double peak;             /* data range used (0 when not known and not needed) */
    int measured;            /* 1 when the measured_* fields are filled */
    double measured_l2;      /* over the original nx ny nz voxels, against the original volume
                                (or the full reconstruction when no volume was given) */
    double measured_rmse;
    double measured_psnr;
    double measured_max;     /* max |error| */
    int levels;
    size_t level_total[WVOL_SELECT_MAX_LEVELS + 1];   /* [m] for m = 1..levels; [0] unused */
    size_t level_kept[WVOL_SELECT_MAX_LEVELS + 1];    /* detail bands of level m; [0]: low-pass */
    double level_energy[WVOL_SELECT_MAX_LEVELS + 1];  /* energy of level m's detail; [0]: low-pass */
    double level_energy_kept[WVOL_SELECT_MAX_LEVELS + 1];
} wvol_select_report;

/* The kept set: one bit per coefficient of the Mallat array. */
typedef struct wvol_selection wvol_selection;

/* Ranks and selects in O(N) (two radix-histogram passes over the float bits of
 * the keys, no sort). `original` (may be NULL) is the volume the coefficients
 * came from: it gives the PSNR peak and the reference for measured errors.
 * rep (may be NULL) receives the report. Bad params (NaN, fraction/energy out
 * of [0,1], negative threshold, drop_levels >= levels, bad ellipsoid) are refused
 * with WVOL_ERR_ARG. A count larger than N keeps everything. */
WVOL_API wvol_status wvol_select(wvol_selection **out, const wvol_coeffs *c, const wvol_select_params *prm,
                                 const wvol_volume *original, wvol_select_report *rep, wvol_error *err);

/* Selection from an explicit kept bitmap (bit i of word i/64 = coefficient i),
 * e.g. after decoding a file. The low-pass cube is added. rep may be NULL. */
WVOL_API wvol_status wvol_selection_from_bitmap(wvol_selection **out, const wvol_coeffs *c, const uint64_t *bits,
                                                wvol_select_report *rep, wvol_error *err);

WVOL_API void wvol_selection_destroy(wvol_selection *s); /* NULL is fine */

WVOL_API size_t wvol_selection_total(const wvol_selection *s);  /* N */
WVOL_API size_t wvol_selection_kept(const wvol_selection *s);
WVOL_API int wvol_selection_is_kept(const wvol_selection *s, size_t index); /* index into c->data */
/* The bitmap, (N + 63) / 64 words; valid while s lives. */
WVOL_API const uint64_t *wvol_selection_bits(const wvol_selection *s);

/* Zeroes the dropped coefficients of c in place (c must have the selection's layout). */
WVOL_API wvol_status wvol_selection_apply(const wvol_selection *s, wvol_coeffs *c, wvol_error *err);

/* Reconstructs the kept part and fills the measured_* fields of rep (and peak
 * when rep->peak <= 0). original may be NULL (then the full reconstruction of c
 * is the reference). */
WVOL_API wvol_status wvol_selection_measure(const wvol_selection *s, const wvol_coeffs *c, const wvol_volume *original,
                                            wvol_select_report *rep, wvol_error *err);

/* The LOD weight w(x) of prm at a world position (1 without ellipsoids). */
WVOL_API double wvol_lod_weight(const wvol_select_params *prm, const double world[3]);

/* ---- the store (DESIGN.md section 6) --------------------------------------- */

typedef struct wvol_store wvol_store;

typedef struct wvol_store_params {
    int spline_J;          /* knots per unit 2^J of the basis splines; 0 = default (4: the
                              speed/accuracy trade-off of docs/basis.md; the CLI and Python
                              use it too) */
    int majorant;          /* 1: the basis tables are the majorants of |phi|, |psi|
                              (wvol_basis_create_majorant) and the coefficients are stored as
                              |c|: its X-ray bounds sum |c| int |B| on every ray (a residual
                              store for wvol_render_bound). Default 0 */
} wvol_store_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_store_params_default(wvol_store_params *p);

/* Builds the store of the coefficients of c kept by sel (NULL: every nonzero
 * coefficient, plus the whole low-pass cube). c is copied from; it need not
 * outlive the store. prm may be NULL (defaults). */
WVOL_API wvol_status wvol_store_build(wvol_store **out, const wvol_coeffs *c, const wvol_selection *sel,
                                      const wvol_store_params *prm, wvol_error *err);

WVOL_API void wvol_store_destroy(wvol_store *s); /* NULL is fine */

/* A store on a .wvc file (version 2, random access), holding the low-pass cube and the
 * chunk index; its detail coefficients are decoded on demand, chunk by chunk, into a
 * cache of at most `budget` bytes (0: WVOL_WVC_DEFAULT_BUDGET, 1 GiB; a budget below
 * one chain of chunks is refused). Brick reconstructions read it (the bricked renderer,
 * marching cubes brick by brick, wvol_store_densify); the octree queries (query_box,
 * query_ray, box_bounds) refuse it with WVOL_ERR_UNSUPPORTED, and lookup, eval, next
 * and node_get see only the low-pass cube. A version-1 file is decoded whole (refused
 * above the budget). Unlike a built store, its cache changes under const calls (it has
 * a lock: concurrent readers are still safe). */
WVOL_API wvol_status wvol_store_open(wvol_store **out, const char *path, size_t budget,
                                     const wvol_store_params *prm, wvol_error *err);
/* The file's header, band table and index summary (a store made by wvol_store_open;
 * NULL otherwise). */
WVOL_API const wvol_wvc_info *wvol_store_file_info(const wvol_store *s);
/* 1 for a store made by wvol_store_open. */
WVOL_API int wvol_store_is_file(const wvol_store *s);
/* The file's cache counters (a store made by wvol_store_open only), and the first
 * decoding error met since the last call (a damaged chunk, the budget exceeded): reads
 * that met it gave zeros, so check after every use. */
WVOL_API wvol_status wvol_store_file_stats(const wvol_store *s, wvol_wvc_cache_stats *st, wvol_error *err);

typedef struct wvol_store_info {
    const wvol_filter *filter;
    int levels;
    size_t nx, ny, nz;        /* original size */
    size_t px, py, pz;        /* padded size = period of the model per axis */
    double spacing[3], origin[3];
    int transformed[3];       /* 0 for an axis of extent 1 */
    size_t lowpass[3];        /* low-pass cube dims */
    size_t kept;              /* kept coefficients, low-pass cube included */
    size_t kept_lowpass;
    size_t nodes;             /* octree nodes (detail levels; connectors included) */
    size_t roots;             /* nodes of level M: indices 0 .. roots-1 */
    size_t hash_slots;
    size_t bytes;             /* memory held by the store (basis tables excluded) */
    double bytes_per_coeff;   /* bytes / kept */
    size_t basis_bytes;       /* the basis tables and their range tables */
} wvol_store_info;

WVOL_API void wvol_store_get_info(const wvol_store *s, wvol_store_info *info);

/* The basis tables the store evaluates with (owned by the store). */
WVOL_API const wvol_basis *wvol_store_basis(const wvol_store *s);

/* Coefficient value by index. Returns 1 and sets *value when kept, 0 otherwise
 * (also for out-of-range indices). band 0 only at level M. value may be NULL. */
WVOL_API int wvol_store_lookup(const wvol_store *s, int level, int band, size_t p, size_t q, size_t r, float *value);

typedef struct wvol_store_coeff {
    float value;
    uint8_t level;   /* 1..M */
    uint8_t band;    /* 0..7; 0 only at level M (the low-pass cube) */
    uint32_t p, q, r;
} wvol_store_coeff;

/* Iteration over every kept coefficient: the low-pass cube first (raster order),
 * then the nodes coarse to fine. Start with a zeroed cursor; each call returns 1
 * and fills *c, or 0 at the end. */
typedef struct wvol_store_iter {
    size_t node, k;
} wvol_store_iter;
WVOL_API int wvol_store_next(const wvol_store *s, wvol_store_iter *it, wvol_store_coeff *c);

/* One basis function (one periodic image of it) that a query touches. */
typedef struct wvol_store_hit {
    double lo[3], hi[3];  /* support box of this image (voxel coords); +-inf on an untransformed axis */
    double t0, t1;        /* ray queries: the part of [tmin, tmax] inside the box; box queries: 0, 0 */
    double norm;          /* 2^{-m d/2}: w(x) = norm * prod_a B_a((x_a - lo_a) / 2^m) */
    float value;          /* coefficient */
    uint8_t level, band;
    uint16_t reserved;
    uint32_t p, q, r;
} wvol_store_hit;

/* A caller-owned, reusable, growable list; start zeroed, free with
 * wvol_store_hits_free. Queries clear it and append. */
typedef struct wvol_store_hits {
    wvol_store_hit *hits;
    size_t count, capacity;
} wvol_store_hits;

WVOL_API void wvol_store_hits_free(wvol_store_hits *h);

/* Every kept basis function (with each periodic image) whose closed support box
 * meets the closed box [lo, hi] (voxel coords), found by descending the octree
 * and skipping subtrees whose support misses the box. */
WVOL_API wvol_status wvol_store_query_box(const wvol_store *s, const double lo[3], const double hi[3],
                                          wvol_store_hits *out, wvol_error *err);

/* Every kept basis function image whose support box the segment o + t d,
 * t in [tmin, tmax], crosses (voxel coords; d need not be unit length; a zero d
 * is a point). hit.t0 <= hit.t1 give the part of the segment inside the box. */
WVOL_API wvol_status wvol_store_query_ray(const wvol_store *s, const double o[3], const double d[3], double tmin,
                                          double tmax, wvol_store_hits *out, wvol_error *err);

/* Rigorous bounds of the spline model f^ and its gradient on a closed box
 * (voxel coords): for every x in the box, vmin <= f^(x) <= vmax, |f^(x)| <= vabs,
 * |df^/dx_a (x)| <= grad[a], |grad f^(x)| <= grad_norm (a.e.; f^ is Lipschitz with
 * these constants on the box). Never exceeded: ranges of the spline pieces are
 * computed exactly and padded for rounding (docs/store.md). For Haar f^ is
 * piecewise constant: its gradient is 0 almost everywhere (grad = 0) and it
 * jumps at voxel faces. */
typedef struct wvol_store_bounds {
    double vmin, vmax;
    double vabs;          /* sum over touching functions of |c| max|w| on the box */
    double grad[3];
    double grad_norm;
    size_t touching;      /* basis function images meeting the box */
} wvol_store_bounds;

WVOL_API wvol_status wvol_store_box_bounds(const wvol_store *s, const double lo[3], const double hi[3],
                                           wvol_store_bounds *out, wvol_error *err);

/* f^ at x (voxel coords) from the kept coefficients through the basis splines;
 * grad (may be NULL) receives the gradient in voxel units. Periodic. */
WVOL_API double wvol_store_eval(const wvol_store *s, const double x[3], double grad[3]);

/* Bounds of a single basis function of (level, band) over all space, periodic
 * copies included: |w| <= *vmax, |dw/dx_a| <= gmax[a], for the spline model and,
 * with the spline's measured error added, for the cascade's phi and psi too (the
 * node bounds are sums of these). Either output may be NULL. */
WVOL_API void wvol_store_function_bounds(const wvol_store *s, int level, int band, double *vmax, double gmax[3]);

/* Read-only view of the octree for custom traversals. Nodes 0..roots-1 are the
 * level-M nodes; the present children of a node are contiguous from child_first
 * in child-bit order (child bit i = 1*(x odd) + 2*(y odd) + 4*(z odd)). */
typedef struct wvol_store_node {
    int level;
    uint32_t p, q, r;
    unsigned band_mask;       /* bit l-1 set: band l (1..7) kept at this node */
    unsigned child_mask;      /* bit i set: child i present */
    const float *values;      /* popcount(band_mask) values, increasing band */
    size_t child_first;
    double lo[3], hi[3];      /* the node's support box (contains its subtree's), lo in [-s, P - s) */
    double vbound;            /* sum over the subtree of |c| max|w| */
    double gbound[3];         /* sum over the subtree of |c| max|dw/dx_a| */
} wvol_store_node;

WVOL_API size_t wvol_store_node_count(const wvol_store *s);
WVOL_API void wvol_store_node_get(const wvol_store *s, size_t i, wvol_store_node *out);

/* The dense low-pass cube (dims in info.lowpass, x fastest). */
WVOL_API const float *wvol_store_lowpass(const wvol_store *s);

/* Dense coefficients with zeros for what the store does not hold (for
 * wvol_idwt3 and friends). */
WVOL_API wvol_status wvol_store_densify(const wvol_store *s, wvol_coeffs **out, wvol_error *err);

/* The store's level-`level` low-pass volume: what wvol_idwt3_level(densify(s), level) gives
 * (ceil(n / 2^level) samples per transformed axis, spacing 2^level times, values scaled by
 * 2^{-level/2} per transformed axis, origin on the level's scaling-function centres), built
 * from the coefficients of the levels above `level` only. A file-backed store decodes only
 * those levels' chunks (wvol_wvc_read_region on the level's whole grid), within its budget.
 * level 0 is the full reconstruction; level outside 0..levels is refused (WVOL_ERR_ARG). */
WVOL_API wvol_status wvol_store_level_volume(wvol_volume **out, const wvol_store *s, int level, wvol_error *err);
/* Energy (sum c^2) of the store's detail coefficients of levels 1..level: by Parseval the
 * squared L2 distance between the full model and the level's (the drop_levels figure). A
 * file-backed store sums its band table's energies (the encoder's, before quantisation). */
WVOL_API wvol_status wvol_store_level_energy(const wvol_store *s, int level, double *energy, wvol_error *err);

/* World <-> voxel coordinates of the store's grid; a NULL store or input gives 0, a NULL
 * output does nothing (the same for dir_to_voxel). */
WVOL_API void wvol_store_world_to_voxel(const wvol_store *s, const double world[3], double voxel[3]);
WVOL_API void wvol_store_voxel_to_world(const wvol_store *s, const double voxel[3], double world[3]);
/* A direction: d_voxel[a] = d_world[a] / spacing[a] (keeps the ray parameter). */
WVOL_API void wvol_store_dir_to_voxel(const wvol_store *s, const double dworld[3], double dvoxel[3]);

#ifdef __cplusplus
}
#endif
#endif
