/* SPDX-License-Identifier: MIT
 * The exact first crossing of the trilinear interpolant of one cell along a ray segment
 * (Marmitt, Kleer, Wald, Friedrich, Slusallek 2004, "Fast and accurate ray-voxel
 * intersection techniques for iso-surface ray tracing"; Parker et al. 1998).
 *
 * Along q(tau) = q0 + tau dq the interpolant sum_ijk c_ijk u_i(x) v_j(y) w_k(z), with
 * u_0 = 1 - x, u_1 = x (likewise v, w), is a product of three linear factors per corner, so
 * g(tau) = interp - iso = A tau^3 + B tau^2 + C tau + D. The roots of g' = 3A tau^2 + 2B tau + C
 * inside (0, len) cut [0, len] into at most three parts on which g is monotone: on such a part
 * g lies between its end values, so the class (g >= 0) can only change once, and only if the
 * far end's class differs from the near end's. The first such part holds the first crossing,
 * refined by bisection on the class (never leaving the part, so never jumping to a later root).
 * A tangent touch (g reaching 0 at a root of g' without changing sign) is found too: the
 * part's end has class g >= 0. Rounding: the coefficients and values are float64 sums of
 * float32 corners, accurate to ~1e-15 of the corners' magnitudes; crossings of smaller
 * amplitude can be missed or added (the guarantee says so). */
#include <math.h>

#include "iso_internal.h"

/* g(tau) by Horner. */
static inline double cubic(const double k[4], double t)
{
    return ((k[0] * t + k[1]) * t + k[2]) * t + k[3];
}

double wvol__cell_eval(const double c[8], const double q[3], double grad[3])
{
    double x = q[0], y = q[1], z = q[2];
    /* along x first, then y, then z */
    double c00 = c[0] + x * (c[1] - c[0]), c10 = c[2] + x * (c[3] - c[2]);
    double c01 = c[4] + x * (c[5] - c[4]), c11 = c[6] + x * (c[7] - c[6]);
    double c0 = c00 + y * (c10 - c00), c1 = c01 + y * (c11 - c01);
    if (grad) {
        double dx00 = c[1] - c[0], dx10 = c[3] - c[2], dx01 = c[5] - c[4], dx11 = c[7] - c[6];
        double dx0 = dx00 + y * (dx10 - dx00), dx1 = dx01 + y * (dx11 - dx01);
        grad[0] = dx0 + z * (dx1 - dx0);
        grad[1] = (c10 - c00) + z * ((c11 - c01) - (c10 - c00));
        grad[2] = c1 - c0;
    }
    return c0 + z * (c1 - c0);
}

int wvol__cell_crossing(const double c[8], const double q0[3], const double dq[3], double len, double iso, int *cls,
                        double tol, double *tau)
{
    double k[4] = {0, 0, 0, 0}, cut[4], q[3];
    int n = 0, i, s0;
    for (i = 0; i < 3; i++) q[i] = q0[i] < 0.0 ? 0.0 : q0[i] > 1.0 ? 1.0 : q0[i]; /* the start is in the cell */
    q0 = q;
    /* sum over the corners of (c - iso)(A0 + t A1)(B0 + t B1)(C0 + t C1): with iso taken from
     * each corner first, a corner equal to iso adds exactly nothing, so a plateau at iso is
     * g = 0 exactly (class >= iso), and corners all >= iso give g >= 0 exactly */
    for (i = 0; i < 8; i++) {
        int bx = i & 1, by = (i >> 1) & 1, bz = (i >> 2) & 1;
        double a0 = bx ? q0[0] : 1.0 - q0[0], a1 = bx ? dq[0] : -dq[0];
        double b0 = by ? q0[1] : 1.0 - q0[1], b1 = by ? dq[1] : -dq[1];
        double e0 = bz ? q0[2] : 1.0 - q0[2], e1 = bz ? dq[2] : -dq[2];
        double ci = c[i] - iso;
        k[3] += ci * a0 * b0 * e0;
        k[2] += ci * (a1 * b0 * e0 + a0 * b1 * e0 + a0 * b0 * e1);
        k[1] += ci * (a1 * b1 * e0 + a1 * b0 * e1 + a0 * b1 * e1);
        k[0] += ci * a1 * b1 * e1;
    }
    s0 = *cls < 0 ? k[3] >= 0.0 : *cls; /* the class before the segment */
    *cls = s0;
    if ((k[3] >= 0.0) != s0) {      /* already of the other class at the start */
        *tau = 0.0;
        return 1;
    }
    cut[n++] = 0.0;
    { /* roots of g' = 3 k0 t^2 + 2 k1 t + k2 inside (0, len), increasing */
        double qa = 3.0 * k[0], qb = 2.0 * k[1], qc = k[2], r[2];
        int nr = 0;
        if (qa != 0.0) {
            double disc = qb * qb - 4.0 * qa * qc;
            if (disc >= 0.0) {
                /* the stable pair of formulas (no cancellation) */
                double sq = sqrt(disc), qq = -0.5 * (qb + (qb >= 0 ? sq : -sq));
                r[nr++] = qq / qa;
                if (qq != 0.0) r[nr++] = qc / qq;
            }
        } else if (qb != 0.0) {
            r[nr++] = -qc / qb;
        }
        if (nr == 2 && r[1] < r[0]) {
            double x = r[0];
            r[0] = r[1], r[1] = x;
        }
        for (i = 0; i < nr; i++)
            if (r[i] > 0.0 && r[i] < len) cut[n++] = r[i];
    }
    cut[n++] = len;
    for (i = 1; i < n; i++) {
        double a = cut[i - 1], b = cut[i];
        if ((cubic(k, b) >= 0.0) == s0) continue;
        /* the part [a, b] is monotone; class s0 at a (the previous part ended there in s0),
         * the other class at b: bisect on the class */
        while (b - a > tol) {
            double m = 0.5 * (a + b);
            if (m <= a || m >= b) break;
            if ((cubic(k, m) >= 0.0) == s0) a = m;
            else b = m;
        }
        *tau = b;
        return 1;
    }
    return 0;
}
