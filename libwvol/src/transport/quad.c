/* SPDX-License-Identifier: MIT
 * Planar parallelograms with a frame: the rectilinear parametric <-> object mapping and the
 * Nusselt direction coordinates of Lewis & Fournier 2002 (eqs. 2-3, §7.1.1.1). Kept small and
 * separate so the radiosity module's quads can absorb it. */
#include "transport_internal.h"

#include <math.h>

static void sub3(const double a[3], const double b[3], double r[3])
{
    for (int i = 0; i < 3; i++) r[i] = a[i] - b[i];
}

static void cross3(const double a[3], const double b[3], double r[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

wvol_status wvol_transport_quad_check(const wvol_transport_quad *q, wvol_error *err)
{
    double eu[3], ev[3], n[3], d[3], lu, lv, ln, scale, off;
    WVOL_RETURN_IF(!q, err, WVOL_ERR_ARG, "quad: NULL");
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 3; c++)
            WVOL_RETURN_IF(!isfinite(q->p[i][c]), err, WVOL_ERR_NONFINITE, "quad: vertex %d coordinate %d is not finite",
                           i, c);
    /* the transfer integrals take up to fourth powers of lengths (areas over squared distances,
     * squared): beyond 1e60, or edges below 1e-60, they leave double's range and came out 0 */
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 3; c++)
            WVOL_RETURN_IF(fabs(q->p[i][c]) > 1e60, err, WVOL_ERR_ARG,
                           "quad: vertex %d coordinate %d is %g: coordinates must lie within +-1e60 (the transfer "
                           "integrals take fourth powers of lengths); scale the scene",
                           i, c, q->p[i][c]);
    sub3(q->p[1], q->p[0], eu);
    sub3(q->p[3], q->p[0], ev);
    cross3(eu, ev, n);
    lu = sqrt(wvol__dot3(eu, eu));
    lv = sqrt(wvol__dot3(ev, ev));
    ln = sqrt(wvol__dot3(n, n));
    scale = lu > lv ? lu : lv;
    WVOL_RETURN_IF(lu > 0 && lv > 0 && (lu < 1e-60 || lv < 1e-60), err, WVOL_ERR_ARG,
                   "quad: edges p0p1 and p0p3 of lengths %g and %g: edges must be at least 1e-60 long (the "
                   "transfer integrals take fourth powers of lengths); scale the scene",
                   lu, lv);
    WVOL_RETURN_IF(!(lu > 0 && lv > 0) || !(ln > 1e-9 * lu * lv), err, WVOL_ERR_ARG,
                   "quad: degenerate (edges p0p1 and p0p3 of lengths %g and %g span an area of %g)", lu, lv, ln);
    /* p2 must be p1 + p3 - p0: first out of the plane (non-planar), then in it (not a parallelogram) */
    for (int c = 0; c < 3; c++) d[c] = q->p[2][c] - (q->p[1][c] + q->p[3][c] - q->p[0][c]);
    off = wvol__dot3(d, n) / ln;
    WVOL_RETURN_IF(fabs(off) > 1e-9 * scale, err, WVOL_ERR_ARG,
                   "quad: non-planar (p2 lies %g off the plane of p0, p1, p3)", off);
    WVOL_RETURN_IF(sqrt(wvol__dot3(d, d)) > 1e-9 * scale, err, WVOL_ERR_ARG,
                   "quad: not a parallelogram (p2 is %g from p1 + p3 - p0; the rectilinear mapping needs one)",
                   sqrt(wvol__dot3(d, d)));
    return WVOL_OK;
}

void wvol__tframe_init(wvol__tframe *f, const wvol_transport_quad *q)
{
    double g00, g01, g11, det, l;
    for (int c = 0; c < 3; c++) {
        f->o[c] = q->p[0][c];
        f->eu[c] = q->p[1][c] - q->p[0][c];
        f->ev[c] = q->p[3][c] - q->p[0][c];
    }
    cross3(f->eu, f->ev, f->n);
    l = sqrt(wvol__dot3(f->n, f->n));
    f->area = l;
    for (int c = 0; c < 3; c++) f->n[c] /= l;
    l = sqrt(wvol__dot3(f->eu, f->eu));
    for (int c = 0; c < 3; c++) f->t[c] = f->eu[c] / l;
    cross3(f->n, f->t, f->b);
    g00 = wvol__dot3(f->eu, f->eu);
    g01 = wvol__dot3(f->eu, f->ev);
    g11 = wvol__dot3(f->ev, f->ev);
    det = g00 * g11 - g01 * g01;
    f->ginv[0][0] = g11 / det;
    f->ginv[0][1] = -g01 / det;
    f->ginv[1][0] = -g01 / det;
    f->ginv[1][1] = g00 / det;
}

void wvol__tframe_point(const wvol__tframe *f, double u, double v, double x[3])
{
    for (int c = 0; c < 3; c++) x[c] = f->o[c] + u * f->eu[c] + v * f->ev[c];
}

void wvol__tframe_param(const wvol__tframe *f, const double x[3], double uv[2])
{
    double d[3], a, b;
    sub3(x, f->o, d);
    a = wvol__dot3(d, f->eu);
    b = wvol__dot3(d, f->ev);
    uv[0] = f->ginv[0][0] * a + f->ginv[0][1] * b;
    uv[1] = f->ginv[1][0] * a + f->ginv[1][1] * b;
}

int wvol__tframe_dir(const wvol__tframe *f, double k, double l, double w[3])
{
    double mx = 2 * k - 1, my = 2 * l - 1, r2 = mx * mx + my * my, mz;
    if (!(r2 < 1)) return 0;
    mz = sqrt(1 - r2);
    for (int c = 0; c < 3; c++) w[c] = mx * f->t[c] + my * f->b[c] + mz * f->n[c];
    return 1;
}

void wvol__tframe_kl(const wvol__tframe *f, const double w[3], double kl[2])
{
    kl[0] = 0.5 * (wvol__dot3(w, f->t) + 1);
    kl[1] = 0.5 * (wvol__dot3(w, f->b) + 1);
}
