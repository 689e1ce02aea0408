/* SPDX-License-Identifier: MIT
 * Gauss-Legendre rules: the roots of P_n by Newton's method from Tricomi's estimate. */
#include "core/quadrature.h"

#include <math.h>

void wvol__gauss_legendre(int n, double *x, double *w)
{
    int i, it, k;
    for (i = 0; i < n; i++) {
        double z = cos(3.14159265358979323846 * (i + 0.75) / (n + 0.5)), pp = 1;
        for (it = 0; it < 100; it++) {
            double p0 = 1, p1 = 0, dz;
            for (k = 1; k <= n; k++) {
                double p2 = p1;
                p1 = p0;
                p0 = ((2.0 * k - 1) * z * p1 - (k - 1.0) * p2) / k;
            }
            pp = n * (z * p0 - p1) / (z * z - 1);
            dz = p0 / pp;
            z -= dz;
            if (fabs(dz) < 1e-16) break;
        }
        x[i] = 0.5 * (1 - z);
        w[i] = 1.0 / ((1 - z * z) * pp * pp);
    }
}
