/* SPDX-License-Identifier: MIT
 * The store's internal interface for f^ along one ray as exact piecewise polynomials, built
 * from its kept basis functions (ray_pieces.c). Used by the spline integrator
 * (render/spline.c) and the implicit-surface ray tracer (iso/). Not installed.
 *
 * Along x(t) = o + t d (voxel coordinates, t the world ray parameter) a level-m basis
 * function is a product of three cubic spline pieces in t between the knots of its level's
 * lattice x_a + s in 2^m h Z (h = basis->h). wvol__spline_ray asks the store for the
 * functions whose support meets [ta, tb], lays out each used level's lattice pieces and adds
 * every function's product of composed cubics to the pieces it covers; with `merge` it sums
 * all levels onto level 1's (the finest) lattice in ws->macc. Each piece's polynomial is in
 * its normalised variable u in [0, 1] (t = T[e] + u (T[e+1] - T[e])), degree <= 9.
 * The values are built factorised (functions sharing a translate and band on an axis share
 * that axis's composed cubic on a piece: sum_x X sum_y Y sum_z c Z, ray_pieces.c); the
 * gradient, and the values with ws->per_function set (the reference the tests compare with),
 * function by function. The two agree to rounding (tests/c/test_ray_factor.c). */
#ifndef WVOL_STORE_RAY_H
#define WVOL_STORE_RAY_H

#include <stdint.h>

#include "wvol/store.h"

#define WVOL__NC 10 /* coefficients of a degree-9 polynomial */

typedef struct wvol__level_ws {
    double *T;          /* breakpoints of this level's lattice */
    size_t capT, E;     /* E pieces */
    double *acc;        /* E * NC (value), then E * 3 * NC (gradient) when shading */
    size_t capA;
    int used;           /* a function of this level was added */
} wvol__level_ws;

/* Scratch of the factorised builder (ray_pieces.c): per function its weight, piece range and
 * per-axis factor keys; per axis the keys' piece ranges and composed cubics. */
typedef struct wvol__fact_hit {
    double w;
    uint32_t e0, e1, k[3];
} wvol__fact_hit;

typedef struct wvol__fact_key {
    double lo, hi;      /* the support's extent on this axis */
    uint32_t s0, s1;    /* pieces the ray may be inside it on (its slab) */
    uint32_t e0, e1;    /* pieces its functions are used on (the union of theirs) */
    size_t off;         /* offset of its cubics in cub (4 per piece from e0) */
    int seen;
} wvol__fact_key;

typedef struct wvol__fact_axis {
    wvol__fact_key *key;
    size_t capK;
    double *cub;
    size_t capC;
} wvol__fact_axis;

typedef struct wvol__fact_ws {
    wvol__fact_hit *h, *s;      /* the level's functions; the same sorted by (key x, key y) */
    size_t capH, capS;
    uint32_t *count;
    size_t capN;
    double *zs, *yz;            /* per piece: sum of c Z (cubic), sum of Y (c Z) (degree 6) */
    size_t capZ, capY;
    wvol__fact_axis ax[3];
} wvol__fact_ws;

/* Per-thread scratch, reused across rays; start zeroed, free with wvol__spline_ws_free.
 * per_function: build every piece by the per-function product instead of the factorised
 * sum (the reference the tests compare the factorised builder with; the gradient always
 * uses it). */
typedef struct wvol__spline_ws {
    int per_function;
    wvol__fact_ws f;
    wvol__level_ws lev[WVOL_SELECT_MAX_LEVELS + 1];
    double *ax[3];      /* per-axis crossings (scratch) */
    size_t capX[3];
    double *macc;       /* merged: every level on level 1's lattice (value, then gradient) */
    size_t capM;
    wvol_store_hits hits;
} wvol__spline_ws;

/* What a store contributes to every ray (read-only, shared by threads). */
typedef struct wvol__spline_geom {
    const wvol_store *s;
    const wvol_basis *b;
    wvol_store_info info;
    double shift;       /* s: knots at x + s in grid * Z */
    double grid;        /* 2h: level 1's lattice spacing */
    double norm[WVOL_SELECT_MAX_LEVELS + 1];  /* 2^{-m d / 2}, d = transformed axes */
    double bern[WVOL__NC][WVOL__NC];          /* monomial -> Bernstein on [0, 1] */
} wvol__spline_geom;

wvol_status wvol__spline_geom_init(wvol__spline_geom *g, const wvol_store *s, wvol_error *err);

/* Counters a ray adds to. */
typedef struct wvol__spline_count {
    size_t pieces, functions;
} wvol__spline_count;

/* Builds the piece polynomials of f^ (and of its voxel-space gradient when shading) on
 * [ta, tb] of the voxel-space ray o + t d. merge: sum the levels into ws->macc on
 * ws->lev[1]'s lattice (which then always exists). */
wvol_status wvol__spline_ray(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                             double ta, double tb, int shading, int merge, wvol__spline_count *cnt, wvol_error *err);

/* The same from an explicit list of hits (e.g. a subset of ws->hits; they must not alias
 * storage that the build reallocates: ws->hits is not touched). */
wvol_status wvol__spline_build(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                               double ta, double tb, const wvol_store_hit *hits, size_t n, int shading, int merge,
                               wvol__spline_count *cnt, wvol_error *err);

/* Adds more functions' values (any levels) to the merged polynomials ws->macc, on level 1's
 * pieces [elo, ehi) only (after a build with merge; no gradient), factorised like the build;
 * 0 when out of memory. */
int wvol__spline_add_finest_list(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                                 const wvol_store_hit *hits, size_t n, size_t elo, size_t ehi, wvol__spline_count *cnt);

void wvol__spline_ws_free(wvol__spline_ws *ws);

/* Horner evaluation of a degree-9 polynomial (WVOL__NC coefficients, increasing degree);
 * inline: the integrator and the tracer evaluate it in their inner loops. */
static inline double wvol__poly_eval(const double *a, double u)
{
    double r = a[WVOL__NC - 1];
    int k;
    for (k = WVOL__NC - 2; k >= 0; k--) r = r * u + a[k];
    return r;
}

/* Bernstein coefficients on [0, 1] of the monomial polynomial a; the end ones are the end
 * values and the polynomial lies in their convex hull. Returns max over j of the summed
 * magnitudes |bern[j][k] a[k]|, which bounds the rounding of every coefficient by
 * NC * DBL_EPSILON times it. */
double wvol__bernstein(const wvol__spline_geom *g, const double *a, double *bcoef);

#endif
