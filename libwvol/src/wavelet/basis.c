/* SPDX-License-Identifier: MIT */
/* Basis-function tables per family and J: phi and psi as cubic splines (periodic
 * end conditions on the support, see spline.c) through the cascade values, their
 * derivatives and primitives, the checks of DESIGN.md section 7 and the bounds the
 * store and the iso tracer need. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wavelet/basis_internal.h"

/* Relative and absolute slack added to every bound computed from the tables, so
 * that rounding in an evaluation can never exceed it. */
#define BOUND_SLACK(v) ((v) * (1.0 + 1e-12) + 1e-300)

static double horner3(const double *c, double u)
{
    return c[0] + u * (c[1] + u * (c[2] + u * c[3]));
}

static void fill_haar(wvol_basis *b)
{
    int i;
    /* J = 1: two pieces of width 1/2 on [0, 1) */
    for (i = 0; i < 2; i++) {
        double *p = b->phi + 4 * i, *q = b->psi + 4 * i;
        p[0] = 1.0, p[1] = p[2] = p[3] = 0.0;
        q[0] = i == 0 ? 1.0 : -1.0, q[1] = q[2] = q[3] = 0.0;
    }
}

/* Pieces scaled to the unit interval: pt[4i + a] = p_a h^a, and for the second
 * factor qt[4i + a] = sum_b q_b h^b / (a + b + 1), so that the integral over a
 * piece of p(u) q(u) is h * dot(pt_i, qt_j): 4 products per pair of pieces. */
static void scale_pieces(double *pt, double *qt, const double *c, int P, double h)
{
    int i, a, k;
    for (i = 0; i < P; i++) {
        double t[4], hp = 1.0;
        for (a = 0; a < 4; a++, hp *= h) t[a] = c[4 * (size_t)i + a] * hp;
        if (pt)
            for (a = 0; a < 4; a++) pt[4 * (size_t)i + a] = t[a];
        if (qt)
            for (a = 0; a < 4; a++) {
                double s = 0.0;
                for (k = 0; k < 4; k++) s += t[k] / (double)(a + k + 1);
                qt[4 * (size_t)i + a] = s;
            }
    }
}

/* max_k |<a(. - k), c> - delta_k| (delta only when asked) over k = kmin..kmax,
 * by exact integration of the products of the aligned cubic pieces; at is a's
 * scaled table, ct c's integrated one (scale_pieces). */
static double gram_error(const wvol_basis *b, const double *at, const double *ct, int kmin, int kmax, int delta)
{
    int k, i, i0, i1, P = b->pieces;
    double worst = 0.0;
    for (k = kmin; k <= kmax; k++) {
        long shift = (long)k * b->per_unit;   /* a(x - k) on piece i is a's piece i - shift */
        double s = 0.0;
        i0 = shift > 0 ? (int)shift : 0;
        i1 = shift < 0 ? P + (int)shift : P;
        for (i = i0; i < i1; i++) {
            const double *p = at + 4 * (i - shift), *q = ct + 4 * (size_t)i;
            s += p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3];
        }
        s *= b->h;
        if (delta && k == 0) s -= 1.0;
        if (fabs(s) > worst) worst = fabs(s);
    }
    return worst;
}

/* The tables' rigorous bounds (vmax, dmax, abs_integral, end_slope). */
static void compute_bounds(wvol_basis *b)
{
    int w, i, P = b->pieces;
    for (w = 0; w < 2; w++) {
        const double *tab = w ? b->psi : b->phi, *der = w ? b->dpsi : b->dphi;
        double vm = 0.0, dm = 0.0, ai = 0.0, t;
        for (i = 0; i < P; i++) {
            t = wvol__cubic_absmax(tab + 4 * (size_t)i, b->h);
            if (t > vm) vm = t;
            t = wvol__cubic_absmax(der + 4 * (size_t)i, b->h);
            if (t > dm) dm = t;
            ai += wvol__cubic_absint(tab + 4 * (size_t)i, b->h);
        }
        b->vmax[w] = BOUND_SLACK(vm);
        b->dmax[w] = BOUND_SLACK(dm);
        b->abs_integral[w] = BOUND_SLACK(ai);
        b->end_slope[w] = fabs(tab[1]);
    }
}

/* scaled: scratch of 16 doubles per piece */
static void compute_checks(wvol_basis *b, const double *phic, const double *psic, int Jc, double *scaled)
{
    int i, w, P = b->pieces, L = b->length;
    size_t n, Nc = (size_t)(L - 1) << Jc;
    int sub = Jc - b->J;
    double step = ldexp(1.0, -Jc), err[2] = {0.0, 0.0}, cs = 0.0;

    /* integrals: the primitive's value at the end of the support */
    {
        const double *q = b->phi_int + 5 * (size_t)(P - 1), *r = b->psi_int + 5 * (size_t)(P - 1);
        double hh = b->h;
        b->phi_integral = q[0] + hh * (q[1] + hh * (q[2] + hh * (q[3] + hh * q[4])));
        b->psi_integral = r[0] + hh * (r[1] + hh * (r[2] + hh * (r[3] + hh * r[4])));
    }
    /* centre of mass of the spline: sum_i integral_0^h (x_i + u) S_i(u) du */
    for (i = 0; i < P; i++) {
        const double *c = b->phi + 4 * (size_t)i;
        double hh = b->h, x0 = i * hh;
        double I0 = hh * (c[0] + hh * (c[1] / 2 + hh * (c[2] / 3 + hh * c[3] / 4)));
        double I1 = hh * hh * (c[0] / 2 + hh * (c[1] / 3 + hh * (c[2] / 4 + hh * c[3] / 5)));
        cs += x0 * I0 + I1;
    }
    b->center_spline = cs;
    /* spline against the cascade at J + 2 (3 of 4 points are between knots) */
    for (w = 0; w < 2; w++) {
        const double *tab = w ? b->psi : b->phi, *ref = w ? psic : phic;
        for (n = 0; n < Nc; n++) {
            size_t piece = n >> sub;
            double u = (double)(n - (piece << sub)) * step;
            double d = fabs(horner3(tab + 4 * piece, u) - ref[n]);
            if (d > err[w]) err[w] = d;
        }
        if (fabs(ref[Nc]) > err[w]) err[w] = fabs(ref[Nc]); /* x = support: the model is 0 */
    }
    b->spline_error_phi = err[0];
    b->spline_error_psi = err[1];
    b->spline_error = err[0] > err[1] ? err[0] : err[1];
    /* orthonormality of the spline model */
    {
        double *pt = scaled, *pq = pt + 4 * (size_t)P, *st = pq + 4 * (size_t)P, *sq = st + 4 * (size_t)P;
        double e1, e2;
        scale_pieces(pt, pq, b->phi, P, b->h);
        scale_pieces(st, sq, b->psi, P, b->h);
        b->ortho_error = gram_error(b, pt, pq, 0, L - 2, 1);
        e1 = gram_error(b, st, sq, 0, L - 2, 1);
        e2 = gram_error(b, pt, sq, -(L - 2), L - 2, 0);
        b->ortho_error_psi = e1 > e2 ? e1 : e2;
    }
    compute_bounds(b);
}

wvol_status wvol_basis_create(wvol_basis **out, const wvol_filter *f, int J, wvol_error *err)
{
    wvol_basis *b;
    double *block, *phic = NULL, *psic = NULL;
    size_t P, N, Nc;
    int L, Jc, n, haar;
    wvol_status s = WVOL_OK;

    WVOL_RETURN_IF(!out || !f, err, WVOL_ERR_ARG, "basis: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(J < WVOL_BASIS_J_MIN || J > WVOL_BASIS_J_MAX, err, WVOL_ERR_ARG,
                   "basis: J = %d outside %d..%d", J, WVOL_BASIS_J_MIN, WVOL_BASIS_J_MAX);
    L = f->length;
    WVOL_RETURN_IF(!f->h || !f->g || L < 2 || L > WVOL_BASIS_MAX_LENGTH, err, WVOL_ERR_ARG,
                   "basis: filter '%s' has %d taps (2..%d supported)", f->name, L, WVOL_BASIS_MAX_LENGTH);
    haar = wvol__filter_is_haar(f);
    if (haar) J = 1;
    b = calloc(1, sizeof *b);
    WVOL_RETURN_IF(!b, err, WVOL_ERR_NOMEM, "basis: out of memory");
    b->filter = f;
    b->J = J;
    b->exact = haar;
    b->degree = haar ? 0 : 3;
    b->length = L;
    b->per_unit = 1 << J;
    b->pieces = (L - 1) << J;
    b->h = ldexp(1.0, -J);
    b->inv_h = ldexp(1.0, J);
    b->support = (double)(L - 1);
    {
        double m1 = 0.0;
        for (n = 0; n < L; n++) m1 += n * f->h[n];
        b->center = m1 / M_SQRT2;
    }
    P = (size_t)b->pieces;
    block = malloc(P * (4 + 4 + 4 + 4 + 5 + 5) * sizeof *block);
    if (!block) {
        free(b);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "basis: out of memory for %zu pieces", P);
    }
    b->phi = block;
    b->psi = b->phi + 4 * P;
    b->dphi = b->psi + 4 * P;
    b->dpsi = b->dphi + 4 * P;
    b->phi_int = b->dpsi + 4 * P;
    b->psi_int = b->phi_int + 5 * P;

    Jc = J + 2;
    N = P;
    Nc = (size_t)(L - 1) << Jc;
    phic = malloc(2 * (Nc + 1) * sizeof *phic);
    if (!phic) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "basis: out of memory for the cascade (%zu values)", Nc + 1);
        goto fail;
    }
    psic = phic + (Nc + 1);
    if ((s = wvol__cascade_phi(phic, f, Jc, err)) != WVOL_OK) goto fail;
    wvol__cascade_psi_from_phi(psic, phic, f, Jc);

    if (haar) {
        fill_haar(b);
    } else {
        double *y = malloc((N + 1) * sizeof *y);
        size_t i;
        if (!y) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "basis: out of memory");
            goto fail;
        }
        for (i = 0; i <= N; i++) y[i] = phic[i << 2];
        s = wvol__spline_periodic(b->phi, y, N, b->h, err);
        for (i = 0; s == WVOL_OK && i <= N; i++) y[i] = psic[i << 2];
        if (s == WVOL_OK) s = wvol__spline_periodic(b->psi, y, N, b->h, err);
        free(y);
        if (s != WVOL_OK) goto fail;
    }
    wvol__spline_deriv(b->dphi, b->phi, N);
    wvol__spline_deriv(b->dpsi, b->psi, N);
    wvol__spline_primitive(b->phi_int, b->phi, N, b->h);
    wvol__spline_primitive(b->psi_int, b->psi, N, b->h);
    {
        /* 16 doubles per piece: phi and psi scaled and integrated (scale_pieces) */
        double *scratch = malloc(16 * P * sizeof *scratch);
        if (!scratch) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "basis: out of memory for the checks");
            goto fail;
        }
        compute_checks(b, phic, psic, Jc, scratch);
        free(scratch);
    }
    free(phic);
    *out = b;
    return WVOL_OK;
fail:
    free(phic);
    free(block);
    free(b);
    return s;
}

/* Piece by piece, the cubic whose Bernstein coefficients on the piece are the absolute values
 * of the spline's: it is >= |spline| on the piece (|p| <= sum |b_i| B_i, the B_i >= 0), equal
 * to |spline| where the piece keeps one sign, and continuous (the end coefficients are the end
 * values). */
/* Bernstein coefficients on [0, 1] of a value piece c (local variable u in [0, h]) in t = u / h. */
static void piece_bernstein(const double *c, double h, double bz[4])
{
    double a[4], hp = 1.0;
    int k;
    for (k = 0; k < 4; k++, hp *= h) a[k] = c[k] * hp;
    wvol_poly3_bernstein(bz, a);
}

static void majorant_pieces(double *c, int P, double h)
{
    int i;
    for (i = 0; i < P; i++) {
        double *q = c + 4 * (size_t)i, a[4], bz[4], hp = 1.0;
        int k;
        piece_bernstein(q, h, bz);
        for (k = 0; k < 4; k++) bz[k] = fabs(bz[k]);
        a[0] = bz[0];
        a[1] = 3.0 * (bz[1] - bz[0]);
        a[2] = 3.0 * (bz[2] - 2.0 * bz[1] + bz[0]);
        a[3] = bz[3] - 3.0 * bz[2] + 3.0 * bz[1] - bz[0];
        for (k = 0; k < 4; k++, hp *= h) q[k] = a[k] / hp;
    }
}

double wvol_basis_periodised_sup(const wvol_basis *b, int which)
{
    int per, i, k, j;
    double best = 0;
    if (!b) return NAN;
    per = b->per_unit;
    for (i = 0; i < per; i++) {
        double sum = 0;
        for (k = i; k < b->pieces; k += per) {
            double bz[4], mx = 0;
            piece_bernstein(wvol_basis_coeffs(b, which, WVOL_BASIS_VALUE, k), b->h, bz);
            for (j = 0; j < 4; j++) mx = fmax(mx, fabs(bz[j]));
            sum += mx;
        }
        best = fmax(best, sum);
    }
    return best;
}

void wvol_basis_piece_range(const wvol_basis *b, int which, int i, double *lo, double *hi)
{
    double bz[4], mag = 0.0;
    int j;
    if (!lo || !hi) return;
    if (!b || i < 0 || i >= b->pieces) { /* no such piece: an empty range */
        *lo = INFINITY, *hi = -INFINITY;
        return;
    }
    piece_bernstein(wvol_basis_coeffs(b, which, WVOL_BASIS_VALUE, i), b->h, bz);
    *lo = *hi = bz[0];
    for (j = 0; j < 4; j++) {
        *lo = fmin(*lo, bz[j]);
        *hi = fmax(*hi, bz[j]);
        mag += fabs(bz[j]);
    }
    *lo -= 1e-12 * mag;
    *hi += 1e-12 * mag;
}

wvol_status wvol_basis_create_majorant(wvol_basis **out, const wvol_filter *f, int J, wvol_error *err)
{
    wvol_basis *b;
    size_t N;
    WVOL_FORWARD(wvol_basis_create(out, f, J, err));
    b = *out;
    N = (size_t)b->pieces;
    majorant_pieces(b->phi, b->pieces, b->h);
    majorant_pieces(b->psi, b->pieces, b->h);
    wvol__spline_deriv(b->dphi, b->phi, N);
    wvol__spline_deriv(b->dpsi, b->psi, N);
    b->phi_integral = wvol__spline_primitive(b->phi_int, b->phi, N, b->h);
    b->psi_integral = wvol__spline_primitive(b->psi_int, b->psi, N, b->h);
    compute_bounds(b);
    b->majorant = 1;
    return WVOL_OK;
}

void wvol_basis_destroy(wvol_basis *b)
{
    if (!b) return;
    free(b->phi); /* the one block holding every table */
    free(b);
}

double wvol_basis_value(const wvol_basis *b, int which, double x)
{
    if (!b) return NAN;
    int i = wvol_basis_piece(b, x);
    if (i < 0) return x == x ? 0.0 : x;
    return horner3((which ? b->psi : b->phi) + 4 * (size_t)i, x - i * b->h);
}

double wvol_basis_deriv(const wvol_basis *b, int which, double x)
{
    int i = wvol_basis_piece(b, x);
    const double *d;
    double u;
    if (i < 0) return x == x ? 0.0 : x;
    d = (which ? b->dpsi : b->dphi) + 4 * (size_t)i;
    u = x - i * b->h;
    return d[0] + u * (d[1] + u * d[2]);
}

double wvol_basis_primitive(const wvol_basis *b, int which, double x)
{
    int i;
    const double *q;
    double u;
    if (x != x) return x;
    if (x <= 0.0) return 0.0;
    if (x >= b->support) return which ? b->psi_integral : b->phi_integral;
    i = wvol_basis_piece(b, x);
    q = (which ? b->psi_int : b->phi_int) + 5 * (size_t)i;
    u = x - i * b->h;
    return q[0] + u * (q[1] + u * (q[2] + u * (q[3] + u * q[4])));
}
