/* SPDX-License-Identifier: MIT
 * Quadrature rules shared by the modules (declared internal interface; not installed). */
#ifndef WVOL_CORE_QUADRATURE_H
#define WVOL_CORE_QUADRATURE_H

/* n-point Gauss-Legendre nodes x[0..n-1] and weights w[0..n-1] on [0, 1] (weights sum to 1),
 * nodes in increasing order; exact for polynomials of degree <= 2n - 1. n >= 1. */
void wvol__gauss_legendre(int n, double *x, double *w);

#endif
