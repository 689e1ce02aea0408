/* SPDX-License-Identifier: MIT
 * Fast path: X-ray for any orthographic view by footprint splatting (DESIGN.md section 8).
 *
 * Every basis function of a store is a translate and dilate of one of 8 unit functions
 * B_band(y) = prod_a theta_a(y_a) (theta = phi or psi by the band's bit a), supported on the
 * cube [0, L-1]^3. Along parallel rays y(s) = w + s e (e a unit vector, w in the plane normal
 * to it) the X-ray of B_band is a function of w alone, its footprint
 *   T(w) = integral of B_band(w + s e) ds,
 * and the part of the line up to s = r is G(w, r). A level-m function with lower corner lo
 * adds, to the pixel whose voxel-space ray is o + t D (t world),
 *   value * norm * (2^m / |D|) * (G(w, s_out) - G(w, s_in)),
 * with y0 = (o - lo) / 2^m split into w and rho = y0 . e, and s = t |D| / 2^m + rho at the
 * ray's entry and exit of the rendered box. For a function inside the box every ray crosses
 * all of its support and the difference is T(w). So one table per band, built once per view
 * (the dilation takes care of the levels), is all the splat needs: T on a fine grid of the
 * footprint plane (bilinear), G on a coarser 3D grid (trilinear) for the functions the box
 * clips. X-ray is linear in the coefficients, so the image is the sum of the splats.
 *
 * The tables are integrals of the spline model along lines: Gauss-Legendre (3 nodes) on
 * intervals of at most 1/64 unit, split at every half-integer plane (where Haar jumps and
 * where the splines' slopes jump at the support ends), exact for each piece up to the
 * spline pieces' C^2 joins inside. The error of the image is the tables' interpolation
 * error, measured against the exact spline-projected integrator (docs/render.md).
 * Based on: Westover 1990 (footprint splatting); Lippert & Gross 1995 (wavelet splatting). */
#include "render_internal.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>


/* Grid steps in units of the unit function, for supports up to 3 (db2); longer supports scale
 * them so that the tables keep their size (~21 MB). The footprint plane's step of the 2D table
 * (bilinear) and of the 3D one, and the 3D table's step along the line (cubic Hermite), chosen
 * by measurement on db2 (docs/render.md): the error is ~0.3 h^2 relative in the plane's steps,
 * and the 3D table's plane step dominates (1/16: ~1e-3 where most functions are clipped; 1/32
 * would give 3e-4 at 4 times the memory). */
#define SPLAT_H2 (1.0 / 32.0)
#define SPLAT_H3 (1.0 / 16.0)
#define SPLAT_HR (1.0 / 8.0)
#define SPLAT_SUB (1.0 / 16.0)   /* longest quadrature interval along a line (3 Gauss nodes) */
#define SPLAT_MAX_SUPPORT 9      /* L - 1: longer filters (bl3) are refused */

typedef struct splat_tables {
    double e[3], e1[3], e2[3];  /* line direction and the plane's orthonormal basis (unit space) */
    double u1lo, u2lo, rlo, rhi;
    double h2, inv_h2, h3, inv_h3, hr, inv_hr;
    int n1, n2;                 /* 2D grid: n1 x n2 nodes */
    int m1, m2, mr;             /* 3D grid */
    float *T;                   /* [band][n2][n1] */
    float *G;                   /* [band][mr][m2][m1][2]: integral up to r_k = rlo + k hr, and the
                                   integrand at r_k (its derivative: cubic Hermite in r) */
} splat_tables;

static void cross3(double out[3], const double a[3], const double b[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void unit3(double a[3])
{
    double n = sqrt(dot3(a, a));
    a[0] /= n, a[1] /= n, a[2] /= n;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The 8 unit functions at the point w + s e. */
static void unit_values(const splat_tables *t, const wvol_basis *b, const double w[3], double s, double out[8])
{
    double f[3][2];
    int a, band;
    for (a = 0; a < 3; a++) {
        double x = w[a] + s * t->e[a];
        f[a][0] = wvol_basis_value(b, WVOL_BASIS_PHI, x);
        f[a][1] = wvol_basis_value(b, WVOL_BASIS_PSI, x);
    }
    for (band = 0; band < 8; band++) out[band] = f[0][band & 1] * f[1][(band >> 1) & 1] * f[2][(band >> 2) & 1];
}

/* Integrates the 8 unit functions along the line w + s e over [rlo, rhi]: tot[band] gets the
 * whole integrals and, when cum is set, cum[(k * 8 + band) * 2] the integral up to
 * r_k = rlo + k hr (k = 0..mr-1) and cum[(k * 8 + band) * 2 + 1] its derivative in r there,
 * the integrand at r_k. brk: scratch for the breakpoints. */
static void line_integrals(const splat_tables *t, const wvol_basis *b, const double w[3], double tot[8], double *cum,
                           double *brk, size_t cap)
{
    static const double gx[3] = {0.11270166537925831148, 0.5, 0.88729833462074168852};
    static const double gw[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
    size_t nb = 0, i;
    int a, band, k, nextk = 0;
    double acc[8] = {0}, sup = b->support;
    /* the part of the line inside the cube [0, L-1]^3 */
    double s0 = t->rlo, s1 = t->rhi;
    for (a = 0; a < 3; a++) {
        if (fabs(t->e[a]) < 1e-15) {
            if (w[a] < 0 || w[a] > sup) s1 = s0 - 1; /* misses */
            continue;
        }
        double ta = (0 - w[a]) / t->e[a], tb = (sup - w[a]) / t->e[a];
        if (ta > tb) {
            double x = ta;
            ta = tb, tb = x;
        }
        if (ta > s0) s0 = ta;
        if (tb < s1) s1 = tb;
    }
    if (cum)
        for (k = 0; k < 16 * t->mr; k++) cum[k] = 0;
    for (band = 0; band < 8; band++) tot[band] = 0;
    if (!(s1 > s0)) return;
    brk[nb++] = s0;
    brk[nb++] = s1;
    for (a = 0; a < 3; a++) {
        if (fabs(t->e[a]) < 1e-15) continue;
        double x0 = w[a] + s0 * t->e[a], x1 = w[a] + s1 * t->e[a];
        long j0 = (long)ceil(2.0 * fmin(x0, x1)), j1 = (long)floor(2.0 * fmax(x0, x1)), j;
        for (j = j0; j <= j1 && nb < cap; j++) {
            double s = (0.5 * (double)j - w[a]) / t->e[a];
            if (s > s0 && s < s1) brk[nb++] = s;
        }
    }
    if (cum) {
        long k0 = (long)ceil((s0 - t->rlo) * t->inv_hr), k1 = (long)floor((s1 - t->rlo) * t->inv_hr), kk;
        for (kk = k0 < 0 ? 0 : k0; kk <= k1 && kk < t->mr && nb < cap; kk++) {
            double s = t->rlo + (double)kk * t->hr;
            if (s > s0 && s < s1) brk[nb++] = s;
        }
    }
    qsort(brk, nb, sizeof *brk, cmp_double);
    for (i = 0; i + 1 < nb; i++) {
        double lo = brk[i], len = brk[i + 1] - lo;
        int parts, q, g;
        if (!(len > 0)) continue;
        if (cum) /* grid points at or before lo get the integral so far */
            while (nextk < t->mr && t->rlo + nextk * t->hr <= lo + 1e-12 * t->hr) {
                double val[8];
                unit_values(t, b, w, t->rlo + nextk * t->hr, val);
                for (band = 0; band < 8; band++) {
                    cum[((size_t)nextk * 8 + band) * 2] = acc[band];
                    cum[((size_t)nextk * 8 + band) * 2 + 1] = val[band];
                }
                nextk++;
            }
        parts = (int)ceil(len / SPLAT_SUB);
        for (q = 0; q < parts; q++) {
            double plen = len / parts, pl = lo + q * plen;
            for (g = 0; g < 3; g++) {
                double val[8], wt = gw[g] * plen;
                unit_values(t, b, w, pl + gx[g] * plen, val);
                for (band = 0; band < 8; band++) acc[band] += wt * val[band];
            }
        }
    }
    for (band = 0; band < 8; band++) tot[band] = acc[band];
    if (cum) /* past the cube: the whole integral, and nothing more to add */
        for (; nextk < t->mr; nextk++)
            for (band = 0; band < 8; band++) cum[((size_t)nextk * 8 + band) * 2] = acc[band];
}

/* Builds the tables for unit-space direction dir (any length). */
static wvol_status tables_build(splat_tables *t, const wvol_basis *b, const double dir[3], int threads,
                                wvol_error *err)
{
    double sup = b->support, scale = sup > 3 ? sup / 3 : 1, lo[3] = {INFINITY, INFINITY, INFINITY},
           hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int a, c, ok = 1;
    size_t n2d, n3d;
    memset(t, 0, sizeof *t);
    for (a = 0; a < 3; a++) t->e[a] = dir[a];
    unit3(t->e);
    /* e1: the axis least aligned with e, made normal to it; e2 = e x e1 */
    {
        int amin = 0;
        double ax[3] = {0, 0, 0}, pr;
        for (a = 1; a < 3; a++)
            if (fabs(t->e[a]) < fabs(t->e[amin])) amin = a;
        ax[amin] = 1;
        pr = dot3(ax, t->e);
        for (a = 0; a < 3; a++) t->e1[a] = ax[a] - pr * t->e[a];
        unit3(t->e1);
        cross3(t->e2, t->e, t->e1);
    }
    for (c = 0; c < 8; c++) {
        double p[3] = {(c & 1) ? sup : 0, (c & 2) ? sup : 0, (c & 4) ? sup : 0}, v[3];
        v[0] = dot3(p, t->e1), v[1] = dot3(p, t->e2), v[2] = dot3(p, t->e);
        for (a = 0; a < 3; a++) lo[a] = fmin(lo[a], v[a]), hi[a] = fmax(hi[a], v[a]);
    }
    t->h2 = SPLAT_H2 * scale;
    t->h3 = SPLAT_H3 * scale;
    t->inv_h2 = 1 / t->h2;
    t->inv_h3 = 1 / t->h3;
    t->hr = SPLAT_HR * scale;
    t->inv_hr = 1 / t->hr;
    /* one node of zeros beyond each side, so lookups next to the edge need no test */
    t->u1lo = lo[0] - t->h3;
    t->u2lo = lo[1] - t->h3;
    t->rlo = lo[2];
    t->rhi = hi[2];
    t->n1 = (int)ceil((hi[0] - t->u1lo) * t->inv_h2) + 3;
    t->n2 = (int)ceil((hi[1] - t->u2lo) * t->inv_h2) + 3;
    /* the 3D grid's nodes are every (h3/h2)-th node of the 2D grid (both come from the same lines) */
    t->m1 = (t->n1 - 1) / (int)lround(t->h3 / t->h2) + 1;
    t->m2 = (t->n2 - 1) / (int)lround(t->h3 / t->h2) + 1;
    t->mr = (int)ceil((t->rhi - t->rlo) * t->inv_hr) + 1;
    n2d = (size_t)t->n1 * (size_t)t->n2;
    n3d = (size_t)t->m1 * (size_t)t->m2 * (size_t)t->mr;
    t->T = calloc(8 * n2d, sizeof(float));
    t->G = calloc(16 * n3d, sizeof(float));
    if (!t->T || !t->G) {
        free(t->T), free(t->G);
        t->T = t->G = NULL;
        return wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the splat tables (%zu floats)",
                              8 * n2d + 16 * n3d);
    }
#pragma omp parallel num_threads(wvol__threads(threads))
    {
        size_t cap = (size_t)(6 * sup * 2 + 8) + (size_t)t->mr + 8;
        double *brk = malloc(cap * sizeof(double)), *cum = malloc((size_t)t->mr * 16 * sizeof(double));
        int ratio = (int)lround(t->h3 / t->h2), j;
        if (!brk || !cum) {
#pragma omp atomic write
            ok = 0;
        } else {
#pragma omp for schedule(dynamic, 4)
            for (j = 0; j < t->n2; j++) {
                int i, band, k;
                double u2 = t->u2lo + j * t->h2;
                for (i = 0; i < t->n1; i++) {
                    double u1 = t->u1lo + i * t->h2, w[3], tot[8];
                    int on3 = (i % ratio == 0) && (j % ratio == 0);
                    for (int q = 0; q < 3; q++) w[q] = u1 * t->e1[q] + u2 * t->e2[q];
                    line_integrals(t, b, w, tot, on3 ? cum : NULL, brk, cap);
                    for (band = 0; band < 8; band++) t->T[band * n2d + (size_t)j * t->n1 + i] = (float)tot[band];
                    if (on3) {
                        size_t base = (size_t)(j / ratio) * t->m1 + (size_t)(i / ratio);
                        for (band = 0; band < 8; band++)
                            for (k = 0; k < t->mr; k++) {
                                float *g = t->G + 2 * (band * n3d + (size_t)k * t->m1 * t->m2 + base);
                                g[0] = (float)cum[((size_t)k * 8 + band) * 2];
                                g[1] = (float)cum[((size_t)k * 8 + band) * 2 + 1];
                            }
                    }
                }
            }
        }
        free(brk);
        free(cum);
    }
    if (!ok) {
        free(t->T), free(t->G);
        t->T = t->G = NULL;
        return wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory building the splat tables");
    }
    return WVOL_OK;
}

/* Bilinear T(u1, u2) of one band (0 outside the grid). */
static inline double lookup2(const splat_tables *t, const float *T, double u1, double u2)
{
    double f1 = (u1 - t->u1lo) * t->inv_h2, f2 = (u2 - t->u2lo) * t->inv_h2;
    if (!(f1 >= 0 && f2 >= 0 && f1 < t->n1 - 1 && f2 < t->n2 - 1)) return 0;
    int i = (int)f1, j = (int)f2;
    double a = f1 - i, c = f2 - j;
    const float *p = T + (size_t)j * t->n1 + i;
    double r0 = p[0] + a * (p[1] - p[0]), r1 = p[t->n1] + a * (p[t->n1 + 1] - p[t->n1]);
    return r0 + c * (r1 - r0);
}

/* Bilinear in u of the (value, derivative) pair at node p of the 3D grid. */
static inline void pair2(const float *p, int m1, double a, double c, double out[2])
{
    for (int q = 0; q < 2; q++) {
        double r0 = p[q] + a * (p[2 + q] - p[q]), r1 = p[2 * m1 + q] + a * (p[2 * m1 + 2 + q] - p[2 * m1 + q]);
        out[q] = r0 + c * (r1 - r0);
    }
}

/* G(u, r): 0 before the cube, T beyond it, in between bilinear in u and cubic Hermite in r
 * (the integrand is G's derivative in r, so the r direction costs no accuracy). */
static inline double lookup3(const splat_tables *t, const float *T, const float *G, double u1, double u2, double r)
{
    if (!(r > t->rlo)) return 0;
    if (r >= t->rhi) return lookup2(t, T, u1, u2);
    double f1 = (u1 - t->u1lo) * t->inv_h3, f2 = (u2 - t->u2lo) * t->inv_h3, fr = (r - t->rlo) * t->inv_hr;
    if (!(f1 >= 0 && f2 >= 0 && f1 < t->m1 - 1 && f2 < t->m2 - 1)) return 0;
    int i = (int)f1, j = (int)f2, k = (int)fr;
    if (k > t->mr - 2) k = t->mr - 2;
    double a = f1 - i, c = f2 - j, g = fr - k, p[2], q[2], g2 = g * g, g3 = g2 * g;
    size_t sl = 2 * (size_t)t->m1 * t->m2;
    const float *base = G + (size_t)k * sl + 2 * ((size_t)j * t->m1 + i);
    pair2(base, t->m1, a, c, p);
    pair2(base + sl, t->m1, a, c, q);
    return (2 * g3 - 3 * g2 + 1) * p[0] + (g3 - 2 * g2 + g) * t->hr * p[1] + (3 * g2 - 2 * g3) * q[0] +
           (g3 - g2) * t->hr * q[1];
}

/* Solves the 3x3 system [c0 c1 c2] x = r (columns) by Cramer's rule; 0 when singular. */
static int solve3(const double c0[3], const double c1[3], const double c2[3], const double r[3], double x[3])
{
    double k[3], det;
    cross3(k, c1, c2);
    det = dot3(c0, k);
    if (!(fabs(det) > 0)) return 0;
    x[0] = dot3(r, k) / det;
    cross3(k, c2, c0);
    x[1] = dot3(r, k) / det;
    cross3(k, c0, c1);
    x[2] = dot3(r, k) / det;
    return 1;
}

typedef struct splat_view {
    double O0[3], Ex[3], Ey[3], D[3], len; /* voxel-space ray of pixel position (px, py): O0 + px Ex + py Ey + t D */
    double box_lo[3], box_hi[3];
    double *tin, *tout;                    /* per pixel; tin = NAN where the ray misses */
    int W, H;
} splat_view;

/* Adds one function image (level m, band, lower corner lo, weight value * norm) to acc. */
/* Adds one basis function's projection to the image rows y = phase (mod every) that it covers. */
static void splat_one(const splat_tables *t, const splat_view *v, const wvol_basis *b, double *acc, int m, int band,
                      const double lo[3], double weight, int phase, int every, size_t *pixels)
{
    double sc = ldexp(1.0, -m), sup = b->support * ldexp(1.0, m), X[3], y0[3], pmin[2] = {INFINITY, INFINITY},
           pmax[2] = {-INFINITY, -INFINITY}, base[3], dx[3], dy[3], pq[3];
    int a, c, inside = 1, x0, x1, y, yy0, yy1;
    const float *T = t->T + (size_t)band * t->n1 * t->n2;
    const float *G = t->G + 2 * (size_t)band * t->m1 * t->m2 * t->mr;
    double gain = weight * ldexp(1.0, m) / v->len, tscale = v->len * sc;
    for (a = 0; a < 3; a++)
        if (lo[a] < v->box_lo[a] || lo[a] + sup > v->box_hi[a]) inside = 0;
    /* the support's corners in pixel coordinates bound the pixels it can touch */
    for (c = 0; c < 8; c++) {
        double r[3];
        for (a = 0; a < 3; a++) X[a] = lo[a] + (((c >> a) & 1) ? sup : 0) - v->O0[a];
        if (!solve3(v->Ex, v->Ey, v->D, X, r)) return;
        pmin[0] = fmin(pmin[0], r[0]), pmax[0] = fmax(pmax[0], r[0]);
        pmin[1] = fmin(pmin[1], r[1]), pmax[1] = fmax(pmax[1], r[1]);
    }
    /* pixel x's centre is px = x + 1/2 */
    x0 = pmin[0] - 0.5 < 0 ? 0 : (int)ceil(pmin[0] - 0.5);
    x1 = pmax[0] - 0.5 >= v->W ? v->W - 1 : (int)floor(pmax[0] - 0.5);
    yy0 = pmin[1] - 0.5 < 0 ? 0 : (int)ceil(pmin[1] - 0.5);
    yy1 = pmax[1] - 0.5 >= v->H ? v->H - 1 : (int)floor(pmax[1] - 0.5);
    yy0 += ((phase - yy0) % every + every) % every; /* this caller's first row */
    if (x0 > x1 || yy0 > yy1) return;
    /* y0(px, py) = (O0 - lo)/2^m + px Ex/2^m + py Ey/2^m, in the table's frame (u1, u2, rho) */
    for (a = 0; a < 3; a++) y0[a] = (v->O0[a] - lo[a]) * sc;
    base[0] = dot3(y0, t->e1), base[1] = dot3(y0, t->e2), base[2] = dot3(y0, t->e);
    dx[0] = dot3(v->Ex, t->e1) * sc, dx[1] = dot3(v->Ex, t->e2) * sc, dx[2] = dot3(v->Ex, t->e) * sc;
    dy[0] = dot3(v->Ey, t->e1) * sc, dy[1] = dot3(v->Ey, t->e2) * sc, dy[2] = dot3(v->Ey, t->e) * sc;
    *pixels += (size_t)(x1 - x0 + 1) * (size_t)((yy1 - yy0) / every + 1);
    for (y = yy0; y <= yy1; y += every) {
        double py = y + 0.5;
        int x;
        for (a = 0; a < 3; a++) pq[a] = base[a] + py * dy[a] + (x0 + 0.5) * dx[a];
        double *row = acc + (size_t)y * v->W;
        if (inside) {
            for (x = x0; x <= x1; x++) {
                row[x] += gain * lookup2(t, T, pq[0], pq[1]);
                pq[0] += dx[0], pq[1] += dx[1];
            }
        } else {
            const double *tin = v->tin + (size_t)y * v->W, *tout = v->tout + (size_t)y * v->W;
            for (x = x0; x <= x1; x++) {
                if (tin[x] == tin[x]) {
                    double s0 = tin[x] * tscale + pq[2], s1 = tout[x] * tscale + pq[2];
                    row[x] += gain * (lookup3(t, T, G, pq[0], pq[1], s1) - lookup3(t, T, G, pq[0], pq[1], s0));
                }
                pq[0] += dx[0], pq[1] += dx[1], pq[2] += dx[2];
            }
        }
    }
}

wvol_status wvol_render_xray_splat(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                                   const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_store_info info;
    const wvol_basis *b;
    wvol__cam k;
    splat_tables t;
    splat_view v;
    wvol_store_coeff *cf = NULL;
    size_t ncf = 0, cap = 0, npx, P[3], rays_hit = 0, images = 0, pixels = 0, i;
    double t_start = wvol__now(), c_start = wvol__cpu_now(), o[3], dw[3], sft;
    double *acc = NULL;
    int a, nthreads;
    wvol_status st = WVOL_OK;

    wvol__params(&p, params);
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "render: no store");
    WVOL_RETURN_IF(p.mode != WVOL_RENDER_MODE_XRAY, err, WVOL_ERR_UNSUPPORTED,
                   "render: the splat fast path is X-ray only (absorption is not linear in the coefficients)");
    WVOL_FORWARD(wvol__render_check(img, cam, NULL, &p, err));
    WVOL_FORWARD(wvol__check_colors(&p, NULL, 0, err));
    WVOL_FORWARD(wvol__check_skip(&p, 0, err));
    WVOL_RETURN_IF(cam->projection != WVOL_PROJECTION_ORTHOGRAPHIC, err, WVOL_ERR_UNSUPPORTED,
                   "render: the splat fast path needs an orthographic camera (a perspective view has no shared "
                   "footprint)");
    wvol_store_get_info(s, &info);
    b = wvol_store_basis(s);
    WVOL_RETURN_IF(!b, err, WVOL_ERR_ARG, "render: the store has no basis tables");
    WVOL_RETURN_IF(!info.transformed[0] || !info.transformed[1] || !info.transformed[2], err, WVOL_ERR_UNSUPPORTED,
                   "render: the splat fast path needs all three axes transformed (extent > 1)");
    WVOL_RETURN_IF(b->support > SPLAT_MAX_SUPPORT, err, WVOL_ERR_UNSUPPORTED,
                   "render: the splat fast path takes filters of up to %d taps (%s has %d: its footprint tables "
                   "would span the volume)",
                   SPLAT_MAX_SUPPORT + 1, info.filter->name, b->length);
    P[0] = info.px, P[1] = info.py, P[2] = info.pz;
    sft = b->center;

    /* the view in voxel space: pixel position (px, py) has the ray O0 + px Ex + py Ey + t D */
    memset(&v, 0, sizeof v);
    v.W = img->width, v.H = img->height;
    wvol__cam_init(&k, cam);
    {
        double o1[3], o2[3], w1[3], w2[3];
        wvol__cam_ray(&k, 0, 0, o, dw);
        wvol__cam_ray(&k, 1, 0, o1, dw);
        wvol__cam_ray(&k, 0, 1, o2, dw);
        wvol_store_world_to_voxel(s, o, v.O0);
        wvol_store_world_to_voxel(s, o1, w1);
        wvol_store_world_to_voxel(s, o2, w2);
        wvol_store_dir_to_voxel(s, dw, v.D);
        for (a = 0; a < 3; a++) v.Ex[a] = w1[a] - v.O0[a], v.Ey[a] = w2[a] - v.O0[a];
        v.len = sqrt(dot3(v.D, v.D));
        for (a = 0; a < 3; a++) v.box_lo[a] = -0.5, v.box_hi[a] = (double)(a == 0 ? info.nx : a == 1 ? info.ny : info.nz) - 0.5;
    }
    WVOL_FORWARD(tables_build(&t, b, v.D, p.threads, err));

    npx = (size_t)v.W * (size_t)v.H;
    v.tin = malloc(npx * sizeof(double));
    v.tout = malloc(npx * sizeof(double));
    if (!v.tin || !v.tout) goto nomem;
    for (i = 0; i < npx; i++) {
        double px = (double)(i % (size_t)v.W) + 0.5, py = (double)(i / (size_t)v.W) + 0.5, oo[3], t0, t1;
        for (a = 0; a < 3; a++) oo[a] = v.O0[a] + px * v.Ex[a] + py * v.Ey[a];
        if (wvol__ray_box(oo, v.D, v.box_lo, v.box_hi, &t0, &t1)) v.tin[i] = t0, v.tout[i] = t1, rays_hit++;
        else v.tin[i] = v.tout[i] = NAN;
    }

    /* the kept coefficients, so the threads can share them out */
    {
        wvol_store_iter it;
        wvol_store_coeff c;
        memset(&it, 0, sizeof it);
        cap = info.kept ? info.kept : 1;
        cf = malloc(cap * sizeof *cf);
        if (!cf) goto nomem;
        while (wvol_store_next(s, &it, &c) && ncf < cap) cf[ncf++] = c;
    }

    /* Each thread owns the image rows y = its number (mod the threads) and adds every function's
     * part in them, in the coefficients' order: a pixel's sum is the same additions in the same
     * order for any thread count and run (docs/cli.md: images the same for any count). The
     * footprints are found by every thread; the pixels' work is split. */
    nthreads = wvol__threads(p.threads);
    if (nthreads > v.H) nthreads = v.H;
    acc = calloc(npx, sizeof(double));
    if (!acc) goto nomem;
#pragma omp parallel num_threads(nthreads) reduction(+ : images, pixels)
    {
        const int me = omp_get_thread_num(), every = omp_get_num_threads();
        long n;
        for (n = 0; n < (long)ncf; n++) {
            const wvol_store_coeff *c = &cf[n];
            int m = c->level;
            double step = ldexp(1.0, m), sup = b->support * step, norm = pow(2.0, -1.5 * m), lo[3];
            long jlo[3], jhi[3], E[3], pos[3] = {(long)c->p, (long)c->q, (long)c->r}, j0, j1, j2;
            /* the periodic images j = pos + k E whose support [j 2^m - s, j 2^m - s + sup] meets the box */
            for (int q = 0; q < 3; q++) {
                E[q] = (long)(P[q] >> m);
                jlo[q] = (long)ceil((v.box_lo[q] + sft - sup) / step);
                jhi[q] = (long)floor((v.box_hi[q] + sft) / step);
                /* first j >= jlo with j = pos mod E */
                long r = ((jlo[q] - pos[q]) % E[q] + E[q]) % E[q];
                jlo[q] += r ? E[q] - r : 0;
            }
            for (j2 = jlo[2]; j2 <= jhi[2]; j2 += E[2])
                for (j1 = jlo[1]; j1 <= jhi[1]; j1 += E[1])
                    for (j0 = jlo[0]; j0 <= jhi[0]; j0 += E[0]) {
                        lo[0] = (double)j0 * step - sft;
                        lo[1] = (double)j1 * step - sft;
                        lo[2] = (double)j2 * step - sft;
                        images += me == 0;
                        splat_one(&t, &v, b, acc, m, c->band, lo, (double)c->value * norm, me, every, &pixels);
                    }
        }
    }
    /* X-ray pixels are (I, I, I, 1) where the ray meets the box */
    for (i = 0; i < npx; i++) {
        const double sum = acc[i];
        float *px = img->rgba + 4 * i;
        if (v.tin[i] == v.tin[i]) px[0] = px[1] = px[2] = (float)sum, px[3] = 1.0f;
        else px[0] = px[1] = px[2] = px[3] = 0.0f;
    }
    {
        wvol__counts c = {.rays_hit = rays_hit, .functions = images, .samples = pixels,
                          .bytes = 4 * 8 * ((size_t)t.n1 * t.n2 + 2 * (size_t)t.m1 * t.m2 * t.mr) +
                                   npx * sizeof(double) + 2 * npx * sizeof(double) +
                                   cap * sizeof *cf};
        wvol__stats_fill(stats, img, t_start, c_start, &c);
    }
    st = wvol__image_check_range(img, err);
    goto done;
nomem:
    st = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the splat (%zu pixels, %zu coefficients)", npx,
                        info.kept);
done:
    free(t.T);
    free(t.G);
    free(v.tin);
    free(v.tout);
    free(cf);
    free(acc);
    return st;
}
