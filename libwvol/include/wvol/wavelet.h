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

typedef enum wvol_family { WVOL_HAAR = 0, WVOL_DAUBECHIES, WVOL_COIFLET, WVOL_BATTLE_LEMARIE } wvol_family;

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
wvol_status wvol_filter_get(const wvol_filter **out, const char *name, wvol_error *err);
/* "haar", "daubechies", "coiflet", "battle-lemarie" ("?" for anything else). */
const char *wvol_family_name(wvol_family f);
/* All filters, for listing: index 0..count-1. */
int wvol_filter_count(void);
const wvol_filter *wvol_filter_at(int i);

/* Most levels M such that the padded size of each dimension (>= 2^M) still
 * leaves a low-pass cube of at least one sample; for a 1-voxel axis that axis is
 * not transformed (its extent stays 1). */
int wvol_dwt_max_levels(size_t nx, size_t ny, size_t nz);

/* Coefficients of a multi-level transform, Mallat layout on the padded grid
 * px x py x pz (each a multiple of 2^levels, or 1 for an untransformed axis).
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
wvol_status wvol_dwt3(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                      wvol_error *err);
wvol_status wvol_dwt3_pad(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                          wvol_pad_mode pad, wvol_error *err);
/* Same with the arithmetic in float64 (use_f64 = 1) before rounding the coefficients
 * to float32; wvol_dwt3 and wvol_dwt3_pad compute in float32. */
wvol_status wvol_dwt3_ex(wvol_coeffs **out, const wvol_volume *v, const wvol_filter *f, int levels,
                         wvol_pad_mode pad, int use_f64, wvol_error *err);

/* Zero coefficients for an nx x ny x nz volume (padded as wvol_dwt3 pads it): for
 * readers that fill c->data themselves (the CLI's raw coefficient files, the store). */
wvol_status wvol_coeffs_create(wvol_coeffs **out, const wvol_filter *f, int levels, size_t nx, size_t ny,
                               size_t nz, wvol_error *err);
/* Padded size of an axis of n samples for `levels` levels: 1 stays 1, else n rounded up
 * to a multiple of 2^levels. */
size_t wvol_dwt_padded_size(size_t n, int levels);

/* Full inverse, cropped back to nx x ny x nz. */
wvol_status wvol_idwt3(wvol_volume **out, const wvol_coeffs *c, wvol_error *err);
/* Same with float64 arithmetic (use_f64 = 1). */
wvol_status wvol_idwt3_ex(wvol_volume **out, const wvol_coeffs *c, int use_f64, wvol_error *err);

/* Coarser volume: undo levels..stop_level+1 only, giving the low-pass cube of
 * level stop_level s, cropped to the cells that touch the original grid: size
 * ceil(n/2^s) per transformed axis (1-voxel axes stay 1), spacing * 2^s, values scaled
 * by 2^{-s/2} per transformed axis (2^{-3s/2} for a full 3D volume) so they are
 * comparable with the samples, and origin moved to the scaling functions' centres:
 * origin + spacing * (2^s - 1) * filter->center. stop_level 0 = wvol_idwt3. */
wvol_status wvol_idwt3_level(wvol_volume **out, const wvol_coeffs *c, int stop_level, wvol_error *err);

/* Reconstruct only the finest-level samples in the box [lo, hi) (voxel indices of
 * the original grid) without reconstructing the rest. Result is (hi-lo) sized,
 * origin set to the box's world position. */
wvol_status wvol_idwt3_brick(wvol_volume **out, const wvol_coeffs *c, const size_t lo[3],
                             const size_t hi[3], wvol_error *err);

void wvol_coeffs_destroy(wvol_coeffs *c);
wvol_status wvol_coeffs_clone(wvol_coeffs **out, const wvol_coeffs *c, wvol_error *err);

/* Index into c->data of coefficient (level, band, p, q, r); positions are within
 * the band's extent (px >> level, ...; 1 along an untransformed axis). Returns
 * (size_t)-1 for an invalid request: level outside 1..levels, band 0 below the
 * coarsest level, a band that is high-pass along an untransformed (1-voxel) axis,
 * or a position outside the band. */
size_t wvol_coeffs_index(const wvol_coeffs *c, int level, int band, size_t p, size_t q, size_t r);
/* Inverse of wvol_coeffs_index (index < px*py*pz; otherwise level is set to 0). */
void wvol_coeffs_locate(const wvol_coeffs *c, size_t index, int *level, int *band, size_t *p,
                        size_t *q, size_t *r);

/* In-place transforms on raw arrays (the engine under wvol_dwt3; n? must be
 * multiples of 2^levels or 1). Float64 variants for accumulation-sensitive use. */
wvol_status wvol_dwt3_inplace_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                  int levels, wvol_error *err);
wvol_status wvol_idwt3_inplace_f32(float *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                   int levels, wvol_error *err);
wvol_status wvol_dwt3_inplace_f64(double *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                  int levels, wvol_error *err);
wvol_status wvol_idwt3_inplace_f64(double *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                   int levels, wvol_error *err);

/* 1D periodic single level (the plain reference form, double): n even; out has n
 * values: a[0..n/2) then d[0..n/2); out must not alias the input. Does nothing when
 * an argument is NULL or n is odd or < 2. */
void wvol_dwt1(double *out, const double *x, size_t n, const wvol_filter *f);
void wvol_idwt1(double *out, const double *ad, size_t n, const wvol_filter *f);

/* ---- basis functions as cubic splines (DESIGN.md section 7) ---------------- */

/* Tables for one family: phi and psi on [0, length-1] sampled by the cascade at
 * x = n / 2^J, then a cubic spline per interval of width 2^-J, stored in monomial
 * form in the local variable u = x - x0 in [0, 2^-J):
 *   value(x0 + u) = c[0] + c[1] u + c[2] u^2 + c[3] u^3
 * plus the primitive (integral from 0) and the derivative as their own pieces.
 * Haar is exact piecewise constant (c[1..3] = 0 and J = 0 for phi... see impl). */
typedef struct wvol_basis {
    const wvol_filter *filter;
    int J;                  /* knots per unit = 2^J */
    int pieces;             /* (length-1) * 2^J */
    double support;         /* length - 1 */
    double *phi;            /* pieces * 4 */
    double *psi;            /* pieces * 4 */
    double *phi_int;        /* primitive of phi, pieces * 4; phi_int at support = integral */
    double *psi_int;
    double *dphi;           /* derivative of the phi spline, pieces * 4 (quadratics) */
    double *dpsi;
    double phi_integral, psi_integral;   /* from the spline: ~1 and ~0 */
    double spline_error;    /* max |spline - cascade at J+2| over phi and psi */
    double ortho_error;     /* max_k |<phi(.-k), phi> - delta_k| from the spline */
} wvol_basis;

/* Builds the tables (J from 1 to 12). */
wvol_status wvol_basis_create(wvol_basis **out, const wvol_filter *f, int J, wvol_error *err);
void wvol_basis_destroy(wvol_basis *b);

/* Evaluate phi / psi and derivatives (0 outside the support). which: 0 = phi, 1 = psi. */
double wvol_basis_value(const wvol_basis *b, int which, double x);
double wvol_basis_deriv(const wvol_basis *b, int which, double x);
double wvol_basis_primitive(const wvol_basis *b, int which, double x);

/* Cascade algorithm: values of phi (which 0) or psi (which 1) at x = n/2^J,
 * n = 0 .. (length-1)*2^J, into out (caller provides that many + 1 values). */
wvol_status wvol_cascade(double *out, const wvol_filter *f, int which, int J, wvol_error *err);

/* f^ and its gradient at a point in voxel coordinates of the original grid
 * (x = i means sample i), from all coefficients of c: f^(x) = sum over the
 * pyramid's basis functions at y = x + center (DESIGN.md section 2), periodic
 * on the padded grid. Exact for the spline model. grad may be NULL. */
double wvol_fhat_eval(const wvol_coeffs *c, const wvol_basis *b, const double x[3], double grad[3]);

#ifdef __cplusplus
}
#endif
#endif
