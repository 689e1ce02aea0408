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
} wvol__mc_job;

/* Edge key: ((gk * gny + gj) * 3 + axis) * gnx + gi for the edge from global
 * sample (gi, gj, gk) along axis. Keys increase in the kernel's vertex order. */
static inline uint64_t wvol__edge_key(const size_t gdims[3], uint64_t gi, uint64_t gj, uint64_t gk,
                                      int axis)
{
    return ((gk * gdims[1] + gj) * 3 + (uint64_t)axis) * gdims[0] + gi;
}

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
} wvol__iso_boxk;

void wvol__iso_boxk_init(wvol__iso_boxk *k, const wvol_store *s);

/* Rigorous range [*vmin, *vmax] of f^ on the closed box [lo, hi] (voxel coords), from the
 * functions touching it (queried into hl). The low-pass coefficients are fitted by a plane,
 * c_p = a0 + g . (p - pbar) + r_p (least squares over the touching ones), and
 *   sum c w = a0 norm S(x) + sum_a g_a norm [(y_a - pbar_a) s(y_a) - m(y_a)] prod_{b != a} s(y_b)
 *             + sum r_p w_p,
 * y = (x + s) / 2^M, with the ranges of s and m from the spline's pieces and |sum r w| <=
 * sum |r| max|w|; details |sum c w| <= sum |c| max|w|. A constant or linear background (CT
 * air, the smooth flanks of a Gaussian) costs nothing, unlike |c| max|w| per function. */
wvol_status wvol__iso_box_range(const wvol__iso_boxk *k, const wvol_store *s, wvol_store_hits *hl, const double lo[3],
                                const double hi[3], double *vmin, double *vmax, wvol_error *err);

/* What every ray of a trace shares (read only while rays are traced). */
typedef struct wvol__tracer {
    wvol__spline_geom g;
    double iso, tol, chunk;
    wvol__iso_boxk k;   /* function bounds for the cells and the small functions' envelope */
    /* cell grid (images only): cells of `cell` voxels, class 1 (f^ >= iso on the whole closed
     * cell), 0 (f^ < iso) or -1 (undecided), from the store's rigorous box bounds */
    double cell;
    size_t nc[3];
    signed char *cls;
} wvol__tracer;

/* A thread's scratch, reused across rays; start zeroed. */
typedef struct wvol__trace_ws {
    wvol__spline_ws s;
    double *env;        /* per level-1 piece: sum of |c| max|w| of the small functions covering it */
    size_t capE;
    double *cut;        /* cell boundaries along the ray */
    size_t capC;
} wvol__trace_ws;

void wvol__trace_ws_free(wvol__trace_ws *w);

/* Classifies the cell grid of tr (tr->cls, malloc'ed: the caller frees it, also on failure)
 * by wvol__iso_box_range, with nth threads. */
wvol_status wvol__trace_cells(wvol__tracer *tr, int nth, wvol_error *err);

/* The first crossing of f^ = iso along o + t d, t >= tmin (world; d a unit direction) into
 * *h (zeroed first; h->t +inf on a miss). With tr->cls, cells whose bounds exclude iso are
 * stepped over. */
wvol_status wvol__trace(const wvol__tracer *tr, wvol__trace_ws *w, const double o[3], const double d[3], double tmin,
                        wvol_iso_hit *h, wvol_error *err);

#endif
