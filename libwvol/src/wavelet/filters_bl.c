/* SPDX-License-Identifier: MIT */
/* Battle-Lemarie (orthonormalised B-spline) filters from their Fourier form.
 * Based on: Battle 1987, Lemarie 1988; Daubechies, "Ten Lectures" section 5.4;
 * the cubic case as in DESIGN.md section 3 (seed paper eqs 27-30). */
#include <math.h>
#include <stdlib.h>

#include "wavelet/wavelet_internal.h"

/* P(w) = 105 sin^8(w/2) Sigma8(w) = N1 + N2: the 2pi-periodic numerator of
 * Sigma8(w) = sum_k |B^(w + 2 pi k)|^2 for the cubic B-spline (DESIGN.md section 3). */
static double bl3_p(double w)
{
    double s = sin(0.5 * w), c = cos(0.5 * w);
    double s2 = s * s, c2 = c * c;
    double n1 = 5.0 + 30.0 * c2 + 30.0 * s2 * c2;
    double n2 = 2.0 * s2 * s2 * c2 + 70.0 * c2 * c2 + (2.0 / 3.0) * s2 * s2 * s2;
    return n1 + n2;
}

/* H(w) = sqrt(2) phi^(2w) / phi^(w) with phi^(w) = 1 / (w^4 sqrt(Sigma8(w))).
 * Written without the removable singularities: sin^4(w)/sin^4(w/2) = 16 cos^4(w/2), so
 * H(w) = sqrt(2) cos^4(w/2) sqrt(P(w) / P(2w)). Real and even: the filter is symmetric. */
static double bl3_H(double w)
{
    double c = cos(0.5 * w), c4 = c * c * c * c;
    return sqrt(2.0) * c4 * sqrt(bl3_p(w) / bl3_p(2.0 * w));
}

int wvol__bl_compute(int order, double tol, double *h, int cap, int *len)
{
    /* Dense sampling of H on [0, 2pi) and an inverse DFT. H is analytic and periodic,
     * so the coefficients alias only with h[n +- NS], which decay like exp(-0.6 |n|):
     * NS = 4096 makes aliasing far below double rounding. H is real and even, so the
     * inverse DFT reduces to a cosine sum, done directly (the tap count is small). */
    enum { NS = 4096, NMAX = 200 };
    static const double two_pi = 6.283185307179586476925286766559;
    double c[NMAX], sum = 0.0, *Hs, *ctab;
    int n, j, K = -1;
    if (order != 3 || !h || !len) return -1;
    Hs = malloc(2 * NS * sizeof *Hs);
    if (!Hs) return -1;
    ctab = Hs + NS;
    for (j = 0; j < NS; j++) {
        Hs[j] = bl3_H(two_pi * j / NS);
        ctab[j] = cos(two_pi * j / NS);
    }
    /* cos(n w_j) = cos(2 pi (n j mod NS) / NS): a table lookup, exact */
    for (n = 0; n < NMAX; n++) {
        double acc = 0.0;
        for (j = 0; j < NS; j++) acc += Hs[j] * ctab[((size_t)n * (size_t)j) % NS];
        c[n] = acc / NS;
    }
    free(Hs);
    /* centre tap c[0]; truncate beyond the last |c[n]| >= tol */
    for (n = 0; n < NMAX; n++)
        if (fabs(c[n]) >= tol) K = n;
    if (K < 0 || K >= NMAX - 1 || 2 * K + 2 > cap) return -1;
    /* h[K + n] = h[K - n] = c[n]: our filters start at index 0 */
    for (n = -K; n <= K; n++) h[K + n] = c[n < 0 ? -n : n];
    /* The two-scale relation needs sum h = sqrt(2) (phi integrates to 1); truncation
     * moves it by ~1e-10, so rescale. The residual orthonormality defect is reported. */
    for (n = 0; n < 2 * K + 1; n++) sum += h[n];
    for (n = 0; n < 2 * K + 1; n++) h[n] *= sqrt(2.0) / sum;
    /* One zero tap at the end: the quadrature mirror g[n] = (-1)^n h[L-1-n] is orthogonal
     * to h only for an even length L (an odd shift), so the 2K+1 symmetric taps become
     * L = 2K+2 with h[L-1] = 0 (and g[0] = 0). The centre tap stays at index K. */
    h[2 * K + 1] = 0.0;
    *len = 2 * K + 2;
    return 0;
}
