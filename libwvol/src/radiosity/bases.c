/* SPDX-License-Identifier: MIT
 * Tree-wavelet bases on the unit cell: Legendre scaling functions (Alpert's multiwavelets M1-M4; M1
 * is Haar) and flatlets F2, F3 (m boxes), their two-scale (push) matrices, the kernel sample rules,
 * the oracle's residual projector and the one-node wavelet step with its dual.
 * Based on: Alpert 1993 (multiwavelets); Gortler et al. 1993 sections 6-7 (flatlets, eq. 9). */
#include <math.h>
#include <string.h>

#include "core/quadrature.h"
#include "radiosity_internal.h"

static const char *const names[] = {"haar", "m2", "m3", "m4", "f2", "f3"};

wvol_status wvol_radiosity_basis_parse(const char *name, wvol_radiosity_basis *out, wvol_error *err)
{
    WVOL_RETURN_IF(!name || !out, err, WVOL_ERR_ARG, "radiosity basis: NULL argument");
    if (!strcmp(name, "m1")) name = "haar";
    for (int i = 0; i < 6; i++)
        if (!strcmp(name, names[i])) {
            *out = (wvol_radiosity_basis)i;
            return WVOL_OK;
        }
    return wvol_error_set(err, WVOL_ERR_ARG, "radiosity basis: unknown '%s' (haar, m2, m3, m4, f2, f3)", name);
}

const char *wvol_radiosity_basis_name(wvol_radiosity_basis b)
{
    return (unsigned)b < 6 ? names[b] : "unknown";
}

static int basis_m(wvol_radiosity_basis b)
{
    switch (b) {
    case WVOL_RADIOSITY_BASIS_M2: case WVOL_RADIOSITY_BASIS_F2: return 2;
    case WVOL_RADIOSITY_BASIS_M3: case WVOL_RADIOSITY_BASIS_F3: return 3;
    case WVOL_RADIOSITY_BASIS_M4: return 4;
    default: return 1;
    }
}

int wvol_radiosity_basis_size(wvol_radiosity_basis b) { return basis_m(b) * basis_m(b); }

/* Legendre P_a(2x - 1) * sqrt(2a + 1): orthonormal on [0, 1]. */
static double legendre(int a, double x)
{
    double t = 2 * x - 1, p0 = 1, p1 = t, p2;
    if (a == 0) return 1;
    for (int k = 2; k <= a; k++) {
        p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
        p0 = p1, p1 = p2;
    }
    return p1 * sqrt(2.0 * a + 1);
}

double wvol__rad_phi(const rad_basis *b, int a, double x)
{
    if (!b->flat) return legendre(a, x);
    return (x >= (double)a / b->m && (x < (double)(a + 1) / b->m || (a == b->m - 1 && x <= 1))) ? sqrt((double)b->m)
                                                                                                : 0;
}

/* Integral over [0, 1] of f by a composite rule exact for the piecewise polynomials at hand:
 * 12 pieces (boundaries of every box of m <= 3 at both scales) with 6 Gauss points each. */
typedef double (*fn1)(const rad_basis *b, const void *ctx, double x);

static double integrate(const rad_basis *b, const void *ctx, fn1 f)
{
    double x[6], w[6], s = 0;
    wvol__gauss_legendre(6, x, w);
    for (int piece = 0; piece < 12; piece++)
        for (int k = 0; k < 6; k++) s += w[k] / 12 * f(b, ctx, (piece + x[k]) / 12);
    return s;
}

typedef struct push_ctx { int c, a, bb; } push_ctx;

static double push_integrand(const rad_basis *b, const void *ctx, double x)
{
    const push_ctx *pc = ctx;
    /* child c's function a at parent coordinate x: sqrt2 phi_a(2x - c) on its half */
    double xc = 2 * x - pc->c;
    if (xc < 0 || xc > 1) return 0;
    return sqrt(2.0) * wvol__rad_phi(b, pc->a, xc) * wvol__rad_phi(b, pc->bb, x);
}

static double mean_integrand(const rad_basis *b, const void *ctx, double x)
{
    return wvol__rad_phi(b, *(const int *)ctx, x);
}

/* Solves the m x m system a y = r in place (Gaussian elimination with partial pivoting). */
static void solve_small(int m, double *a, double *r, int nrhs)
{
    for (int col = 0; col < m; col++) {
        int piv = col;
        for (int i = col + 1; i < m; i++)
            if (fabs(a[i * m + col]) > fabs(a[piv * m + col])) piv = i;
        if (piv != col) {
            for (int k = 0; k < m; k++) {
                double t = a[col * m + k];
                a[col * m + k] = a[piv * m + k], a[piv * m + k] = t;
            }
            for (int k = 0; k < nrhs; k++) {
                double t = r[col * nrhs + k];
                r[col * nrhs + k] = r[piv * nrhs + k], r[piv * nrhs + k] = t;
            }
        }
        for (int i = 0; i < m; i++) {
            double f;
            if (i == col) continue;
            f = a[i * m + col] / a[col * m + col];
            for (int k = 0; k < m; k++) a[i * m + k] -= f * a[col * m + k];
            for (int k = 0; k < nrhs; k++) r[i * nrhs + k] -= f * r[col * nrhs + k];
        }
    }
    for (int i = 0; i < m; i++)
        for (int k = 0; k < nrhs; k++) r[i * nrhs + k] /= a[i * m + i];
}

void wvol__rad_basis_init(rad_basis *b, wvol_radiosity_basis kind)
{
    double gx[RAD_MAXNQ], gw[RAD_MAXNQ], vtwv[RAD_MAXM * RAD_MAXM], proj[RAD_MAXM * RAD_MAXNQ];
    int i, k, a, c;
    memset(b, 0, sizeof *b);
    b->kind = kind;
    b->m = basis_m(kind);
    b->nb = b->m * b->m;
    b->flat = kind == WVOL_RADIOSITY_BASIS_F2 || kind == WVOL_RADIOSITY_BASIS_F3;
    if (b->flat) {
        /* the paper's rule: two Gauss points on each constant piece */
        wvol__gauss_legendre(2, gx, gw);
        b->nq = 2 * b->m;
        for (a = 0; a < b->m; a++)
            for (k = 0; k < 2; k++) b->qx[2 * a + k] = (a + gx[k]) / b->m, b->qw[2 * a + k] = gw[k] / b->m;
    } else {
        /* M + 1 points: exact Galerkin for kernels of degree <= 2 per direction more than the basis, and the
         * oracle can see the degree-M part of the kernel (Haar: 2 points, as the paper always uses) */
        b->nq = b->m + 1;
        wvol__gauss_legendre(b->nq, b->qx, b->qw);
    }
    for (a = 0; a < b->m; a++) {
        for (k = 0; k < b->nq; k++) b->phi[a][k] = wvol__rad_phi(b, a, b->qx[k]);
        b->mean[a] = integrate(b, &a, mean_integrand);
    }
    for (c = 0; c < 2; c++)
        for (a = 0; a < b->m; a++)
            for (k = 0; k < b->m; k++) {
                push_ctx pc = {c, a, k};
                b->push[c][a][k] = integrate(b, &pc, push_integrand);
            }
    /* residual operator I - V (V^T W V)^-1 V^T W over the nq sample points, V_ka = P_a(x_k), a < M */
    for (a = 0; a < b->m; a++)
        for (i = 0; i < b->m; i++) {
            double s = 0;
            for (k = 0; k < b->nq; k++) s += legendre(a, b->qx[k]) * b->qw[k] * legendre(i, b->qx[k]);
            vtwv[a * b->m + i] = s;
        }
    for (a = 0; a < b->m; a++)
        for (k = 0; k < b->nq; k++) proj[a * b->nq + k] = legendre(a, b->qx[k]) * b->qw[k];
    solve_small(b->m, vtwv, proj, b->nq); /* proj = (V^T W V)^-1 V^T W */
    for (i = 0; i < b->nq; i++)
        for (k = 0; k < b->nq; k++) {
            double s = 0;
            for (a = 0; a < b->m; a++) s += legendre(a, b->qx[i]) * proj[a * b->nq + k];
            b->resid[i][k] = (i == k) - s;
        }
}

/* Flatlet details: rows over the 2m child boxes orthogonal to the polynomials of degree < m and to
 * each other's lower moments (for F2 the paper's eq. 9 rows [-1 3 -3 1], [1 -1 -1 1] up to scale). */
static void flatlet_details(int m, double *rows)
{
    int n = 2 * m, r, k, j;
    for (r = 0; r < m; r++) {
        /* start from the monomial x^(m + r) sampled at box centres, remove degree < m + r by Gram-Schmidt
         * against 1, x, ..., x^(m + r - 1) in the discrete inner product */
        double basis[8][6];
        for (j = 0; j <= m + r; j++)
            for (k = 0; k < n; k++) basis[j][k] = pow(k + 0.5, j);
        for (j = 0; j <= m + r; j++) {
            for (int i = 0; i < j; i++) {
                double d = 0, nn = 0;
                for (k = 0; k < n; k++) d += basis[j][k] * basis[i][k], nn += basis[i][k] * basis[i][k];
                for (k = 0; k < n; k++) basis[j][k] -= d / nn * basis[i][k];
            }
        }
        for (k = 0; k < n; k++) rows[r * n + k] = basis[m + r][k];
    }
}

void wvol__rad_basis_wavelet(const rad_basis *b, double *t, double *tinv)
{
    int m = b->m, n = 2 * m, i, k, c, a;
    double work[64], rhs[64];
    memset(t, 0, sizeof(double) * n * n);
    /* smooth rows: parent coefficient a from the children = push^T (orthonormal scaling functions) */
    for (a = 0; a < m; a++)
        for (c = 0; c < 2; c++)
            for (k = 0; k < m; k++) t[a * n + c * m + k] = b->push[c][k][a];
    if (b->flat) {
        flatlet_details(m, t + m * n);
        /* in child coefficients of boxes of width 1/(2m) ordered left to right: child c box k */
    } else {
        /* Alpert: complete the smooth rows to an orthonormal basis of R^n by Gram-Schmidt on unit vectors */
        int row = m;
        for (int e = 0; e < n && row < n; e++) {
            double v[8] = {0};
            double nn = 0;
            v[e] = 1;
            for (i = 0; i < row; i++) {
                double d = 0;
                for (k = 0; k < n; k++) d += v[k] * t[i * n + k];
                for (k = 0; k < n; k++) v[k] -= d * t[i * n + k];
            }
            for (k = 0; k < n; k++) nn += v[k] * v[k];
            if (nn < 1e-8) continue;
            for (k = 0; k < n; k++) t[row * n + k] = v[k] / sqrt(nn);
            row++;
        }
    }
    memcpy(work, t, sizeof(double) * n * n);
    for (i = 0; i < n; i++)
        for (k = 0; k < n; k++) rhs[i * n + k] = i == k;
    solve_small(n, work, rhs, n);
    memcpy(tinv, rhs, sizeof(double) * n * n);
}
