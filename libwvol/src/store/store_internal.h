/* SPDX-License-Identifier: MIT */
/* Internals shared by the store sources (selection, LOD weights, basis ranges,
 * octree). Not installed. */
#ifndef WVOL_STORE_INTERNAL_H
#define WVOL_STORE_INTERNAL_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>

#include "wvol/store.h"
#include "core/status_internal.h"

/* ---- Mallat layout of a coefficient pyramid -------------------------------- */

typedef struct wvol__layout {
    int levels;
    int L;          /* filter taps */
    double s;       /* filter centre */
    size_t P[3];    /* padded size (period) per axis */
    int tr[3];      /* axis transformed (P > 1) */
    size_t N;       /* P0 P1 P2 */
} wvol__layout;

wvol_status wvol__layout_init(wvol__layout *ly, const wvol_coeffs *c, wvol_error *err);
/* The same from the sizes alone (a file-backed store has no dense pyramid). */
wvol_status wvol__layout_init_dims(wvol__layout *ly, const wvol_filter *filter, int levels, size_t px, size_t py,
                                   size_t pz, wvol_error *err);

/* Extent of a band of level m along axis a (1 on an untransformed axis). */
static inline size_t wvol__ext(const wvol__layout *ly, int a, int m)
{
    return ly->tr[a] ? ly->P[a] >> m : 1;
}

/* Band l exists (no high-pass along an untransformed axis). */
static inline int wvol__band_ok(const wvol__layout *ly, int band)
{
    for (int a = 0; a < 3; a++)
        if (((band >> a) & 1) && !ly->tr[a]) return 0;
    return 1;
}

static inline size_t wvol__index(const wvol__layout *ly, int m, int band, size_t p, size_t q, size_t r)
{
    size_t o0 = (band & 1) ? wvol__ext(ly, 0, m) : 0;
    size_t o1 = (band & 2) ? wvol__ext(ly, 1, m) : 0;
    size_t o2 = (band & 4) ? wvol__ext(ly, 2, m) : 0;
    return (o0 + p) + ly->P[0] * ((o1 + q) + ly->P[1] * (o2 + r));
}

/* Number of transformed axes. */
static inline int wvol__dims(const wvol__layout *ly) { return ly->tr[0] + ly->tr[1] + ly->tr[2]; }

/* Row segments of the Mallat array in index order: within one row (j, k) the
 * x range [x0, x1) belongs to one (level, band); level 0 stands for the
 * low-pass cube (level M, band 0). */
typedef struct wvol__seg {
    size_t x0, x1;
    int level, band;   /* level 0: low-pass */
    size_t p0, q, r;   /* position of x0 within the band */
} wvol__seg;

/* Per-axis "h-level": for index i along axis a, the level m whose high half
 * holds i, or levels + 1 for the low-pass part. Tables of P[a] bytes each. */
typedef struct wvol__segplan {
    wvol__layout ly;
    uint8_t *h[3];
    int nxseg;                 /* x segments per row */
    size_t xs[WVOL_SELECT_MAX_LEVELS + 2];  /* x segment bounds */
    int xh[WVOL_SELECT_MAX_LEVELS + 1];     /* h-level of each x segment */
} wvol__segplan;

wvol_status wvol__segplan_init(wvol__segplan *sp, const wvol__layout *ly, wvol_error *err);
void wvol__segplan_free(wvol__segplan *sp);
/* The segments of row (j, k): fills segs (capacity nxseg), returns the count. */
int wvol__segplan_row(const wvol__segplan *sp, size_t j, size_t k, wvol__seg *segs);

/* ---- selection -------------------------------------------------------------- */

struct wvol_selection {
    wvol__layout ly;
    size_t kept;
    uint64_t *bits;   /* (N + 63) / 64 words */
};

/* Kept set of every nonzero coefficient plus the low-pass cube. */
wvol_status wvol__selection_nonzero(wvol_selection **out, const wvol_coeffs *c, wvol_error *err);

/* Per-level LOD weights at the support centres: w[m][p + e0 (q + e1 r)] for
 * m = 1..levels; NULL arrays when prm has no ellipsoids. */
typedef struct wvol__lodw {
    float *w[WVOL_SELECT_MAX_LEVELS + 1];
} wvol__lodw;

wvol_status wvol__lod_validate(const wvol_select_params *prm, wvol_error *err);
wvol_status wvol__lod_weights(wvol__lodw *out, const wvol_coeffs *c, const wvol__layout *ly,
                              const wvol_select_params *prm, wvol_error *err);
void wvol__lod_free(wvol__lodw *lw);
/* Centre of the support of position p at level m along axis a (voxel coords). */
static inline double wvol__support_centre(const wvol__layout *ly, int a, int m, size_t p)
{
    if (!ly->tr[a]) return 0.0;
    return ldexp((double)p + 0.5 * (ly->L - 1), m) - ly->s;
}

/* ---- rigorous ranges of the basis splines ------------------------------------ */

enum { WVOL__PHI = 0, WVOL__PSI = 1, WVOL__DPHI = 2, WVOL__DPSI = 3, WVOL__KINDS = 4 };

typedef struct wvol__ranges {
    int pieces;
    int J;
    double per_unit, h;    /* 2^J, 2^-J */
    double support;        /* L - 1 */
    int n;                 /* segment tree leaves (power of 2 >= pieces) */
    double *mn[WVOL__KINDS], *mx[WVOL__KINDS];   /* 2n nodes each */
    double absmax[WVOL__KINDS];                  /* max |.| over the support (spline model) */
    double spline_error;                         /* the basis' measured spline error */
} wvol__ranges;

wvol_status wvol__ranges_build(wvol__ranges *rg, const wvol_basis *b, wvol_error *err);
void wvol__ranges_free(wvol__ranges *rg);
/* Range of kind k over local u in [u0, u1] (clipped to the support), widened by
 * one piece each side; empty (u1 < 0 or u0 > support) gives [0, 0]. */
void wvol__ranges_query(const wvol__ranges *rg, int kind, double u0, double u1, double *lo, double *hi);
/* max over u of sum_n |B(u + n T)| for a period of T = period_pieces pieces (0:
 * no copies), plus the spline error per copy for phi and psi: a bound for the
 * periodized spline and the periodized cascade function alike. */
double wvol__ranges_periodic_max(const wvol__ranges *rg, int kind, size_t period_pieces);

static inline double wvol__horner3(const double *c, double u) { return c[0] + u * (c[1] + u * (c[2] + u * c[3])); }

static inline double wvol__min(double a, double b) { return a < b ? a : b; }
static inline double wvol__max(double a, double b) { return a > b ? a : b; }

/* ---- the octree ----------------------------------------------------------------- */

typedef struct wvol__node {
    uint64_t key;          /* level << 57 | p << 38 | q << 19 | r */
    uint32_t coef_first;
    uint32_t child_first;
    uint8_t band_mask, child_mask;
    uint16_t pad;
} wvol__node;                /* 24 bytes; subtree bounds are computed on request (store.c) */

#define WVOL__POS_BITS 19
#define WVOL__POS_MAX ((size_t)1 << WVOL__POS_BITS)

static inline uint64_t wvol__key(int m, size_t p, size_t q, size_t r)
{
    return ((uint64_t)m << 57) | ((uint64_t)p << 38) | ((uint64_t)q << 19) | (uint64_t)r;
}

static inline int wvol__key_level(uint64_t k) { return (int)(k >> 57); }
static inline void wvol__key_pos(uint64_t k, size_t pos[3])
{
    pos[0] = (size_t)(k >> 38) & (WVOL__POS_MAX - 1);
    pos[1] = (size_t)(k >> 19) & (WVOL__POS_MAX - 1);
    pos[2] = (size_t)k & (WVOL__POS_MAX - 1);
}

struct wvol_store {
    wvol__layout ly;
    struct wvol_wvc_file *file; /* a store opened on a .wvc file (store_file.c): no nodes; its
                                   detail coefficients are read through the file's chunk cache
                                   by the block view (blocks.c); NULL for a built store */
    const wvol_filter *filter;
    size_t nx, ny, nz;
    double spacing[3], origin[3];
    wvol_basis *basis;
    wvol__ranges rg;
    size_t E[3];              /* low-pass / root extents */
    float *lowpass;           /* E0 E1 E2 */
    int32_t *root_of;         /* E0 E1 E2: node index of the root at that position, or -1 */
    wvol__node *nodes;
    size_t nnodes, nroots;
    float *values;
    size_t nvalues;
    uint32_t *hash;           /* node index + 1, 0 = empty */
    size_t hash_mask;
    /* per (level, band): max|w| and max|dw/dx_a| over all space, periodic copies included */
    double fvmax[WVOL_SELECT_MAX_LEVELS + 1][8];
    double fgmax[WVOL_SELECT_MAX_LEVELS + 1][8][3];
    double norm[WVOL_SELECT_MAX_LEVELS + 1];  /* 2^{-m d / 2} */
    double pow2[WVOL_SELECT_MAX_LEVELS + 1], ipow2[WVOL_SELECT_MAX_LEVELS + 1];  /* 2^m, 2^-m */
    /* A built store's block-sparse view and its brick bounds (blocks.c), made on first use
     * under view_lock and kept until the store is destroyed: every brick reader (renderer
     * frames, marching cubes at several iso-values, the caster) shares them. */
    pthread_mutex_t view_lock;
    int view_lock_ok;
    struct wvol__store_blocks *view;
    struct wvol__brick_bounds *view_bounds; /* NULL where the bound does not apply */
};

/* Frees the cached view and bounds (blocks.c). */
void wvol__store_view_free(wvol_store *s);

/* A file-backed store's first decoding error since the last call (gathers cannot
 * return one): WVOL_OK for a built store. */
wvol_status wvol__store_file_error(const wvol_store *s, wvol_error *err);

/* What wvol_store_build and wvol_store_open share: layout, grid, basis tables and their
 * ranges, per-(level, band) function bounds, and the low-pass cube and root table
 * allocated (E0 E1 E2 each, not filled). majorant: the basis tables are the majorants of |phi|,
 * |psi| (wvol_store_params.majorant). s is zeroed; on failure the caller destroys it. */
wvol_status wvol__store_shell(wvol_store *s, const wvol__layout *ly, const wvol_filter *filter, const size_t n[3],
                              const double spacing[3], const double origin[3], int J, int majorant,
                              wvol_error *err);

#endif
