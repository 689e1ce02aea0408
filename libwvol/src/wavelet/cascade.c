/* SPDX-License-Identifier: MIT */
/* Cascade algorithm: phi and psi of an orthonormal QMF filter at dyadic points.
 * Integer values from the eigenvector of the two-scale matrix, then the two-scale
 * relation level by level, so every dyadic value is exact up to rounding.
 * Based on: Daubechies, Ten Lectures on Wavelets (1992), section 6.5;
 * Strang & Nguyen, Wavelets and Filter Banks (1996), section 6.2. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wavelet/basis_internal.h"

int wvol__filter_is_haar(const wvol_filter *f)
{
    return f->length == 2;
}

/* phi(1..L-2): (A - I) v = 0 with A[k][j] = sqrt(2) h[2k - j], k, j = 1..L-2
 * (phi(0) = phi(L-1) = 0 for every continuous phi). The all-ones row vector is a
 * left eigenvector of A for eigenvalue 1 (the sum rules sum_n h[2n] = sum_n
 * h[2n+1] = 1/sqrt 2), so the rows of A - I are dependent through it and any one
 * row can be replaced by the normalisation sum_k phi(k) = 1 (partition of unity).
 * Gaussian elimination with partial pivoting on the (L-2)^2 system. */
static wvol_status integer_values(double *v, const wvol_filter *f, wvol_error *err)
{
    int L = f->length, n = L - 2, i, j, k, piv;
    double *a, t, best;
    if (n <= 0) return wvol_error_set(err, WVOL_ERR_ARG, "cascade: filter '%s' too short", f->name);
    a = malloc((size_t)n * (size_t)(n + 1) * sizeof *a);
    if (!a) return wvol_error_set(err, WVOL_ERR_NOMEM, "cascade: out of memory (%d taps)", L);
#define A(r, c) a[(size_t)(r) * (size_t)(n + 1) + (size_t)(c)]
    for (k = 0; k < n; k++) {
        for (j = 0; j < n; j++) {
            int idx = 2 * (k + 1) - (j + 1);
            A(k, j) = (idx >= 0 && idx < L ? M_SQRT2 * f->h[idx] : 0.0) - (k == j ? 1.0 : 0.0);
        }
        A(k, n) = 0.0;
    }
    for (j = 0; j < n; j++) A(n - 1, j) = 1.0;
    A(n - 1, n) = 1.0;
    for (k = 0; k < n; k++) {
        piv = k;
        best = fabs(A(k, k));
        for (i = k + 1; i < n; i++)
            if (fabs(A(i, k)) > best) best = fabs(A(i, k)), piv = i;
        if (!(best > 1e-300)) {
            free(a);
            return wvol_error_set(err, WVOL_ERR_INTERNAL,
                                  "cascade: two-scale matrix of '%s' is singular (eigenvalue 1 not simple)",
                                  f->name);
        }
        if (piv != k)
            for (j = k; j <= n; j++) t = A(k, j), A(k, j) = A(piv, j), A(piv, j) = t;
        for (i = k + 1; i < n; i++) {
            t = A(i, k) / A(k, k);
            if (t != 0.0)
                for (j = k; j <= n; j++) A(i, j) -= t * A(k, j);
        }
    }
    for (k = n - 1; k >= 0; k--) {
        t = A(k, n);
        for (j = k + 1; j < n; j++) t -= A(k, j) * v[j + 1];
        v[k + 1] = t / A(k, k);
    }
#undef A
    v[0] = 0.0;
    v[L - 1] = 0.0;
    free(a);
    return WVOL_OK;
}

wvol_status wvol__cascade_phi(double *out, const wvol_filter *f, int J, wvol_error *err)
{
    int L = f->length, j, n;
    size_t N, step, i;
    if (J < 0 || J > 24) return wvol_error_set(err, WVOL_ERR_ARG, "cascade: J = %d outside 0..24", J);
    N = (size_t)(L - 1) << J;
    if (wvol__filter_is_haar(f)) {
        for (i = 0; i < N; i++) out[i] = 1.0;
        out[N] = 0.0;
        return WVOL_OK;
    }
    memset(out, 0, (N + 1) * sizeof *out);
    {
        double *v = malloc((size_t)L * sizeof *v);
        wvol_status s;
        if (!v) return wvol_error_set(err, WVOL_ERR_NOMEM, "cascade: out of memory");
        s = integer_values(v, f, err);
        if (s == WVOL_OK)
            for (j = 0; j < L; j++) out[(size_t)j << J] = v[j];
        free(v);
        if (s != WVOL_OK) return s;
    }
    /* Level lev: new points are the odd multiples of 2^-lev, at stride `step` in
     * out; phi(2x - n) lies on level lev-1, at out[(i*2 - n*2^J)...] in units of
     * the finest grid: x = i/2^J -> 2x - n = (2i - n 2^J)/2^J. */
    for (j = 1; j <= J; j++) {
        step = (size_t)1 << (J - j);
        for (i = step; i < N; i += 2 * step) {
            double acc = 0.0;
            long long twoi = 2 * (long long)i, off;
            for (n = 0; n < L; n++) {
                off = twoi - ((long long)n << J);
                if (off <= 0) break;      /* 2x - n <= 0: phi is 0 there, and for larger n too */
                if (off < (long long)N) acc += f->h[n] * out[off];
            }
            out[i] = M_SQRT2 * acc;
        }
    }
    return WVOL_OK;
}

void wvol__cascade_psi_from_phi(double *psi, const double *phi, const wvol_filter *f, int J)
{
    int L = f->length, n;
    size_t N = (size_t)(L - 1) << J, i;
    if (wvol__filter_is_haar(f)) {
        /* right-continuous Haar wavelet, exact */
        size_t half = N / 2;
        for (i = 0; i < N; i++) psi[i] = i < half ? 1.0 : -1.0;
        psi[N] = 0.0;
        if (J == 0) psi[0] = 1.0; /* only x = 0 and x = 1 are on the grid */
        return;
    }
    for (i = 0; i <= N; i++) {
        double acc = 0.0;
        long long twoi = 2 * (long long)i, off;
        for (n = 0; n < L; n++) {
            off = twoi - ((long long)n << J);
            if (off <= 0) break;
            if (off < (long long)N) acc += f->g[n] * phi[off];
        }
        psi[i] = M_SQRT2 * acc;
    }
}

wvol_status wvol_cascade(double *out, const wvol_filter *f, int which, int J, wvol_error *err)
{
    size_t N;
    double *phi;
    wvol_status s;
    WVOL_RETURN_IF(!out || !f, err, WVOL_ERR_ARG, "cascade: NULL argument");
    WVOL_RETURN_IF(which != 0 && which != 1, err, WVOL_ERR_ARG, "cascade: which = %d (0 phi, 1 psi)", which);
    WVOL_RETURN_IF(J < 0 || J > 20, err, WVOL_ERR_ARG, "cascade: J = %d outside 0..20", J);
    WVOL_RETURN_IF(f->length < 2 || f->length > (1 << 20), err, WVOL_ERR_ARG, "cascade: filter length %d",
                   f->length);
    if (which == 0) return wvol__cascade_phi(out, f, J, err);
    N = (size_t)(f->length - 1) << J;
    phi = malloc((N + 1) * sizeof *phi);
    WVOL_RETURN_IF(!phi, err, WVOL_ERR_NOMEM, "cascade: out of memory for %zu values", N + 1);
    s = wvol__cascade_phi(phi, f, J, err);
    if (s == WVOL_OK) wvol__cascade_psi_from_phi(out, phi, f, J);
    free(phi);
    return s;
}
