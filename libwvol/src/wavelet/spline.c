/* SPDX-License-Identifier: MIT */
/* Cubic splines on a uniform grid in monomial form, with their derivative and
 * primitive pieces, exact products and bounds. The spline of phi (psi) on its
 * support [0, L-1] has periodic end conditions: S'(0) = S'(L-1), S''(0) = S''(L-1).
 * Then at every integer the jumps of S', S'' of the copies of S that end there
 * cancel those of the copies that start there, so sum_p S(x - p) is a C^2
 * periodic spline interpolating 1 at every knot, i.e. exactly 1: the spline model
 * keeps the partition of unity (a constant volume stays constant) and the
 * integral h sum_i y_i (trapezoid rule, exact for periodic splines).
 * Based on: de Boor, A Practical Guide to Splines (1978), chapter IV (the
 * second-derivative form); Sherman-Morrison for the cyclic tridiagonal system. */
#include <math.h>
#include <stdlib.h>

#include "wavelet/basis_internal.h"

/* Periodic cubic spline through y[0..n] (y[n] == y[0]) with period n h. The
 * moments M_i = S''(x_i) solve the cyclic system
 *   M_{i-1} + 4 M_i + M_{i+1} = 6 (y_{i-1} - 2 y_i + y_{i+1}) / h^2,  i mod n,
 * strictly diagonally dominant, by Sherman-Morrison around the Thomas algorithm;
 * then on [x_i, x_i + h): S = y_i + b u + M_i/2 u^2 + (M_{i+1} - M_i)/(6h) u^3
 * with b = (y_{i+1} - y_i)/h - h (2 M_i + M_{i+1})/6. */
wvol_status wvol__spline_periodic(double *c, const double *y, size_t n, double h, wvol_error *err)
{
    double *m, *z, *cp, inv_h2 = 1.0 / (h * h);
    size_t i;
    if (n < 3) return wvol_error_set(err, WVOL_ERR_ARG, "spline: %zu intervals (3 or more needed)", n);
    m = malloc(3 * (n + 1) * sizeof *m);
    if (!m) return wvol_error_set(err, WVOL_ERR_NOMEM, "spline: out of memory for %zu knots", n + 1);
    z = m + (n + 1);
    cp = z + (n + 1);
    {
        /* A = T + u v^T with T tridiagonal: gamma = -4, T[0][0] = 4 - gamma, T[n-1][n-1] = 4 - 1/gamma,
         * u = (gamma, 0.., 1), v = (1, 0.., 1/gamma). Solve T x = r and T z = u. */
        double gamma = -4.0, beta, fact;
        double *r = m; /* right-hand side, overwritten by x */
        for (i = 0; i < n; i++) {
            double ym = y[i == 0 ? n - 1 : i - 1], yp = y[i + 1];
            r[i] = 6.0 * (ym - 2.0 * y[i] + yp) * inv_h2;
            z[i] = (i == 0) ? gamma : (i == n - 1 ? 1.0 : 0.0);
        }
        for (i = 0; i < n; i++) {
            double diag = 4.0;
            if (i == 0) diag = 4.0 - gamma;
            if (i == n - 1) diag = 4.0 - 1.0 / gamma;
            beta = diag - (i ? cp[i - 1] : 0.0);
            cp[i] = 1.0 / beta;
            r[i] = (r[i] - (i ? r[i - 1] : 0.0)) / beta;
            z[i] = (z[i] - (i ? z[i - 1] : 0.0)) / beta;
        }
        for (i = n - 1; i-- > 0;) {
            r[i] -= cp[i] * r[i + 1];
            z[i] -= cp[i] * z[i + 1];
        }
        fact = (r[0] + r[n - 1] / gamma) / (1.0 + z[0] + z[n - 1] / gamma);
        for (i = 0; i < n; i++) r[i] -= fact * z[i];
        r[n] = r[0];
    }
    for (i = 0; i < n; i++) {
        double *p = c + 4 * i;
        p[0] = y[i];
        p[1] = (y[i + 1] - y[i]) / h - h * (2.0 * m[i] + m[i + 1]) / 6.0;
        p[2] = 0.5 * m[i];
        p[3] = (m[i + 1] - m[i]) / (6.0 * h);
    }
    free(m);
    return WVOL_OK;
}

void wvol__spline_deriv(double *d, const double *c, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        d[4 * i + 0] = c[4 * i + 1];
        d[4 * i + 1] = 2.0 * c[4 * i + 2];
        d[4 * i + 2] = 3.0 * c[4 * i + 3];
        d[4 * i + 3] = 0.0;
    }
}

/* Primitive from 0; the running integral is summed with Kahan compensation so
 * that the value at the end of a long table (bl3 at J = 12 has ~10^5 pieces)
 * keeps full precision. Returns the total integral. */
double wvol__spline_primitive(double *P, const double *c, size_t n, double h)
{
    double acc = 0.0, comp = 0.0, piece, yk, t;
    size_t i;
    for (i = 0; i < n; i++) {
        const double *p = c + 4 * i;
        double *q = P + 5 * i;
        q[0] = acc;
        q[1] = p[0];
        q[2] = p[1] / 2.0;
        q[3] = p[2] / 3.0;
        q[4] = p[3] / 4.0;
        piece = h * (q[1] + h * (q[2] + h * (q[3] + h * q[4])));
        yk = piece - comp;
        t = acc + yk;
        comp = (t - acc) - yk;
        acc = t;
    }
    return acc;
}

/* max |c(u)| over u in [0, h]: ends and the roots of c'(u) = c1 + 2 c2 u + 3 c3 u^2 */
double wvol__cubic_absmax(const double *c, double h)
{
    double best = fabs(c[0]), v, roots[2];
    int nr = 0, k;
    double a = 3.0 * c[3], b = 2.0 * c[2], cc = c[1];
    v = c[0] + h * (c[1] + h * (c[2] + h * c[3]));
    if (fabs(v) > best) best = fabs(v);
    if (a != 0.0) {
        double disc = b * b - 4.0 * a * cc;
        if (disc >= 0.0) {
            double sq = sqrt(disc), qq = -0.5 * (b + (b >= 0 ? sq : -sq));
            if (qq != 0.0) roots[nr++] = qq / a, roots[nr++] = cc / qq;
            else roots[nr++] = 0.0;
        }
    } else if (b != 0.0) {
        roots[nr++] = -cc / b;
    }
    for (k = 0; k < nr; k++)
        if (roots[k] > 0.0 && roots[k] < h) {
            double u = roots[k];
            v = c[0] + u * (c[1] + u * (c[2] + u * c[3]));
            if (fabs(v) > best) best = fabs(v);
        }
    return best;
}

/* integral over [0, h] of |c(u)|: split at the real roots of the cubic in (0, h)
 * (found by bisection between sign changes of a fine sampling refined by the
 * critical points) and integrate each part exactly. */
double wvol__cubic_absint(const double *c, double h)
{
    double cut[8], x[8], s = 0.0;
    int nc = 0, k;
    /* critical points split [0,h] into monotone runs: each has at most one root */
    double a = 3.0 * c[3], b = 2.0 * c[2], cc = c[1];
    x[nc++] = 0.0;
    if (a != 0.0) {
        double disc = b * b - 4.0 * a * cc;
        if (disc > 0.0) {
            double sq = sqrt(disc), qq = -0.5 * (b + (b >= 0 ? sq : -sq)), r1, r2;
            if (qq != 0.0) {
                r1 = qq / a, r2 = cc / qq;
                if (r1 > r2) { double t = r1; r1 = r2; r2 = t; }
                if (r1 > 0.0 && r1 < h) x[nc++] = r1;
                if (r2 > 0.0 && r2 < h) x[nc++] = r2;
            }
        }
    } else if (b != 0.0) {
        double r = -cc / b;
        if (r > 0.0 && r < h) x[nc++] = r;
    }
    x[nc++] = h;
    {
        int nx = nc, m = 0;
        for (k = 0; k + 1 < nx; k++) {
            double lo = x[k], hi = x[k + 1];
            double flo = c[0] + lo * (c[1] + lo * (c[2] + lo * c[3]));
            double fhi = c[0] + hi * (c[1] + hi * (c[2] + hi * c[3]));
            cut[m++] = lo;
            if ((flo < 0.0 && fhi > 0.0) || (flo > 0.0 && fhi < 0.0)) {
                int it;
                for (it = 0; it < 80; it++) {
                    double mid = 0.5 * (lo + hi), fm = c[0] + mid * (c[1] + mid * (c[2] + mid * c[3]));
                    if ((fm < 0.0) == (flo < 0.0)) lo = mid, flo = fm;
                    else hi = mid;
                }
                cut[m++] = 0.5 * (lo + hi);
            }
        }
        cut[m++] = h;
        for (k = 0; k + 1 < m; k++) {
            double u0 = cut[k], u1 = cut[k + 1];
            double I1 = u1 * (c[0] + u1 * (c[1] / 2 + u1 * (c[2] / 3 + u1 * c[3] / 4)));
            double I0 = u0 * (c[0] + u0 * (c[1] / 2 + u0 * (c[2] / 3 + u0 * c[3] / 4)));
            s += fabs(I1 - I0);
        }
    }
    return s;
}

void wvol_poly3_affine(double out[4], const double c[4], double a, double d)
{
    /* c(a t + d): Taylor shift to d, then scale by a */
    if (!out) return;
    if (!c) {
        out[0] = out[1] = out[2] = out[3] = 0.0;
        return;
    }
    double c0 = c[0] + d * (c[1] + d * (c[2] + d * c[3]));
    double c1 = c[1] + d * (2.0 * c[2] + 3.0 * d * c[3]);
    double c2 = c[2] + 3.0 * d * c[3];
    double c3 = c[3];
    out[0] = c0;
    out[1] = c1 * a;
    out[2] = c2 * a * a;
    out[3] = c3 * a * a * a;
}

void wvol_poly3_bernstein(double bz[4], const double a[4])
{
    if (!bz) return;
    if (!a) {
        bz[0] = bz[1] = bz[2] = bz[3] = 0.0;
        return;
    }
    const double a0 = a[0], a1 = a[1], a2 = a[2], a3 = a[3];
    bz[0] = a0;
    bz[1] = a0 + a1 / 3.0;
    bz[2] = a0 + (2.0 * a1 + a2) / 3.0;
    bz[3] = a0 + a1 + a2 + a3;
}
