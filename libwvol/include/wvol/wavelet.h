/* SPDX-License-Identifier: MIT */
/* Wavelet engine: QMF filters of four families, the separable 3D periodic
 * transform in Mallat (pyramid) layout, partial reconstruction, and the
 * families' basis functions as cubic-spline tables (DESIGN.md sections 2-4, 7). */
#ifndef WVOL_WAVELET_H
#define WVOL_WAVELET_H

#include <stddef.h>
#include "wvol/volume.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum wvol_family {
    WVOL_FAMILY_HAAR = 0, WVOL_FAMILY_DAUBECHIES, WVOL_FAMILY_COIFLET, WVOL_FAMILY_BATTLE_LEMARIE
} wvol_family;
/* Deprecated names, removed after 0.1 (docs/conventions.md). */
#define WVOL_HAAR WVOL_FAMILY_HAAR
#define WVOL_DAUBECHIES WVOL_FAMILY_DAUBECHIES
#define WVOL_COIFLET WVOL_FAMILY_COIFLET
#define WVOL_BATTLE_LEMARIE WVOL_FAMILY_BATTLE_LEMARIE

/* An orthonormal QMF pair. h is the low-pass "reconstruction" filter of the
 * two-scale relation phi(t) = sqrt(2) sum_n h[n] phi(2t - n) (PyWavelets' rec_lo),
 * so that phi is supported on [0, length-1]; g[n] = (-1)^n h[length-1-n].
 * Analysis: a[k] = sum_n h[n] x[(2k+n) mod N], d[k] = sum_n g[n] x[(2k+n) mod N]. */
typedef struct wvol_filter {
    char name[16];          /* "haar", "db2", "coif1", "bl3" ... */
    wvol_family family;
    int order;              /* N of dbN / coifN, M of blM (spline order; bl3 = cubic) */
    int length;             /* taps, always even (bl3: 127 symmetric taps + one zero = 128) */
    const double *h;        /* low-pass, length taps */
    const double *g;        /* high-pass, length taps */
    int vanishing_moments;  /* of psi */
    double defect;          /* max_k |sum_n h[n] h[n+2k] - delta_k| */
    double center;          /* s = integral of x phi(x) dx: f^ is centred on samples */
} wvol_filter;

/* Looks a filter up by name ("haar", "db1".."db10", "coif1".."coif5", "bl3").
 * The returned filter is static and never freed; lookup is thread-safe (everything
 * derived is computed once, at first use). docs/wavelets.md has the conventions. */
WVOL_API wvol_status wvol_filter_get(const wvol_filter **out, const char *name, wvol_error *err);
/* "haar", "daubechies", "coiflet", "battle-lemarie" ("?" for anything else). */
WVOL_API const char *wvol_family_name(wvol_family f);
/* All filters, for listing: index 0..count-1. */
WVOL_API int wvol_filter_count(void);
WVOL_API const wvol_filter *wvol_filter_at(int i);

/* Most levels M such that the padded size of each dimension (>= 2^M) still
 * leaves a low-pass cube of at least one sample; for a 1-voxel axis that axis is
 * not transformed (its extent stays 1). */
WVOL_API int wvol_dwt_max_levels(size_t nx, size_t ny, size_t nz);

/* Coefficients of a multi-level transform, Mallat layout on the padded grid
 * px x py x pz (each a multiple of 2^levels, or 1 for an untransformed axis). Made by
 * wvol_coeffs_create or a transform: as for wvol_volume, the entry points trust the sizes to
 * describe the array.
 * Level m = 1..levels (1 finest), band l = 1..7: bit0 high-pass in x, bit1 in y,
 * bit2 in z; band 0 = the low-pass cube, only at level == levels. */
typedef struct wvol_coeffs {
    const wvol_filter *filter;
    int levels;
    size_t nx, ny, nz;      /* original (cropped) size */
    size_t px, py, pz;      /* padded size */
    double spacing[3], origin[3];
    float *data;            /* px*py*pz, x fastest */
} wvol_coeffs;

typedef enum wvol_pad_mode { WVOL_PAD_EDGE = 0, WVOL_PAD_ZERO, WVOL_PAD_PERIODIC } wvol_pad_mode;

/* Forward transform of a volume (padded as needed, edge-replicate by default).
 * Refuses NaN/Inf naming the first voxel, and inputs so large that a coefficient
 * overflows float32 (WVOL_ERR_NONFINITE). levels in 1..wvol_dwt_max_levels. */
WVOL_API wvol_status wvol_dwt3(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                               wvol_error *err);
WVOL_API wvol_status wvol_dwt3_pad(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                                   wvol_pad_mode pad, wvol_error *err);
/* Same with the arithmetic in float64 (use_f64 = 1) before rounding the coefficients
 * to float32; wvol_dwt3 and wvol_dwt3_pad compute in float32. */
WVOL_API wvol_status wvol_dwt3_ex(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                                  wvol_pad_mode pad, int use_f64, wvol_error *err);

/* Zero coefficients for an nx x ny x nz volume (padded as wvol_dwt3 pads it): for
 * readers that fill c->data themselves (the CLI's raw coefficient files, the store). */
WVOL_API wvol_status wvol_coeffs_create(wvol_coeffs **out, const wvol_filter *f, int levels, size_t nx, size_t ny,
                                        size_t nz, wvol_error *err);
/* Padded size of an axis of n samples for `levels` levels: 1 stays 1, else n rounded up
 * to a multiple of 2^levels. */
WVOL_API size_t wvol_dwt_padded_size(size_t n, int levels);

/* Full inverse, cropped back to nx x ny x nz. */
WVOL_API wvol_status wvol_idwt3(wvol_volume **out, const wvol_coeffs *c, wvol_error *err);
/* Same with float64 arithmetic (use_f64 = 1). */
WVOL_API wvol_status wvol_idwt3_ex(wvol_volume **out, const wvol_coeffs *c, int use_f64, wvol_error *err);
/* wvol_idwt3 in the coefficients' own buffer, which becomes the volume's: no second
 * buffer of the volume's size is allocated, filled or copied. *c is consumed whatever
 * the outcome (destroyed and set to NULL); the result equals wvol_idwt3's bit for bit. */
WVOL_API wvol_status wvol_idwt3_consume(wvol_volume **out, wvol_coeffs **c, wvol_error *err);

/* Where level s's grid lies (s >= 1, a transformed axis): a level-s scaling function p is
 * centred at 2^s p + (2^s - 1) * f->center voxels. The grid starts with the one centred in the
 * first cell, p = -shift (mod the level's period), shift = floor((2^s - 1) * center / 2^s), at
 * offset = (2^s - 1) * center - 2^s * shift voxels (in [0, 2^s)). Filters with centre <= 1
 * (Haar, db2, db3) have shift 0 at every level; the Coiflets and bl3 do not, and without the
 * shift their coarse grids started inside the volume and wrapped its end around. */
WVOL_API size_t wvol_level_shift(const wvol_filter *f, int level);
WVOL_API double wvol_level_offset(const wvol_filter *f, int level);

/* Coarser volume: undo levels..stop_level+1 only, giving the low-pass cube of
 * level stop_level s, cropped to the cells that touch the original grid: size
 * ceil(n/2^s) per transformed axis (1-voxel axes stay 1), spacing * 2^s, values scaled
 * by 2^{-s/2} per transformed axis (2^{-3s/2} for a full 3D volume) so they are
 * comparable with the samples, sample i the level's coefficient i - wvol_level_shift (mod
 * the level's period) and origin + spacing * wvol_level_offset: the scaling functions'
 * centres, the first in the first cell. stop_level 0 = wvol_idwt3. */
WVOL_API wvol_status wvol_idwt3_level(wvol_volume **out, const wvol_coeffs *c, int stop_level, wvol_error *err);

/* A dense volume's level-`level` low-pass volume through family f: wvol_idwt3_level of
 * wvol_dwt3(v, f, level) (the same grid, values, spacing and origin), and in *energy (may be
 * NULL) the sum c^2 of the detail coefficients dropped to reach it (levels 1..level: the
 * squared L2 distance of the padded volume to its level-`level` approximation). level 0 is a
 * copy (energy 0); level outside 0..wvol_dwt_max_levels is refused (WVOL_ERR_ARG). */
WVOL_API wvol_status wvol_volume_level(wvol_volume **out, const wvol_volume *v, const wvol_filter *f, int level,
                                       double *energy, wvol_error *err);

/* Reconstruct only the finest-level samples in the box [lo, hi) (voxel indices of
 * the original grid) without reconstructing the rest. Result is (hi-lo) sized,
 * origin set to the box's world position. */
WVOL_API wvol_status wvol_idwt3_brick(wvol_volume **out, const wvol_coeffs *c, const size_t lo[3],
                                      const size_t hi[3], wvol_error *err);

WVOL_API void wvol_coeffs_destroy(wvol_coeffs *c);
WVOL_API wvol_status wvol_coeffs_clone(wvol_coeffs **out, const wvol_coeffs *c, wvol_error *err);

/* Index into c->data of coefficient (level, band, p, q, r); positions are within
 * the band's extent (px >> level, ...; 1 along an untransformed axis). Returns
 * (size_t)-1 for an invalid request: level outside 1..levels, band 0 below the
 * coarsest level, a band that is high-pass along an untransformed (1-voxel) axis,
 * or a position outside the band. */
WVOL_API size_t wvol_coeffs_index(const wvol_coeffs *c, int level, int band, size_t p, size_t q, size_t r);
/* Inverse of wvol_coeffs_index (index < px*py*pz; otherwise level is set to 0). */
WVOL_API void wvol_coeffs_locate(const wvol_coeffs *c, size_t index, int *level, int *band, size_t *p,
                                 size_t *q, size_t *r);

/* In-place transforms on raw arrays (the engine under wvol_dwt3; n? must be
 * multiples of 2^levels or 1). Float64 variants for accumulation-sensitive use. */
WVOL_API wvol_status wvol_dwt3_inplace_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                           int levels, wvol_error *err);
WVOL_API wvol_status wvol_idwt3_inplace_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                            int levels, wvol_error *err);
WVOL_API wvol_status wvol_dwt3_inplace_f64(double *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                           int levels, wvol_error *err);
WVOL_API wvol_status wvol_idwt3_inplace_f64(double *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                            int levels, wvol_error *err);

/* ---- the forward transform streamed along z ---------------------------------
 * Slices go in in order (wvol_dwt3_stream_push, any number at a time), and each level's
 * coefficients come out row by row in increasing z through a callback, with memory for
 * a window of about 2 L + 8 slices per level (L taps; wvol_dwt3_stream_bytes), whatever
 * the depth. The coefficients are bit-identical to wvol_dwt3's (edge padding, float32
 * arithmetic, the same kernels in the same order). Callback rows: at level m, the cube
 * being transformed is cx x cy x cz = (px, py, pz) >> (m - 1) (an axis of extent 1
 * stays 1); row r (0 <= r < cz / 2, or r = 0 when cz == 1) gives two planes of cx x cy
 * (x fastest): `low` is what wvol_dwt3 holds at z = r of the pyramid (x < cx, y < cy),
 * `high` what it holds at z = cz / 2 + r (NULL when the z axis is not transformed).
 * Below the coarsest level the x < cx / 2, y < cy / 2 quadrant of `low` is the next
 * level's input, not a coefficient (wvol_coeffs_put_rows skips it). The planes are valid
 * during the call only; a non-OK return stops the transform with that status. Levels
 * are interleaved (level m + 1's row k follows level m's rows 2k + 1 .. ), each in
 * increasing r. Not thread-safe on one stream; the kernels use OpenMP threads. */
typedef struct wvol_source wvol_source;
typedef wvol_status (*wvol_dwt3_rows_fn)(void *user, int level, size_t r, const float *low, const float *high,
                                         wvol_error *err);
typedef struct wvol_dwt3_stream wvol_dwt3_stream;
/* nx x ny x nz original size (padded as wvol_dwt3 pads it); levels as wvol_dwt3. */
WVOL_API wvol_status wvol_dwt3_stream_create(wvol_dwt3_stream **out, const wvol_filter *f, int levels, size_t nx,
                                             size_t ny, size_t nz, wvol_dwt3_rows_fn fn, void *user,
                                             wvol_error *err);
/* count slices of nx * ny samples (finite: the caller checks, as wvol_source_read does). */
WVOL_API wvol_status wvol_dwt3_stream_push(wvol_dwt3_stream *s, const float *slices, size_t count,
                                           wvol_error *err);
/* After the last slice: pads along z and emits the last rows of every level. */
WVOL_API wvol_status wvol_dwt3_stream_finish(wvol_dwt3_stream *s, wvol_error *err);
WVOL_API size_t wvol_dwt3_stream_bytes(const wvol_dwt3_stream *s);
WVOL_API void wvol_dwt3_stream_destroy(wvol_dwt3_stream *s); /* NULL is fine */
/* Rows made in the caller's memory (optional; set before the first slice, NULL to undo):
 * place(user, level, r) returns room for 2 cx cy floats (cx cy when the z axis is not
 * transformed) where row r of level m is then computed, low plane first, high plane after
 * it; the callback's planes point into that room, and the room must stay as it is until
 * the push or finish call that made the row returns (the next level reads the low plane).
 * A kept pyramid laid out in rows is written in place this way, without a copy. A NULL
 * room stops the transform with an error. */
typedef float *(*wvol_dwt3_place_fn)(void *user, int level, size_t r);
WVOL_API wvol_status wvol_dwt3_stream_set_place(wvol_dwt3_stream *s, wvol_dwt3_place_fn place, wvol_error *err);
/* Rows seen piece by piece as they are made (optional; set before the first slice, NULL to
 * undo): piece(user, level, r, y0, y1, low, high) gets rows y0 .. y1 - 1 (of cy) of row r's
 * planes, low and high pointing at their row y0 (high NULL when the z axis is not
 * transformed), right after the thread that made them has checked them, on that thread:
 * pieces of one row arrive on several threads at once (the callee is thread-safe, and
 * may keep per-thread state by omp_get_thread_num(), below the threads OpenMP allows),
 * each plane row exactly once, all before the row's callback. For work that reads every
 * coefficient once (a histogram) while the rows are still in the thread's cache. */
typedef void (*wvol_dwt3_piece_fn)(void *user, int level, size_t r, size_t y0, size_t y1, const float *low,
                                   const float *high);
WVOL_API wvol_status wvol_dwt3_stream_set_pieces(wvol_dwt3_stream *s, wvol_dwt3_piece_fn piece, wvol_error *err);
/* The whole streamed transform of a source (wvol/source.h), read in slabs of about
 * 16 MiB; bytes (may be NULL): the memory it held (window and slab). */
WVOL_API wvol_status wvol_dwt3_source(wvol_source *src, const wvol_filter *f, int levels, wvol_dwt3_rows_fn fn,
                                      void *user, size_t *bytes, wvol_error *err);
/* The same with the rows made where place says (wvol_dwt3_stream_set_place; NULL: in the
 * stream's own buffers) and seen piece by piece (wvol_dwt3_stream_set_pieces; may
 * be NULL). */
WVOL_API wvol_status wvol_dwt3_source_hooked(wvol_source *src, const wvol_filter *f, int levels, wvol_dwt3_rows_fn fn,
                                             wvol_dwt3_place_fn place, wvol_dwt3_piece_fn piece, void *user,
                                             size_t *bytes, wvol_error *err);
/* Copies a callback's rows into their places in c (created for the same size, filter
 * and levels, e.g. by wvol_coeffs_create): after every row of every level, c holds what
 * wvol_dwt3 makes. A level or row c does not have is ignored. */
WVOL_API void wvol_coeffs_put_rows(wvol_coeffs *c, int level, size_t r, const float *low, const float *high);

/* 1D periodic single level (the plain reference form, double): n even; out has n
 * values: a[0..n/2) then d[0..n/2); out must not alias the input. Does nothing when
 * an argument is NULL or n is odd or < 2. */
WVOL_API void wvol_dwt1(double *out, const double *x, size_t n, const wvol_filter *f);
WVOL_API void wvol_idwt1(double *out, const double *ad, size_t n, const wvol_filter *f);

/* ---- basis functions as cubic splines (DESIGN.md section 7) ---------------- */

/* The continuous model of every family except Haar is a cubic spline through the
 * cascade values of phi (and psi) at the knots x = n / 2^J of [0, length-1], with
 * periodic end conditions on the support (S'(0) = S'(L-1), S''(0) = S''(L-1)):
 * the copies of S that end at an integer then cancel the jumps of those that
 * start there, so sum_p S(x - p) = 1 exactly (a constant volume gives a constant
 * f^, a constant transfer function integrates exactly) and int S = 1 exactly. The
 * zero extension is continuous everywhere and C^2 inside the support; at the
 * support ends the slope jumps by end_slope (per family in docs/basis.md and
 * `wvol basis --json`). Haar (and db1, the same filter) is exact: phi is the box [0,1), psi is +1 on [0,1/2) and -1 on
 * [1/2,1), stored as constant pieces with J = 1. docs/basis.md has the measured
 * errors per family and J. */

#define WVOL_BASIS_J_MIN 1
#define WVOL_BASIS_J_MAX 12
/* Longest filter the tables accept: evaluation keeps per-axis scratch of this
 * size on the stack (no allocation in eval paths). */
#define WVOL_BASIS_MAX_LENGTH 256

enum { WVOL_BASIS_PHI = 0, WVOL_BASIS_PSI = 1 };   /* `which` */
/* Deprecated names, removed after 0.1 (docs/conventions.md). */
#define WVOL_PHI WVOL_BASIS_PHI
#define WVOL_PSI WVOL_BASIS_PSI
/* `kind` of table: the spline, its derivative, its primitive (integral from 0) */
typedef enum wvol_basis_kind { WVOL_BASIS_VALUE = 0, WVOL_BASIS_DERIV = 1, WVOL_BASIS_PRIMITIVE = 2 } wvol_basis_kind;

/* Doubles per piece in each kind of table (the derivative is a quadratic whose
 * c[3] is 0; the primitive is a quartic). */
#define WVOL_BASIS_VALUE_STRIDE 4
#define WVOL_BASIS_DERIV_STRIDE 4
#define WVOL_BASIS_PRIMITIVE_STRIDE 5

/* Tables for one family. Piece i (0 <= i < pieces) covers [i h, (i+1) h) with
 * h = 2^-J; in the local variable u = x - i h (0 <= u < h, same units as x):
 *   value(i h + u)     = c[0] + c[1] u + c[2] u^2 + c[3] u^3          c = phi + 4 i
 *   deriv(i h + u)     = d[0] + d[1] u + d[2] u^2                      d = dphi + 4 i
 *   primitive(i h + u) = P[0] + P[1] u + ... + P[4] u^4               P = phi_int + 5 i
 * P[0] is the integral of the spline from 0 to i h (pieces summed exactly).
 * Breakpoints are i h, i = 0..pieces. Outside [0, support) value and deriv are 0
 * and the primitive is 0 left of the support and the full integral right of it.
 * The struct is read-only after creation: share one between threads freely. */
typedef struct wvol_basis {
    const wvol_filter *filter;
    int J;                  /* knots per unit = 2^J (Haar: 1, exact) */
    int exact;              /* 1 for Haar / db1: piecewise constant, no spline */
    int degree;             /* polynomial degree of the value pieces: 0 (Haar) or 3 */
    int length;             /* filter taps L; the support is [0, L-1] */
    int pieces;             /* (L-1) * 2^J */
    int per_unit;           /* 2^J: pieces per unit of x (per voxel at level 1) */
    double h, inv_h;        /* 2^-J, 2^J */
    double support;         /* L - 1 */
    double center;          /* s = sum_n n h[n] / sqrt(2) = integral of x phi, exact from the filter */
    double *phi, *psi;      /* pieces * 4 */
    double *dphi, *dpsi;    /* pieces * 4 */
    double *phi_int, *psi_int;  /* pieces * 5 */
    /* checks (DESIGN.md section 7), all from the spline form */
    double phi_integral, psi_integral;   /* ~1 and ~0 */
    double center_spline;   /* integral of x * spline(phi): ~center */
    double spline_error;    /* max of the two below */
    double spline_error_phi, spline_error_psi;  /* max |spline - cascade at J+2| */
    double ortho_error;     /* max_k |<phi(.-k), phi> - delta_k| */
    double ortho_error_psi; /* max_k of |<psi(.-k), psi> - delta_k| and |<phi(.-k), psi>| */
    /* bounds of the spline model (rigorous, for the store's and the iso tracer's
     * value and Lipschitz bounds): max |value| and max |derivative| over x */
    double vmax[2], dmax[2];    /* [WVOL_BASIS_PHI], [WVOL_BASIS_PSI] */
    double abs_integral[2];     /* integral of |spline|: bounds |integral over any interval| */
    double end_slope[2];        /* |S'(0)| = |S'(L-1)|: the slope jump at the support ends */
    int majorant;               /* 1: the tables are the majorants of |phi|, |psi|
                                   (wvol_basis_create_majorant); the checks above are then
                                   those of the plain splines, the bounds of the majorants */
} wvol_basis;

/* Builds the tables for filter f with 2^J knots per unit (J in 1..12; Haar and
 * db1 ignore J and are exact). Cost O(L^2 2^J). */
WVOL_API wvol_status wvol_basis_create(wvol_basis **out, const wvol_filter *f, int J, wvol_error *err);
WVOL_API void wvol_basis_destroy(wvol_basis *b);   /* NULL is fine */

/* The same tables with phi and psi replaced, piece by piece, by majorants of |phi| and |psi|:
 * the cubic whose Bernstein coefficients on the piece are the absolute values of the
 * spline's. Nonnegative, >= |spline| everywhere, equal to it on every piece where the spline
 * keeps one sign (Haar: exactly |phi|, |psi|), continuous; derivatives, primitives and bounds
 * follow. A store built on them with |c| (wvol_store_params.majorant) has an X-ray that bounds
 * sum |c| int |B| along every ray: the per-pixel error bound (wvol_render_bound). */
WVOL_API wvol_status wvol_basis_create_majorant(wvol_basis **out, const wvol_filter *f, int J, wvol_error *err);

/* An upper bound of sup_u sum_k |theta(u - k)| (theta = phi for which 0, psi for 1): for each
 * position within a unit interval, the pieces of every integer shift, each bounded by its
 * largest Bernstein coefficient. It bounds the sum of |B_j(x)| over one level and band of
 * basis functions (used by the per-pixel error bound's coefficient-error term). NaN for a
 * NULL b. */
WVOL_API double wvol_basis_periodised_sup(const wvol_basis *b, int which);

/* The range of value piece i (0 <= i < pieces) of phi (which 0) or psi (1): the hull
 * [*lo, *hi] of its Bernstein coefficients, which contains the piece's cubic on the piece,
 * padded by 1e-12 of their magnitudes for rounding (the iso tracer's box ranges). An i
 * outside [0, pieces) gives the empty range [+inf, -inf]. */
WVOL_API void wvol_basis_piece_range(const wvol_basis *b, int which, int i, double *lo, double *hi);

/* Evaluate the spline model: which is WVOL_BASIS_PHI or WVOL_BASIS_PSI. O(1), no allocation.
 * value/deriv are 0 outside [0, support); primitive is the integral from 0 to x. value is NaN
 * for a NULL b. */
WVOL_API double wvol_basis_value(const wvol_basis *b, int which, double x);
WVOL_API double wvol_basis_deriv(const wvol_basis *b, int which, double x);
WVOL_API double wvol_basis_primitive(const wvol_basis *b, int which, double x);

/* Per-piece access for analytic integration (a ray crosses the pieces of three
 * 1D factors). Index of the piece holding x: floor(x 2^J), or -1 when x is
 * outside [0, support). Start of piece i: i * b->h. */
static inline int wvol_basis_piece(const wvol_basis *b, double x)
{
    if (!(x >= 0.0) || x >= b->support) return -1;
    int i = (int)(x * b->inv_h);
    return i < b->pieces ? i : b->pieces - 1;
}
/* Coefficients of piece i of a table, local variable u = x - i h; stride per
 * kind as above. i must be in [0, pieces). */
static inline const double *wvol_basis_coeffs(const wvol_basis *b, int which, wvol_basis_kind kind, int i)
{
    switch (kind) {
    case WVOL_BASIS_DERIV: return (which ? b->dpsi : b->dphi) + (size_t)i * WVOL_BASIS_DERIV_STRIDE;
    case WVOL_BASIS_PRIMITIVE: return (which ? b->psi_int : b->phi_int) + (size_t)i * WVOL_BASIS_PRIMITIVE_STRIDE;
    default: return (which ? b->psi : b->phi) + (size_t)i * WVOL_BASIS_VALUE_STRIDE;
    }
}

/* A cubic c(u) = c0 + c1 u + c2 u^2 + c3 u^3 composed with u = a t + d, as a
 * cubic in t: out(t) = c(a t + d). (A ray x(t) = alpha t + beta puts the level-m
 * factor 2^{-m/2} phi(2^{-m} (x + s) - p) on piece i with a = 2^{-m} alpha and
 * d = 2^{-m} (beta + s) - p - i h.) out may alias c. NULL out: does nothing; NULL c: out = 0. */
WVOL_API void wvol_poly3_affine(double out[4], const double c[4], double a, double d);

/* Bernstein coefficients on [0, 1] of the cubic a[0] + a[1] t + a[2] t^2 + a[3] t^3: the cubic
 * lies within their hull on [0, 1], and the end ones are its end values. bz may alias a.
 * NULL bz: does nothing; NULL a: bz = 0. */
WVOL_API void wvol_poly3_bernstein(double bz[4], const double a[4]);

/* Cascade algorithm: values of phi (which 0) or psi (which 1) at x = n/2^J,
 * n = 0 .. (length-1)*2^J, into out (caller provides (length-1)*2^J + 1 values).
 * Method: the integer values phi(1..L-2) are the eigenvector of eigenvalue 1 of
 * the matrix sqrt(2) h[2k-j] (normalised so they sum to 1, which is the partition
 * of unity), then the two-scale relation phi(x) = sqrt(2) sum_n h[n] phi(2x-n)
 * fills in level after level; psi(x) = sqrt(2) sum_n g[n] phi(2x-n). The values
 * are exact up to rounding at every dyadic point (no iteration to converge).
 * Haar/db1: the box and the Haar wavelet (right-continuous). J in 0..20. */
WVOL_API wvol_status wvol_cascade(double *out, const wvol_filter *f, int which, int J, wvol_error *err);

/* f^ and its gradient at a point in voxel coordinates of the original grid
 * (x = i means sample i): f^(x) = sum over the pyramid of c * prod_axes
 * 2^{-m/2} theta(2^{-m} (x + s) - p), theta = psi on an axis whose bit is set in
 * the band and phi otherwise, s = b->center, periodic on the padded grid
 * (DESIGN.md section 2). An axis of extent 1 is not transformed: f^ is constant
 * along it. Exact for the spline model: per level and band only the (L-1)^3
 * positions whose support holds the point are visited. grad (may be NULL) gets
 * d f^/dx in voxel units (divide by the spacing for world units). b must have
 * been built for c's filter (same taps); otherwise NaN is returned. Thread-safe,
 * no allocation. */
WVOL_API double wvol_fhat_eval(const wvol_coeffs *c, const wvol_basis *b, const double x[3], double grad[3]);

#ifdef __cplusplus
}
#endif
#endif
