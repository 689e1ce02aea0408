/* SPDX-License-Identifier: MIT
 * Internal interface of the iso module: the flying-edges kernel on a region of a
 * dense array, shared by wvol_iso_extract (whole volume) and the brick path
 * (one reconstructed brick with a halo). Not installed. */
#ifndef WVOL_ISO_INTERNAL_H
#define WVOL_ISO_INTERNAL_H

#include <stdint.h>
#include "core/clones.h"
#include "core/status_internal.h"
#include "wvol/iso.h"


typedef struct wvol__mc_job {
    const float *data;        /* array, x fastest */
    size_t adims[3];          /* array dimensions */
    size_t lo[3], n[3];       /* meshed region: samples lo .. lo + n - 1 per axis */
    long long gofs[3];        /* global sample index of array element (0, 0, 0) */
    size_t gdims[3];          /* global grid dimensions (for edge keys) */
    double origin[3], spacing[3];
    double iso;
    int threads;              /* 1 = no OpenMP region */
    wvol_iso_normals normals;
    void (*gradient)(void *user, const double xyz[3], double grad[3]);
    void *gradient_user;
    uint64_t **keys;          /* optional: receives malloc'ed per-vertex edge keys */
    /* with keys: key_only[a] = 1 says that a vertex whose edge starts on the region's last
     * sample layer along a (local index n[a] - 1) is another mesh's (bricks: the next brick
     * owns it): only its key is written, its position and normal are left unset */
    int key_only[3];
    /* with keys, optional: receives malloc'ed per-vertex flags, WVOL__MC_KEY_ONLY for the
     * vertices above, WVOL__MC_FIRST for one whose edge starts on the region's first sample
     * layer along an axis a with first_shared[a] (bricks: the brick before may ask for it) */
    unsigned char **vflags;
    int first_shared[3];
} wvol__mc_job;
#define WVOL__MC_KEY_ONLY 1
#define WVOL__MC_FIRST 2

/* Edge key: ((gk * gny + gj) * 3 + axis) * gnx + gi for the edge from global
 * sample (gi, gj, gk) along axis. Keys increase in the kernel's vertex order. */
static inline uint64_t wvol__edge_key(const size_t gdims[3], uint64_t gi, uint64_t gj, uint64_t gk,
                                      int axis)
{
    return ((gk * gdims[1] + gj) * 3 + (uint64_t)axis) * gdims[0] + gi;
}

/* Refuses an unknown normals mode, analytic normals without a gradient, or a thread count
 * out of range: the checks of wvol_iso_params both extraction paths (dense, bricks) share. */
wvol_status wvol__iso_params_check(const wvol_iso_params *p, wvol_error *err);

/* Refuses a grid whose mesh the float32 vertices cannot hold: world coordinates beyond
 * FLT_MAX, or so large that float32 cannot resolve an eighth of the finest spacing there (an
 * origin of 1e7 with unit voxels snaps every vertex to whole voxels; 1e9 collapses the mesh).
 * Both extraction paths (dense, bricks) share it. */
wvol_status wvol__iso_vertex_range_check(const double origin[3], const double spacing[3], const size_t n[3],
                                         wvol_error *err);

/* Meshes the region; *out is a new mesh (possibly empty). stats may be NULL. */
wvol_status wvol__mc_run(wvol_mesh **out, const wvol__mc_job *job, wvol_iso_stats *stats,
                         wvol_error *err);

/* Bound [vmin, vmax] of the reconstructed samples of the box [s0, s1] (inclusive
 * voxel indices), computed from the coefficients alone (bricks.c; for tests). */
wvol_status wvol__iso_box_bound(const wvol_coeffs *c, const long s0[3], const long s1[3], double *vmin,
                                double *vmax, wvol_error *err);

/* ---- the implicit-surface ray tracer: the API (raytrace.c), one ray (trace_ray.c), the
 * bounds of boxes and the cell grid (trace_cells.c) ---- */

#include "store/store_ray.h"
#include "wvol/store.h"

/* Per-store constants of wvol__iso_box_range. */
typedef struct wvol__iso_boxk {
    int levels;
    double fb[WVOL_SELECT_MAX_LEVELS + 1][8]; /* max |w| of a function of (level, band) */
    double norm;                              /* the low-pass functions' 2^{-M d / 2} */
    double scale, shift;                      /* 2^M and the filter's centre s */
    int transformed[3];
    double s1[2];       /* range of s(y) = sum_p phi(y - p), the partition of unity */
    double m1[2];       /* range of m(y) = sum_p (y - p) phi(y - p), its first moment */
    /* ranges of runs of spline pieces of phi (0) and psi (1), a sparse table: entry
     * 4 (r pieces + i) + 2 which + {0, 1} is [min, max] over pieces i .. i + 2^r - 1 (each
     * piece's Bernstein hull, padded); NULL: every factor uses its global max (fb) */
    double *prange;
    int pieces, per_unit, runs;
    double inv_size[WVOL_SELECT_MAX_LEVELS + 1]; /* 2^-m: a level-m factor's variable per voxel */
    double support;
    const wvol_basis *basis; /* the store's tables (the tensor range's pieces) */
    double h;                /* their piece length, 2^-J units */
    double bmax3[8];         /* per band: prod_a max |Bernstein coefficient| of its factor's pieces */
    double lip3[8];          /* per band: sum_a dmax_a prod_{b != a} vmax_b (a factor's Lipschitz bound) */
} wvol__iso_boxk;

void wvol__iso_boxk_init(wvol__iso_boxk *k, const wvol_store *s);
void wvol__iso_boxk_free(wvol__iso_boxk *k);

/* Rigorous range [*vmin, *vmax] of f^ on the closed box [lo, hi] (voxel coords), from the
 * functions touching it (queried into hl). The low-pass coefficients are fitted by a plane,
 * c_p = a0 + g . (p - pbar) + r_p (least squares over the touching ones), and
 *   sum c w = a0 norm S(x) + sum_a g_a norm [(y_a - pbar_a) s(y_a) - m(y_a)] prod_{b != a} s(y_b)
 *             + sum r_p w_p,
 * y = (x + s) / 2^M, with the ranges of s and m from the spline's pieces and |sum r w| <=
 * sum |r| max|w|; details |sum c w| <= sum |c| max|w|. A constant or linear background (CT
 * air, the smooth flanks of a Gaussian) costs nothing, unlike |c| max|w| per function.
 * Each function's max|w| is in fact its range on the box: w is a product of three 1D spline
 * factors, each within the hull of the pieces its part of the box covers, so c w lies in
 * c norm [product of the three ranges] and the terms are summed as intervals (a function the
 * box sees only at its tail, or one nearly constant over the box, adds a narrow interval). */
wvol_status wvol__iso_box_range(const wvol__iso_boxk *k, const wvol_store *s, wvol_store_hits *hl, const double lo[3],
                                const double hi[3], double *vmin, double *vmax, wvol_error *err);
/* dst = the hits of src whose support box meets the closed box [lo, hi]: the test the store's
 * box query applies to every function image, so filtering a query over a box that holds
 * [lo, hi] gives the query of [lo, hi] itself, hit for hit and in the same order (0 when out of
 * memory; src and dst distinct). */
int wvol__iso_hits_in_box(const wvol_store_hits *src, const double lo[3], const double hi[3], wvol_store_hits *dst);
/* wvol__iso_box_range from the list of the functions touching the box (a box query's, in its
 * order; the result depends on the order only through rounding). fine (NULL or 2 doubles): the
 * part of the functions below the coarsest level, as the midpoint sum fine[0] and the padded
 * half-width fine[1] of their intervals (wvol__iso_box_class_tensor's finer levels). */
void wvol__iso_box_range_list(const wvol__iso_boxk *k, const wvol_store_hit *hits, size_t n, const double lo[3],
                              const double hi[3], double *vmin, double *vmax, double *fine);

/* Scratch of wvol__iso_box_class_tensor (one per thread; start zeroed, free its order). */
#define WVOL__TT_P 6      /* lattice patches per axis of a cell, at most */
#define WVOL__TT_SPAN 16  /* translates per axis of the coarsest level's functions touching a cell */
#define WVOL__TT_LEVELS 8
typedef struct wvol__tensor_ws {
    unsigned char have[3][2 * WVOL__TT_SPAN];
    double f[3][2 * WVOL__TT_SPAN][4 * WVOL__TT_P]; /* factors' Bernstein coefficients per sub-interval */
    double fc[3][2 * WVOL__TT_SPAN];                /* and their values at the cell's centre */
    size_t cnt[2 * WVOL__TT_SPAN][2 * WVOL__TT_SPAN];
    uint32_t *order;
    size_t cap;
    double w[2 * WVOL__TT_SPAN * 16 * WVOL__TT_P * WVOL__TT_P]; /* per x key: W[q b][r c] */
    double t[16 * WVOL__TT_P * WVOL__TT_P];                     /* one row T[p a][.] */
} wvol__tensor_ws;
/* The class of f^ on the closed box [lo, hi] (a small cell) where the interval range cannot
 * decide it because the coarsest level's functions cancel: 1 (f^ > iso on all of it), 0 (f^ <
 * iso) or -1 (undecided, or not tried: too many lattice patches or translates, an untransformed
 * axis, no piece tables, out of memory). The coarsest level's sum is taken as tensor-product
 * Bernstein forms on the box's patches of its lattice (their hull), the finer levels as the
 * intervals fine[] of wvol__iso_box_range_list; rigorous (rounding padded, trace_tensor.c). */
int wvol__iso_box_class_tensor(const wvol__iso_boxk *k, wvol__tensor_ws *w, const wvol_store_hit *hits, size_t n,
                               const double lo[3], const double hi[3], const double fine[2], double iso);

#define WVOL__CELL_LEVELS 4

/* What every ray of a trace shares (read only while rays are traced, but for the cell grid's
 * lazily filled classes). */
typedef struct wvol__tracer {
    wvol__spline_geom g;
    double iso, tol, chunk;
    wvol__iso_boxk k;   /* function bounds for the cells and the small functions' envelope */
    /* cell grid (images only): a hierarchy of cells, level 0 the coarsest (32 voxels), each
     * level halving the side down to `cell` (4 voxels); a cell's class is 1 (f^ >= iso on the
     * whole closed cell), 0 (f^ < iso), -1 (undecided: its children are looked at) or -2 (not
     * classified yet), computed from the store's rigorous box bounds the first time a ray
     * reaches it (a pure function of the box, so threads may race on it) */
    double cell;
    int tensor;         /* the finest cells undecided by the interval range try the tensor range */
    double refine_gain; /* an undecided cell is refined only where its children's bounds would
                           need to be at most this many times narrower to decide (trace_cells.c) */
    size_t nc[3];
    size_t ncl[WVOL__CELL_LEVELS][3];
    signed char *cls[WVOL__CELL_LEVELS];
    double lo[3], hi[3]; /* the traced extent per axis (voxels): wvol__iso_model_extent */
} wvol__tracer;

/* The part [lo_a, hi_a] of the sample extent [0, n_a - 1] where f^ does not reach across the
 * model's periodic wrap: there the finest-level functions phi(x - p + s) that are not
 * negligible (|phi| above 1e-3 of its maximum on (r0, r1) within the support) all sit on
 * samples 0 <= p <= P_a - 1 of the volume and its end padding, so lo_a = max(0, r1 - 1 - s)
 * and hi_a = min(n_a - 1, P_a + r0 - s). Outside it f^ mixes the far face into the near one
 * (a jump from soft tissue to air across the wrap makes db2's f^ overshoot by hundreds of HU
 * within a voxel of the face: a false surface). Untransformed axes keep [0, n_a - 1]. */
void wvol__iso_model_extent(const wvol_store *s, double lo[3], double hi[3]);

/* A thread's scratch for classifying cells: per level the last cell whose functions it queried
 * (or filtered from its parent's), so that the next cells below it filter that list instead of
 * querying the store again; start zeroed. */
typedef struct wvol__cell_ws {
    wvol_store_hits q[WVOL__CELL_LEVELS];
    double lo[WVOL__CELL_LEVELS][3], hi[WVOL__CELL_LEVELS][3];
    int have[WVOL__CELL_LEVELS];
    wvol__tensor_ws *tt; /* the finest cells' tensor ranges (allocated on first use) */
} wvol__cell_ws;
void wvol__cell_ws_free(wvol__cell_ws *w);

/* A thread's scratch, reused across rays; start zeroed. */
typedef struct wvol__trace_ws {
    wvol__spline_ws s;
    double *env;        /* per level-1 piece: sum of |c| max|w| of the small functions covering it */
    size_t capE;
    double *cut;        /* cell boundaries along the ray */
    size_t capC;
    wvol__cell_ws cellq; /* the cell grid's box queries */
    size_t cells;       /* cells this thread classified */
    double cell_seconds; /* and its time doing so */
    int has_hint;       /* hint holds the depth t of a neighbouring ray's hit (the image's
                           previous pixel in its row); 0 (as zeroed): none */
    double hint;
} wvol__trace_ws;

void wvol__trace_ws_free(wvol__trace_ws *w);

/* Allocates the cell grid of tr, every class unknown (free with wvol__trace_cells_free, also
 * on failure); spacing: the distance between neighbouring rays in the volume (voxels; 0 when
 * unknown), which sets how far undecided cells are refined (tr->refine_gain). */
wvol_status wvol__trace_cells(wvol__tracer *tr, double spacing, wvol_error *err);
void wvol__trace_cells_free(wvol__tracer *tr);
/* A test switch (0 by default): 1 turns the finest cells' tensor ranges off, so that tests can
 * compare the images with and without them. Set it only while no image is traced. */
extern int wvol__trace_tensor_off;
/* The class of f^ in the finest cell holding x (voxel coords): 1, 0 or -1 (undecided), going
 * down the hierarchy from the coarsest cell and classifying the cells met for the first time
 * (w: the caller's query scratch; *evaluated counts them and *seconds adds their time; both
 * may be NULL). */
int wvol__trace_cell_class(const wvol__tracer *tr, wvol__cell_ws *w, const double x[3], size_t *evaluated,
                           double *seconds);
/* Classifies every coarsest cell; cnt[0..2] count the undecided, below and above ones. */
void wvol__trace_cells_top(const wvol__tracer *tr, wvol_store_hits *hl, size_t cnt[3]);
/* Finest cells classified undecided so far. */
size_t wvol__trace_cells_undecided(const wvol__tracer *tr);

/* The first crossing of f^ = iso along o + t d, t >= tmin (world; d a unit direction) into
 * *h (zeroed first; h->t +inf on a miss). With tr->cls, cells whose bounds exclude iso are
 * stepped over. */
wvol_status wvol__trace(const wvol__tracer *tr, wvol__trace_ws *w, const double o[3], const double d[3], double tmin,
                        wvol_iso_hit *h, wvol_error *err);

/* ---- the bricked caster of the trilinear interpolant (cast.c, cast_cell.c) ---- */

#include "wavelet/wavelet_bricks.h"

/* The first crossing of the trilinear interpolant of one cell (corners c[i + 2j + 4k] at
 * (i, j, k)) along q0 + tau dq (cell-local coordinates), tau in [0, len]: the cubic
 * g(tau) = interp - iso is cut at the roots of g' into monotone parts; the first part whose
 * far end is not of class s0 (class: g >= 0) holds the first point where the class differs
 * from s0 = *cls (the class before the segment; < 0: that of g(0), stored back into *cls),
 * found by bisection to a bracket <= tol. Returns 1 with *tau (the bracket's far end,
 * the first point found of the other class; 0 when g(0) is already of the other class) or 0
 * when the class stays s0 on [0, len]. */
int wvol__cell_crossing(const double c[8], const double q0[3], const double dq[3], double len, double iso, int *cls,
                        double tol, double *tau);

/* Refuses a missing image or camera, a bad camera, or an image of another size (what: the
 * caller's name for messages). */
wvol_status wvol__iso_image_check(const wvol_image *img, const wvol_camera *cam, const char *what, wvol_error *err);

/* Refuses a non-finite light or colour, or an ambient outside [0, 1] (what: the caller's name
 * for messages): the shading parameters wvol__iso_shade takes. */
wvol_status wvol__iso_shading_check(const double light[3], const float color[3], float ambient, const char *what,
                                    wvol_error *err);

/* Shades a hit into rgba (Lambert, two-sided, albedo color, ambient; light all 0: a headlight
 * along -d); a miss is transparent black. */
void wvol__iso_shade(float rgba[4], const wvol_iso_hit *h, const double d[3], const double light[3],
                     const float color[3], float ambient);
/* interp at q (cell-local) and its gradient (per unit of q) */
double wvol__cell_eval(const double c[8], const double q[3], double grad[3]);

/* Constants of the bound of |f^ - interp| per group of a brick's cells (cast_bound.c says how). */
typedef struct wvol__fhat_link {
    int ok;             /* 0: no bound (an untransformed axis, no levels) */
    int M, L;           /* levels, filter taps */
    int below, above;   /* the window: samples c0 - below .. c1 + above reach the box [c0, c1] */
    double shift, scale, norm; /* s, 2^M, 2^{-3M/2} */
    /* g_s - interp (level 0): */
    double D, A, K;     /* 1D sums over p of |phi_s - hat| and |phi_s|; K = D (A^2 + A + 1) */
    double S[2];        /* range of S(x) = sum_p phi_s(x - p + s), the spline phi's partition of unity */
    double smax, pmax, p1; /* max |S^3 - 1|, max S^2, max |S^2 - 1| */
    double m1, m2, qmax;   /* max |M1|, max |M2|, max |M2 - tau| (cast_bound.c, sample_part) */
    /* f^ - g_s (the spline functions against their two-scale expansions): */
    double F[WVOL_SELECT_MAX_LEVELS + 1][8]; /* details: sup |prod A - prod B| per level and band */
    double c_u, c_m, c_res;                  /* the low-pass plane fit's constants (normalised) */
} wvol__fhat_link;
void wvol__fhat_link_init(wvol__fhat_link *k, const wvol_store *s);
/* The bound over each group of `group`^3 cells of a brick into out (groups x fastest), from its
 * stored samples s (box dimensions md, its first own sample at index core, its cells [c0, c0 +
 * cells] in voxel indices) and the kept functions touching it; returns the largest, +inf when no
 * bound applies (a face clipped the samples' window; out untouched) or memory runs out. */
double wvol__fhat_link_bound(const wvol__fhat_link *k, const float *s, const size_t md[3], const size_t core[3],
                             const size_t c0[3], const size_t cells[3], int group, const wvol_store_hit *hits,
                             size_t nh, double *out);

typedef struct wvol__caster wvol__caster;

/* A thread's scratch; start zeroed, free with wvol__cast_ws_free. */
typedef struct wvol__cast_ws {
    wvol__brick_scratch scr;
    size_t cells;
    double seconds_build;   /* this thread's wall time spent building bricks */
    wvol_store_hits hits;   /* the functions touching a brick (the model bound) */
} wvol__cast_ws;
void wvol__cast_ws_free(wvol__cast_ws *w);

/* Sets up the bricks of source (bounds and the block view for a store; nothing is built). */
wvol_status wvol__caster_create(wvol__caster **out, const wvol_render_source *src, double iso,
                                const wvol_iso_cast_params *p, wvol_error *err);
void wvol__caster_destroy(wvol__caster *c);
/* The first crossing along o + t d (world, d unit), t >= tmin; bricks built on demand
 * (safe from several threads). */
wvol_status wvol__cast(wvol__caster *c, wvol__cast_ws *w, const double o[3], const double d[3], double tmin,
                       wvol_iso_hit *h, wvol_error *err);
/* The model bound |f^ - interp| over the group of cells holding voxel position x (its brick
 * built if needed): +inf where the bound does not apply (a volume, a brick whose sample window a
 * face clips), NaN on an error (in err). */
double wvol__caster_fhat_bound(wvol__caster *c, wvol__cast_ws *w, const double x[3], wvol_error *err);
/* Counters: bricks total, skipped by bound (so far), built (so far); bytes held. */
void wvol__caster_counts(const wvol__caster *c, size_t *total, size_t *bound, size_t *built, size_t *bytes);

#endif
