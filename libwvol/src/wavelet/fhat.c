/* SPDX-License-Identifier: MIT */
/* f^ and its gradient at any point from a dense pyramid of coefficients, through
 * the spline tables: per level, each axis contributes the L-1 basis functions
 * (phi and psi) whose support holds the point, and each band sums the separable
 * products over those (L-1)^3 positions. */
#include <math.h>
#include <string.h>

#include "wavelet/basis_internal.h"

/* One axis at one level: positions (already wrapped, with the band's offset still
 * to add) and the values and derivatives of phi and psi there. */
typedef struct axis_eval {
    int n;                              /* taps that touch the point: L-1, or 1 on an untransformed axis */
    size_t ext;                         /* band extent along the axis at this level */
    size_t pos[WVOL_BASIS_MAX_LENGTH];
    double v[2][WVOL_BASIS_MAX_LENGTH]; /* [phi/psi][k], scaled by 2^{-m/2} */
    double d[2][WVOL_BASIS_MAX_LENGTH]; /* derivatives wrt the voxel coordinate */
} axis_eval;

/* y in [0, P) is the wrapped coordinate x + s on the padded grid. */
static void axis_setup(axis_eval *ax, const wvol_basis *b, size_t P, int m, double y, int need_grad)
{
    int k, n = b->length - 1, per = b->per_unit;
    double scale, dscale, t, fr, u, inv2m;
    long long i0;
    long long Pm;
    int j;
    if (P == 1) {
        /* untransformed axis: f^ is constant along it (sum_p phi(. - p) = 1) */
        ax->n = 1;
        ax->ext = 1;
        ax->pos[0] = 0;
        ax->v[0][0] = 1.0, ax->d[0][0] = 0.0;
        ax->v[1][0] = 0.0, ax->d[1][0] = 0.0;
        return;
    }
    Pm = (long long)(P >> m);
    ax->n = n;
    ax->ext = (size_t)Pm;
    inv2m = 1.0 / (double)(1ULL << m);                            /* 2^-m, exact */
    scale = (m & 1 ? M_SQRT1_2 : 1.0) / (double)(1ULL << (m / 2)); /* 2^{-m/2} */
    dscale = scale * inv2m;                   /* chain rule: d/dy of phi(2^-m y - p) */
    t = y * inv2m;                            /* exact */
    i0 = (long long)t;                        /* y >= 0 */
    fr = t - (double)i0;
    j = (int)(fr * b->inv_h);
    if (j >= per) j = per - 1;
    if (j < 0) j = 0;
    u = fr - j * b->h;
    /* the position p = i0 - k sees the point at 2^-m y - p = fr + k: piece j + k 2^J,
     * the same local u for every k */
    {
        long long p = i0 < Pm ? i0 : i0 % Pm;
        for (k = 0; k < n; k++) {
            const double *a = b->phi + 4 * (size_t)(j + k * per);
            const double *c = b->psi + 4 * (size_t)(j + k * per);
            ax->pos[k] = (size_t)p;
            ax->v[0][k] = scale * (a[0] + u * (a[1] + u * (a[2] + u * a[3])));
            ax->v[1][k] = scale * (c[0] + u * (c[1] + u * (c[2] + u * c[3])));
            if (need_grad) {
                ax->d[0][k] = dscale * (a[1] + u * (2.0 * a[2] + 3.0 * u * a[3]));
                ax->d[1][k] = dscale * (c[1] + u * (2.0 * c[2] + 3.0 * u * c[3]));
            }
            p = p == 0 ? Pm - 1 : p - 1;
        }
    }
}

static double wrap(double y, size_t P)
{
    double Pd = (double)P;
    if (y >= 0.0 && y < Pd) return y;
    y = fmod(y, Pd);
    if (y < 0.0) y += Pd;
    if (y >= Pd) y = 0.0;   /* -tiny + P rounds to P */
    return y;
}

static int same_filter(const wvol_filter *a, const wvol_filter *b)
{
    int n;
    if (a == b) return 1;
    if (!a || !b || a->length != b->length) return 0;
    for (n = 0; n < a->length; n++)
        if (a->h[n] != b->h[n]) return 0;
    return 1;
}

double wvol_fhat_eval(const wvol_coeffs *c, const wvol_basis *b, const double x[3], double grad[3])
{
    axis_eval ax[3];
    size_t P[3], sx, sxy;
    double y[3], val = 0.0, g[3] = {0.0, 0.0, 0.0};
    int m, a, band, need = grad != NULL;

    if (!c || !b || !x || !c->data || !same_filter(c->filter, b->filter) || !isfinite(x[0]) ||
        !isfinite(x[1]) || !isfinite(x[2]) || c->levels < 1 || c->levels > 62) {
        if (grad) grad[0] = grad[1] = grad[2] = NAN;
        return NAN;
    }
    P[0] = c->px, P[1] = c->py, P[2] = c->pz;
    for (a = 0; a < 3; a++)
        if (P[a] == 0 || (P[a] != 1 && ((P[a] >> c->levels) == 0 || (P[a] & (((size_t)1 << c->levels) - 1))))) {
            /* not a padded grid of this many levels */
            if (grad) grad[0] = grad[1] = grad[2] = NAN;
            return NAN;
        }
    sx = c->px;
    sxy = c->px * c->py;
    for (a = 0; a < 3; a++) y[a] = wrap(x[a] + b->center, P[a]);

    for (m = 1; m <= c->levels; m++) {
        for (a = 0; a < 3; a++) axis_setup(&ax[a], b, P[a], m, y[a], need);
        for (band = (m == c->levels ? 0 : 1); band < 8; band++) {
            int wx = band & 1, wy = (band >> 1) & 1, wz = (band >> 2) & 1, kx, ky, kz;
            const float *base;
            double bv = 0.0, bgx = 0.0, bgy = 0.0, bgz = 0.0;
            /* a high-pass bit on an untransformed axis: no such band */
            if ((wx && P[0] == 1) || (wy && P[1] == 1) || (wz && P[2] == 1)) continue;
            base = c->data + (wx ? ax[0].ext : 0) + sx * (wy ? ax[1].ext : 0) + sxy * (wz ? ax[2].ext : 0);
            for (kz = 0; kz < ax[2].n; kz++) {
                const float *plane = base + sxy * ax[2].pos[kz];
                double av = 0.0, agx = 0.0, agy = 0.0;
                for (ky = 0; ky < ax[1].n; ky++) {
                    const float *row = plane + sx * ax[1].pos[ky];
                    const double *vx = ax[0].v[wx];
                    double sv = 0.0, sd = 0.0;
                    if (need) {
                        const double *dx = ax[0].d[wx];
                        for (kx = 0; kx < ax[0].n; kx++) {
                            double cv = row[ax[0].pos[kx]];
                            sv += cv * vx[kx];
                            sd += cv * dx[kx];
                        }
                        av += sv * ax[1].v[wy][ky];
                        agx += sd * ax[1].v[wy][ky];
                        agy += sv * ax[1].d[wy][ky];
                    } else {
                        for (kx = 0; kx < ax[0].n; kx++) sv += (double)row[ax[0].pos[kx]] * vx[kx];
                        av += sv * ax[1].v[wy][ky];
                    }
                }
                bv += av * ax[2].v[wz][kz];
                if (need) {
                    bgx += agx * ax[2].v[wz][kz];
                    bgy += agy * ax[2].v[wz][kz];
                    bgz += av * ax[2].d[wz][kz];
                }
            }
            val += bv;
            g[0] += bgx, g[1] += bgy, g[2] += bgz;
        }
    }
    if (grad) grad[0] = g[0], grad[1] = g[1], grad[2] = g[2];
    return val;
}
