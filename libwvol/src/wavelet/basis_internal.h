/* SPDX-License-Identifier: MIT */
/* Shared internals of the basis-function tables (cascade.c, spline.c, basis.c,
 * fhat.c). Not installed. */
#ifndef WVOL_BASIS_INTERNAL_H
#define WVOL_BASIS_INTERNAL_H

#include <stddef.h>

#include "wvol/wavelet.h"
#include "core/status_internal.h"

#ifndef M_SQRT1_2
#define M_SQRT1_2 0.70710678118654752440
#endif
#ifndef M_SQRT2
#define M_SQRT2 1.41421356237309504880
#endif

/* Haar and db1 (two taps): exact box, never splines. */
int wvol__filter_is_haar(const wvol_filter *f);

/* phi at x = n/2^J, n = 0..(L-1)2^J (out holds that many + 1). */
wvol_status wvol__cascade_phi(double *out, const wvol_filter *f, int J, wvol_error *err);
/* psi at the same points from phi at the same level J. */
void wvol__cascade_psi_from_phi(double *psi, const double *phi, const wvol_filter *f, int J);

/* Periodic cubic spline through y[0..n] (y[0] == y[n]) at spacing h: n pieces of
 * 4 monomial coefficients in the local variable. n >= 3. */
wvol_status wvol__spline_periodic(double *c, const double *y, size_t n, double h, wvol_error *err);
void wvol__spline_deriv(double *d, const double *c, size_t n);
double wvol__spline_primitive(double *P, const double *c, size_t n, double h);
double wvol__cubic_absmax(const double *c, double h);
double wvol__cubic_absint(const double *c, double h);

#endif
