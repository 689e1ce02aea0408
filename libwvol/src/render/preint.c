/* SPDX-License-Identifier: MIT
 * Pre-integrated transfer functions: the emission-absorption integral over one ray segment
 * along which the scalar is linear, for the piecewise-linear TF, computed per TF segment
 * crossed (no table, so no quantisation of the scalar and no table to rebuild per step).
 *
 * Based on: Engel, Kraus, Ertl 2001 (pre-integrated classification: the scalar linear
 * between samples, the segment's integral read from a table over (front, back) values);
 * Roettger, Kraus, Ertl 2000 / Max, Hanrahan, Crawfis 1990 (the same integral split at the
 * TF's knots, each piece with linear kappa and colour: the piecewise-polynomial form). */
#include "reference_internal.h"

/* Gauss-Legendre, 3 nodes on [0, 1]: exact for polynomials of degree 5 */
static const double GL_X[3] = {0.1127016653792583, 0.5, 0.8872983346207417};
static const double GL_W[3] = {0.2777777777777778, 0.4444444444444444, 0.2777777777777778};

/* The optical depth tau(s) = K0 s + q s^2 (s in [0, 1], q = (K1 - K0) / 2) that one
 * sub-interval of the mean below spans at most: exp varies by a factor e^0.25 over it, and
 * 3-node Gauss-Legendre is then within a relative ~1e-9 (its error term, tau'^6 / 2e6). */
#define PREINT_DTAU 0.25
/* Beyond this optical depth into a piece the rest of the mean weighs below e^-40 */
#define PREINT_TAU_END 40.0

/* The parameter s in [0, 1] where tau(s) = target (tau increases: K0 >= 0, K0 + 2q >= 0),
 * in the form that does not cancel. */
static inline double tau_inverse(double K0, double q, double target)
{
    double disc = K0 * K0 + 4.0 * q * target, s;
    if (disc < 0) disc = 0;
    s = K0 + sqrt(disc) > 0 ? 2.0 * target / (K0 + sqrt(disc)) : 1.0;
    return s < 1.0 ? s : 1.0;
}

/* The mean transmittance over a piece, M = int_0^1 exp(-(K0 s + q s^2)) ds, for K0, K1 >= 0:
 * exact when kappa is constant on the piece, else Gauss-Legendre on sub-intervals that each
 * span at most PREINT_DTAU of optical depth (placed by inverting tau), up to PREINT_TAU_END. */
static double mean_transmittance(double K0, double K1, const double *exp2_256)
{
    const double q = 0.5 * (K1 - K0), total = 0.5 * (K0 + K1);
    double s0 = 0.0, m = 0.0, tau0 = 0.0;
    if (fabs(K1 - K0) <= 1e-12 * total) return total > 1e-300 ? -expm1(-total) / total : 1.0;
    while (s0 < 1.0 && tau0 < PREINT_TAU_END) {
        double tau1 = tau0 + PREINT_DTAU, s1 = tau1 >= total ? 1.0 : tau_inverse(K0, q, tau1), h = s1 - s0;
        if (!(h > 0)) break;
        for (int i = 0; i < 3; i++) {
            double s = s0 + GL_X[i] * h;
            m += GL_W[i] * h * exp_neg(-(K0 * s + q * s * s), exp2_256);
        }
        s0 = s1;
        tau0 = tau1;
    }
    return m;
}

/* Colour and kappa at value v on TF segment i (its linear formula; i = -1 below the first
 * point, n - 1 at and above the last: the constants there). */
static inline void seg_eval(const tf_fast *f, int i, double v, double ck[4])
{
    if (i < 0) {
        for (int c = 0; c < 4; c++) ck[c] = f->c0[0][c];
    } else if (i >= f->n - 1) {
        for (int c = 0; c < 4; c++) ck[c] = f->c0[f->n - 1][c];
    } else {
        double w = v - f->v[i];
        for (int c = 0; c < 4; c++) ck[c] = f->c0[i][c] + w * f->dc[i][c];
        if (ck[3] < 0) ck[3] = 0; /* rounding at a knot where kappa reaches 0 */
    }
}

/* The TF segment holding v: -1 below the first point, n - 1 at or above the last. */
static inline int seg_of(const tf_fast *f, double v)
{
    int lo = 0, hi = f->n - 1;
    if (!(v >= f->v[0])) return -1;
    if (v >= f->v[f->n - 1]) return f->n - 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (f->v[mid] <= v) lo = mid;
        else hi = mid;
    }
    return lo;
}

/* One piece of length len on which kappa and colour are linear, from ck0 to ck1: T and the
 * colour updated. Its optical depth is exact; its emission int c kappa exp(-tau) is, by
 * parts (d(1 - e^-tau) = kappa e^-tau ds), c1 A - (c1 - c0)(1 - M) with A = 1 - e^-tau(len)
 * and M the mean transmittance over the piece: exact up to M's quadrature. */
static inline void piece(const tf_fast *f, const double ck0[4], const double ck1[4], double len, double shade,
                         ray_acc *r)
{
    const double K0 = ck0[3] * len, K1 = ck1[3] * len, tau = 0.5 * (K0 + K1);
    double A, M;
    if (!(tau > 0)) return; /* kappa 0 on the piece: no emission, no absorption */
    A = -expm1(-tau);
    M = 1.0;
    for (int c = 0; c < 3; c++)
        if (ck0[c] != ck1[c]) { /* a colour that changes needs the mean */
            M = mean_transmittance(K0, K1, f->exp2_256);
            break;
        }
    for (int c = 0; c < 3; c++) r->acc[c] += r->T * shade * (ck1[c] * A - (ck1[c] - ck0[c]) * (1.0 - M));
    r->T *= 1.0 - A;
}

void wvol__preint_segment(const tf_fast *f, double a, double b, double len, double shade, ray_acc *r)
{
    double ck0[4], ck1[4], va = a;
    int ia, ib;
    if (!(len > 0) || !(r->T > 0)) return;
    if (a != a) a = b; /* NaN values composite as the TF's first point, as tf_fast_eval does */
    if (b != b) b = a;
    if (a != a) a = b = -INFINITY;
    ia = seg_of(f, a);
    ib = seg_of(f, b);
    va = a;
    seg_eval(f, ia, a, ck0);
    if (ia == ib) { /* the common case: one TF segment */
        seg_eval(f, ib, b, ck1);
        piece(f, ck0, ck1, len, shade, r);
        return;
    }
    /* the knots between a and b, in the ray's order; the piece from va to knot v lies on one
     * TF segment (the lower of the two it separates when rising, the upper when falling) */
    {
        const int up = b > a, step = up ? 1 : -1;
        int i = up ? ia + 1 : ia;          /* the next knot's index */
        const double inv = len / (b - a); /* length per unit of value */
        while (up ? i <= ib : i > ib) {
            const double v = f->v[i];
            const int seg = up ? i - 1 : i;
            double c0[4], c1[4];
            seg_eval(f, seg, va, c0);
            seg_eval(f, seg, v, c1);
            piece(f, c0, c1, (v - va) * inv, shade, r);
            va = v;
            i += step;
        }
        seg_eval(f, ib, va, ck0);
        seg_eval(f, ib, b, ck1);
        piece(f, ck0, ck1, (b - va) * inv, shade, r);
    }
}
