/* SPDX-License-Identifier: MIT
 * Spline-projected integrator (paper eqs 34-47, DESIGN.md section 8): the low-albedo
 * integral along each ray from the kept basis functions of a store, with no dense volume.
 *
 * Along a ray x(t) = o + t d (voxel coordinates, t the world ray parameter) a basis
 * function of level m is norm * prod_a B_a((x_a(t) - lo_a) / 2^m), each factor a cubic
 * spline piece in t between the knots x_a + s in 2^{m-J} Z. All levels' knots lie on the
 * finest lattice x_a + s in 2^{1-J} Z, so f^(t) is one polynomial of degree <= 9 on each
 * piece between consecutive lattice crossings. Per ray: the lattice pieces are merged from
 * the three axes, the store's octree query gives the basis functions the ray crosses, and
 * each one adds (three composed cubics multiplied out) to the polynomial of every piece it
 * covers, in the piece's normalised variable u in [0, 1]. The modes then integrate those
 * polynomials: exactly (X-ray), or with the optical depth exact and the exponential sampled
 * at Gauss-Legendre nodes of sub-pieces split where f^ crosses a TF knot (absorption).
 * Based on: Gross, Lippert et al. (paper, section 5); Max 1995; Weiss & Westermann 2021
 * (ray splitting at TF control points). */
#include "render_internal.h"
#include "spline_ray.h"

#include <float.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define NC WVOL__NC

typedef wvol__level_ws level_ws;
typedef wvol__spline_ws ray_ws;

typedef struct spline_ctx {
    wvol__spline_geom g;
    wvol_render_params p;
    wvol_tf tf;         /* kappa per world unit */
    double gl_x[10], gl_w[10];   /* nodes on [0, 1] */
    int gl_n;
    const float *stop;  /* per-pixel end of the ray (world t), or NULL */
} spline_ctx;

typedef struct ray_res {
    double rgba[4];
    size_t pieces, functions, samples, skipped, clamped;
    int terminated;
} ray_res;

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap) return 1;
    size_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    void *q = realloc(*p, n * elem);
    if (!q) return 0;
    *p = q;
    *cap = n;
    return 1;
}

/* Gauss-Legendre nodes and weights on [0, 1] (Golub-Welsch by Newton on P_n). */
static void gauss_legendre(int n, double *x, double *w)
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

static double binom(int n, int k)
{
    double r = 1;
    int i;
    for (i = 1; i <= k; i++) r = r * (n - k + i) / i;
    return r;
}

double wvol__poly_eval(const double *a, double u)
{
    double r = a[NC - 1];
    int k;
    for (k = NC - 2; k >= 0; k--) r = r * u + a[k];
    return r;
}

/* Integral of the polynomial from 0 to u. */
static double pint(const double *a, double u)
{
    double r = a[NC - 1] / NC;
    int k;
    for (k = NC - 2; k >= 0; k--) r = r * u + a[k] / (k + 1);
    return r * u;
}

/* Merges the sorted crossings x_a + s in grid Z of the three axes with [ta, tb] into
 * L->T and sets L->E, the number of pieces. */
static size_t lattice(const wvol__spline_geom *c, ray_ws *ws, level_ws *L, double grid, const double o[3], const double d[3],
                      double ta, double tb, int *ok)
{
    size_t n[3] = {0, 0, 0}, pos[3] = {0, 0, 0}, total = 2, E = 0;
    int a;
    double eps = 1e-12 * (fabs(ta) + fabs(tb) + 1.0);
    *ok = 1;
    for (a = 0; a < 3; a++) {
        double x0, x1, kd0, kd1;
        long k0, k1;
        if (!c->info.transformed[a] || d[a] == 0.0) continue;
        x0 = o[a] + ta * d[a];
        x1 = o[a] + tb * d[a];
        kd0 = ceil((fmin(x0, x1) + c->shift) / grid);
        kd1 = floor((fmax(x0, x1) + c->shift) / grid);
        if (kd1 < kd0) continue;
        k0 = (long)kd0;
        k1 = (long)kd1;
        n[a] = (size_t)(k1 - k0 + 1);
        total += n[a];
    }
    if (!grow((void **)&L->T, &L->capT, total + 1, sizeof(double))) return *ok = 0, 0;
    for (a = 0; a < 3; a++) {
        if (!n[a]) continue;
        if (!grow((void **)&ws->ax[a], &ws->capX[a], n[a], sizeof(double))) return *ok = 0, 0;
        {
            double x0 = o[a] + ta * d[a], x1 = o[a] + tb * d[a];
            long k0 = (long)ceil((fmin(x0, x1) + c->shift) / grid), k;
            size_t i;
            for (i = 0; i < n[a]; i++) {
                k = d[a] > 0 ? k0 + (long)i : k0 + (long)(n[a] - 1 - i);
                ws->ax[a][i] = ((double)k * grid - c->shift - o[a]) / d[a];
            }
        }
    }
    L->T[E++] = ta;
    for (;;) {
        double best = INFINITY;
        int ba = -1;
        for (a = 0; a < 3; a++)
            if (pos[a] < n[a] && ws->ax[a][pos[a]] < best) best = ws->ax[a][pos[a]], ba = a;
        if (ba < 0) break;
        pos[ba]++;
        if (best > L->T[E - 1] + eps && best < tb - eps) L->T[E++] = best;
    }
    L->T[E++] = tb;
    L->E = E - 1;
    return E - 1;
}

/* out = a * b for cubics a, b -> degree 6 (7 coefficients). */
static void mul33(double out[7], const double a[4], const double b[4])
{
    int i, j;
    for (i = 0; i < 7; i++) out[i] = 0;
    for (i = 0; i < 4; i++)
        for (j = 0; j < 4; j++) out[i + j] += a[i] * b[j];
}

/* acc += w * (a * b), a degree 6, b cubic. */
static void addmul63(double *acc, double w, const double a[7], const double b[4])
{
    int i, j;
    for (i = 0; i < 7; i++) {
        double wa = w * a[i];
        for (j = 0; j < 4; j++) acc[i + j] += wa * b[j];
    }
}

/* Adds one basis function (hit) to the piece polynomials. */
/* c(a u + d) as a cubic in u (Taylor shift to d, then scale by a); inline twin of
 * wvol_poly3_affine for the innermost loop. */
static inline void compose3(double out[4], const double *c, double a, double d)
{
    double c3 = c[3], c2 = c[2] + 3.0 * d * c3;
    double c1 = c[1] + d * (2.0 * c[2] + 3.0 * d * c3);
    double c0 = c[0] + d * (c[1] + d * (c[2] + d * c3));
    out[0] = c0;
    out[1] = c1 * a;
    out[2] = c2 * a * a;
    out[3] = c3 * a * a * a;
}

/* Adds one basis function (hit) to its level's piece polynomials. Factors along axes the ray
 * does not move on (or untransformed axes) are constants of the hit, so an axis-aligned ray
 * costs one cubic per piece. */
static void add_hit(const wvol__spline_geom *c, const level_ws *L, double *accbase, size_t elo, size_t ehi,
                    const double o[3], const double d[3], const wvol_store_hit *h, int shading,
                    wvol__spline_count *r)
{
    size_t E = L->E < ehi ? L->E : ehi;
    const wvol_basis *b = c->b;
    double inv2m = ldexp(1.0, -(int)h->level), w = (double)h->value * c->norm[h->level];
    double base[3], slope[3], cval = 1.0, cder[3] = {1, 1, 1}; /* cder[q]: d/dx_q of the constant factors */
    size_t lo = 0, hi = E, e;
    int a, nvar = 0, var[3], which[3];
    for (a = 0; a < 3; a++) {
        which[a] = (h->band >> a) & 1;
        if (!c->info.transformed[a]) {
            cder[a] = 0;          /* d/dx of a constant factor */
            continue;
        }
        base[a] = (o[a] - h->lo[a]) * inv2m;
        slope[a] = d[a] * inv2m;
        if (d[a] == 0.0) {
            int i = wvol_basis_piece(b, base[a]);
            double u, v, dv;
            const double *k, *kd;
            if (i < 0) return; /* the ray runs outside this factor's support */
            u = base[a] - i * b->h;
            k = wvol_basis_coeffs(b, which[a], WVOL_BASIS_VALUE, i);
            kd = wvol_basis_coeffs(b, which[a], WVOL_BASIS_DERIV, i);
            v = k[0] + u * (k[1] + u * (k[2] + u * k[3]));
            dv = kd[0] + u * (kd[1] + u * kd[2]);
            /* gradient component a: derivative of this factor times the others */
            for (int q = 0; q < 3; q++) cder[q] *= (q == a) ? dv * inv2m : v;
            cval *= v;
        } else {
            var[nvar++] = a;
        }
    }
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (L->T[mid] <= h->t0) lo = mid;
        else hi = mid;
    }
    r->functions++;
    if (lo < elo) lo = elo;
    for (e = lo; e < E && L->T[e] < h->t1; e++) {
        double t0 = L->T[e], len = L->T[e + 1] - t0;
        double f[3][4], g[3][4], prod[NC];
        int skip = 0, k, j;
        if (!(len > 0)) continue;
        for (k = 0; k < nvar; k++) {
            int ax = var[k], i;
            double a0 = base[ax] + t0 * slope[ax], am = a0 + 0.5 * len * slope[ax];
            i = wvol_basis_piece(b, am);
            if (i < 0) {
                skip = 1;
                break;
            }
            compose3(f[k], wvol_basis_coeffs(b, which[ax], WVOL_BASIS_VALUE, i), len * slope[ax], a0 - i * b->h);
            if (shading)
                compose3(g[k], wvol_basis_coeffs(b, which[ax], WVOL_BASIS_DERIV, i), len * slope[ax], a0 - i * b->h);
        }
        if (skip) continue;
        r->pieces++;
        /* the product of the varying factors, times the constant ones */
        for (j = 0; j < NC; j++) prod[j] = 0;
        if (nvar == 0) {
            prod[0] = 1;
        } else if (nvar == 1) {
            for (j = 0; j < 4; j++) prod[j] = f[0][j];
        } else if (nvar == 2) {
            mul33(prod, f[0], f[1]);
        } else {
            double f01[7];
            mul33(f01, f[0], f[1]);
            addmul63(prod, 1.0, f01, f[2]);
        }
        {
            double *acc = accbase + e * NC, wc = w * cval;
            for (j = 0; j < NC; j++) acc[j] += wc * prod[j];
        }
        if (shading) {
            /* component q: d/dx_q of factor q times the other factors */
            int q;
            for (q = 0; q < 3; q++) {
                double gp[NC], t7[7], *acc = accbase + (L->E + e * 3 + (size_t)q) * NC, wq = w;
                int kq = -1;
                for (k = 0; k < nvar; k++)
                    if (var[k] == q) kq = k;
                for (j = 0; j < NC; j++) gp[j] = 0;
                if (kq < 0) {
                    /* factor q is constant: its derivative (and the other constants) in cder[q] */
                    wq *= cder[q];
                    if (nvar == 0) gp[0] = 1;
                    else for (j = 0; j < NC; j++) gp[j] = prod[j];
                } else {
                    const double *fa[3];
                    int n = 0;
                    wq *= inv2m * cval;
                    fa[n++] = g[kq];
                    for (k = 0; k < nvar; k++)
                        if (k != kq) fa[n++] = f[k];
                    if (n == 1) for (j = 0; j < 4; j++) gp[j] = fa[0][j];
                    else if (n == 2) mul33(gp, fa[0], fa[1]);
                    else {
                        mul33(t7, fa[0], fa[1]);
                        addmul63(gp, 1.0, t7, fa[2]);
                    }
                }
                for (j = 0; j < NC; j++) acc[j] += wq * gp[j];
            }
        }
    }
}

/* Roots of p(u) = v on (0, 1): sign changes on 32 sub-intervals, refined by bisection. */
static int crossings(const double *p, double v, double *roots, int cap)
{
    enum { NS = 32 };
    int n = 0, i, it;
    double u0 = 0, q0 = wvol__poly_eval(p, 0) - v;
    for (i = 1; i <= NS && n < cap; i++) {
        double u1 = (double)i / NS, q1 = wvol__poly_eval(p, u1) - v;
        if ((q0 < 0 && q1 > 0) || (q0 > 0 && q1 < 0)) {
            double a = u0, b = u1, qa = q0;
            for (it = 0; it < 60; it++) {
                double m = 0.5 * (a + b), qm = wvol__poly_eval(p, m) - v;
                if ((qm < 0) == (qa < 0)) a = m, qa = qm;
                else b = m;
                if (b - a < 1e-15) break;
            }
            roots[n++] = 0.5 * (a + b);
        }
        u0 = u1;
        q0 = q1;
    }
    return n;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The TF segment holding value f as kappa = k0 + k1 f, colour = c0 + c1 f. */
static void tf_segment(const wvol_tf *tf, double f, double *k0, double *k1, double c0[3], double c1[3])
{
    const wvol_tf_point *p = tf->points;
    int n = tf->count, lo = 0, hi = n - 1, ch;
    if (n == 1 || !(f > p[0].value) || f >= p[n - 1].value) {
        const wvol_tf_point *q = (n == 1 || !(f > p[0].value)) ? &p[0] : &p[n - 1];
        *k0 = q->opacity;
        *k1 = 0;
        for (ch = 0; ch < 3; ch++) c0[ch] = q->rgb[ch], c1[ch] = 0;
        return;
    }
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (p[mid].value <= f) lo = mid;
        else hi = mid;
    }
    {
        double dv = p[hi].value - p[lo].value;
        *k1 = (p[hi].opacity - p[lo].opacity) / dv;
        *k0 = p[lo].opacity - *k1 * p[lo].value;
        for (ch = 0; ch < 3; ch++) {
            c1[ch] = (p[hi].rgb[ch] - p[lo].rgb[ch]) / dv;
            c0[ch] = p[lo].rgb[ch] - c1[ch] * p[lo].value;
        }
    }
}

/* q(v) = p(alpha + beta v), degree 9 (Taylor shift by synthetic division, then scaling). */
static void reexpand(double *q, const double *p, double alpha, double beta)
{
    int i, k;
    double bk = 1;
    for (k = 0; k < NC; k++) q[k] = p[k];
    for (i = 0; i < NC - 1; i++)
        for (k = NC - 2; k >= i; k--) q[k] += alpha * q[k + 1];
    for (k = 1; k < NC; k++) {
        bk *= beta;
        q[k] *= bk;
    }
}

static void addv(double *acc, const double *q, int n)
{
    int k;
    for (k = 0; k < n; k++) acc[k] += q[k];
}

/* Sums every level's piece polynomials onto level 1's (the finest) lattice: ws->macc. */
static int merge_levels(const wvol__spline_geom *c, ray_ws *ws, int shading)
{
    level_ws *F = &ws->lev[1];
    size_t E = F->E, e, per = shading ? 4 : 1, ptr[WVOL_SELECT_MAX_LEVELS + 1];
    int m, M = c->info.levels, k;
    if (!grow((void **)&ws->macc, &ws->capM, E * NC * per, sizeof(double))) return 0;
    if (F->used) memcpy(ws->macc, F->acc, E * NC * per * sizeof(double));
    else memset(ws->macc, 0, E * NC * per * sizeof(double));
    for (m = 2; m <= M; m++) ptr[m] = 0;
    for (e = 0; e < E; e++) {
        double t0 = F->T[e], t1 = F->T[e + 1], tm = 0.5 * (t0 + t1), q[NC];
        for (m = 2; m <= M; m++) {
            level_ws *L = &ws->lev[m];
            double plen, alpha, beta;
            size_t pe;
            if (!L->used) continue;
            while (ptr[m] + 1 < L->E && L->T[ptr[m] + 1] <= tm) ptr[m]++;
            pe = ptr[m];
            plen = L->T[pe + 1] - L->T[pe];
            if (!(plen > 0)) continue;
            alpha = (t0 - L->T[pe]) / plen;
            beta = (t1 - t0) / plen;
            reexpand(q, L->acc + pe * NC, alpha, beta);
            addv(ws->macc + e * NC, q, NC);
            if (shading)
                for (k = 0; k < 3; k++) {
                    reexpand(q, L->acc + (L->E + pe * 3 + (size_t)k) * NC, alpha, beta);
                    addv(ws->macc + (E + e * 3 + (size_t)k) * NC, q, NC);
                }
        }
    }
    return 1;
}

static void integrate(const spline_ctx *c, ray_ws *ws, const double d_world[3], ray_res *r)
{
    const wvol_render_params *p = &c->p;
    double T = 1.0, col[3] = {0, 0, 0}, xr = 0;
    size_t e, E = ws->lev[1].E;
    const double *Tb = ws->lev[1].T;
    int ch, q, m;
    if (p->mode == WVOL_MODE_XRAY) {
        /* no merge needed: the integral is a sum over every level's own pieces */
        for (m = 1; m <= c->g.info.levels; m++) {
            level_ws *L = &ws->lev[m];
            if (!L->used) continue;
            for (e = 0; e < L->E; e++) xr += (L->T[e + 1] - L->T[e]) * pint(L->acc + e * NC, 1.0);
        }
        r->rgba[0] = r->rgba[1] = r->rgba[2] = xr;
        r->rgba[3] = 1.0;
        return;
    }
    for (e = 0; e < E && !r->terminated; e++) {
        const double *a = ws->macc + e * NC;
        double len = Tb[e + 1] - Tb[e], bz[NC], bmin = INFINITY, bmax = -INFINITY, cuts[2 * WVOL_TF_MAX_POINTS + 2];
        int nc = 0, k, j, i;
        if (!(len > 0)) continue;
        /* Bernstein range of the piece: knots outside it cannot be crossed */
        wvol__bernstein(&c->g, a, bz);
        for (j = 0; j < NC; j++) {
            if (bz[j] < bmin) bmin = bz[j];
            if (bz[j] > bmax) bmax = bz[j];
        }
        cuts[nc++] = 0.0;
        for (k = 0; k < c->tf.count && nc < 2 * WVOL_TF_MAX_POINTS; k++) {
            double v = c->tf.points[k].value;
            if (v > bmin && v < bmax) nc += crossings(a, v, cuts + nc, 2 * WVOL_TF_MAX_POINTS - nc);
        }
        if (nc > 2) qsort(cuts + 1, (size_t)(nc - 1), sizeof *cuts, cmp_double);
        cuts[nc++] = 1.0;
        for (i = 0; i + 1 < nc; i++) {
            double s0 = cuts[i], s1 = cuts[i + 1], k0, k1, c0[3], c1[3], P0, h = s1 - s0, dtau1;
            if (!(h > 0)) continue;
            tf_segment(&c->tf, wvol__poly_eval(a, 0.5 * (s0 + s1)), &k0, &k1, c0, c1);
            P0 = pint(a, s0);
            for (q = 0; q < c->gl_n; q++) {
                double s = s0 + h * c->gl_x[q], f = wvol__poly_eval(a, s), kap = k0 + k1 * f, dtau, Tq, shade = 1.0;
                if (kap <= 0) continue;
                dtau = len * (k0 * (s - s0) + k1 * (pint(a, s) - P0));
                Tq = p->mode == WVOL_MODE_ABSORPTION ? T * exp(-dtau) : T * fmax(0.0, 1.0 - dtau);
                if (p->shading) {
                    double grad[3];
                    for (ch = 0; ch < 3; ch++)
                        grad[ch] = wvol__poly_eval(ws->macc + (E + e * 3 + (size_t)ch) * NC, s) / c->g.info.spacing[ch];
                    shade = wvol__shade(grad, d_world, p->ambient);
                }
                for (ch = 0; ch < 3; ch++) col[ch] += c->gl_w[q] * h * len * (c0[ch] + c1[ch] * f) * kap * Tq * shade;
            }
            r->samples += (size_t)c->gl_n;
            dtau1 = len * (k0 * h + k1 * (pint(a, s1) - P0));
            if (p->mode == WVOL_MODE_ABSORPTION) {
                T *= exp(-dtau1);
            } else {
                if (dtau1 > 1) r->clamped++;
                T *= fmax(0.0, 1.0 - dtau1);
            }
            if (T < p->termination || T == 0) {
                r->terminated = 1;
                break;
            }
        }
    }
    for (ch = 0; ch < 3; ch++) r->rgba[ch] = col[ch];
    r->rgba[3] = 1.0 - T;
}

double wvol__bernstein(const wvol__spline_geom *g, const double *a, double *bcoef)
{
    double worst = 0;
    int j, k;
    for (j = 0; j < NC; j++) {
        double bj = 0, mag = 0;
        for (k = 0; k <= j; k++) {
            double t = g->bern[j][k] * a[k];
            bj += t;
            mag += fabs(t);
        }
        bcoef[j] = bj;
        if (mag > worst) worst = mag;
    }
    return worst;
}

wvol_status wvol__spline_ray(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                             double ta, double tb, int shading, int merge, wvol__spline_count *cnt, wvol_error *err)
{
    WVOL_FORWARD(wvol_store_query_ray(g->s, o, d, ta, tb, &ws->hits, err));
    return wvol__spline_build(g, ws, o, d, ta, tb, ws->hits.hits, ws->hits.count, shading, merge, cnt, err);
}

void wvol__spline_add_finest(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                             const wvol_store_hit *h, size_t elo, size_t ehi, wvol__spline_count *cnt)
{
    /* every level's knots lie on level 1's lattice: one polynomial per finest piece */
    add_hit(g, &ws->lev[1], ws->macc, elo, ehi, o, d, h, 0, cnt);
}

wvol_status wvol__spline_build(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                               double ta, double tb, const wvol_store_hit *hits, size_t n, int shading, int merge,
                               wvol__spline_count *cnt, wvol_error *err)
{
    size_t i, per = shading ? 4 : 1;
    int ok, m, M = g->info.levels;
    for (m = 1; m <= M; m++) ws->lev[m].used = 0, ws->lev[m].E = 0;
    /* level 1's lattice is needed for the merge even without level-1 functions */
    if (merge) ws->lev[1].used = 2;
    for (i = 0; i < n; i++) ws->lev[hits[i].level].used = 2;
    for (m = 1; m <= M; m++) {
        level_ws *L = &ws->lev[m];
        if (!L->used) continue;
        lattice(g, ws, L, ldexp(g->grid, m - 1), o, d, ta, tb, &ok);
        if (ok) ok = grow((void **)&L->acc, &L->capA, L->E * NC * per, sizeof(double));
        WVOL_RETURN_IF(!ok, err, WVOL_ERR_NOMEM, "render: out of memory for the ray's pieces");
        memset(L->acc, 0, L->E * NC * per * sizeof(double));
        L->used = 0;
    }
    for (i = 0; i < n; i++) {
        level_ws *L = &ws->lev[hits[i].level];
        L->used = 1;
        add_hit(g, L, L->acc, 0, L->E, o, d, &hits[i], shading, cnt);
    }
    if (merge) WVOL_RETURN_IF(!merge_levels(g, ws, shading), err, WVOL_ERR_NOMEM, "render: out of memory");
    return WVOL_OK;
}

void wvol__spline_ws_free(wvol__spline_ws *ws)
{
    int l;
    for (l = 0; l <= WVOL_SELECT_MAX_LEVELS; l++) {
        free(ws->lev[l].T);
        free(ws->lev[l].acc);
    }
    for (l = 0; l < 3; l++) free(ws->ax[l]);
    free(ws->macc);
    wvol_store_hits_free(&ws->hits);
    memset(ws, 0, sizeof *ws);
}

wvol_status wvol__spline_geom_init(wvol__spline_geom *g, const wvol_store *s, wvol_error *err)
{
    int j, q, m, ntr;
    memset(g, 0, sizeof *g);
    g->s = s;
    g->b = wvol_store_basis(s);
    WVOL_RETURN_IF(!g->b, err, WVOL_ERR_ARG, "the store has no basis tables");
    wvol_store_get_info(s, &g->info);
    g->shift = g->b->center;
    ntr = g->info.transformed[0] + g->info.transformed[1] + g->info.transformed[2];
    for (m = 0; m <= WVOL_SELECT_MAX_LEVELS; m++) g->norm[m] = pow(2.0, -0.5 * m * ntr);
    g->grid = 2.0 * g->b->h;
    for (j = 0; j < NC; j++)
        for (q = 0; q <= j; q++) g->bern[j][q] = binom(j, q) / binom(NC - 1, q);
    return WVOL_OK;
}

static wvol_status trace(const spline_ctx *c, ray_ws *ws, const double ow[3], const double dw[3], double ta, double tb,
                         ray_res *r, wvol_error *err)
{
    double o[3], d[3];
    wvol__spline_count cnt = {0, 0};
    wvol_store_world_to_voxel(c->g.s, ow, o);
    wvol_store_dir_to_voxel(c->g.s, dw, d);
    WVOL_FORWARD(wvol__spline_ray(&c->g, ws, o, d, ta, tb, c->p.shading, c->p.mode != WVOL_MODE_XRAY, &cnt, err));
    r->pieces += cnt.pieces;
    r->functions += cnt.functions;
    integrate(c, ws, dw, r);
    return WVOL_OK;
}

wvol_status wvol_render_spline(wvol_image *img, const wvol_store *s, const wvol_camera *cam, const wvol_tf *tf_in,
                               const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    return wvol_render_spline_until(img, s, cam, tf_in, params, NULL, stats, err);
}

wvol_status wvol_render_spline_until(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                                     const wvol_tf *tf_in, const wvol_render_params *params, const float *stop,
                                     wvol_render_stats *stats, wvol_error *err)
{
    spline_ctx c;
    wvol_geometry g;
    wvol__cam k;
    double lo[3], hi[3], t_start = wvol__now(), c_start = wvol__cpu_now();
    int ntiles, tx, a, failed = 0;
    size_t rays_hit = 0, pieces = 0, functions = 0, samples = 0, skipped = 0, terminated = 0, clamped = 0;
    wvol_error first_err;

    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "render: no store");
    memset(&c, 0, sizeof c);
    wvol__params(&c.p, params);
    WVOL_FORWARD(wvol__render_check(img, cam, tf_in, &c.p, err));
    WVOL_FORWARD(wvol__check_colors(&c.p, NULL, 0, err));
    WVOL_FORWARD(wvol__check_skip(&c.p, 0, err));
    WVOL_FORWARD(wvol__spline_geom_init(&c.g, s, err));
    for (a = 0; a < 3; a++) {
        g.dims[a] = a == 0 ? c.g.info.nx : a == 1 ? c.g.info.ny : c.g.info.nz;
        g.spacing[a] = c.g.info.spacing[a];
        g.origin[a] = c.g.info.origin[a];
    }
    if (c.p.mode != WVOL_MODE_XRAY) wvol__tf_world(&c.tf, tf_in, &g);
    c.stop = stop;
    c.gl_n = c.p.spline.gauss_nodes;
    gauss_legendre(c.gl_n, c.gl_x, c.gl_w);
    wvol_geometry_bounds(&g, lo, hi);
    wvol__cam_init(&k, cam);
    c.p.tile = wvol__tile_side(&c.p, 0);
    ntiles = wvol__tiles(img->width, img->height, c.p.tile);
    tx = (img->width + c.p.tile - 1) / c.p.tile;
    wvol_error_clear(&first_err);
#pragma omp parallel num_threads(wvol__threads(c.p.threads)) \
    reduction(+ : rays_hit, pieces, functions, samples, skipped, terminated, clamped)
    {
        ray_ws ws;
        memset(&ws, 0, sizeof ws);
#pragma omp for schedule(dynamic, 1)
        for (int ti = 0; ti < ntiles; ti++) {
            int x0 = (ti % tx) * c.p.tile, y0 = (ti / tx) * c.p.tile, x, y;
            for (y = y0; y < y0 + c.p.tile && y < img->height; y++)
                for (x = x0; x < x0 + c.p.tile && x < img->width; x++) {
                    double o[3], d[3], t0, t1;
                    float *px = img->rgba + 4 * ((size_t)x + (size_t)img->width * (size_t)y);
                    ray_res r;
                    int ch;
                    memset(&r, 0, sizeof r);
                    wvol__cam_ray(&k, x + 0.5, y + 0.5, o, d);
                    if (!failed && wvol__ray_box(o, d, lo, hi, &t0, &t1)) {
                        if (cam->projection == WVOL_PERSPECTIVE && t0 < 0) t0 = 0;
                        if (c.stop) { /* NaN or +inf: the whole ray */
                            float st = c.stop[(size_t)x + (size_t)img->width * (size_t)y];
                            if (st < t1) t1 = st;
                        }
                        if (t1 > t0) {
                            wvol_error e2;
                            rays_hit++;
                            if (trace(&c, &ws, o, d, t0, t1, &r, &e2) != WVOL_OK) {
#pragma omp critical(wvol_render_err)
                                if (!failed) {
                                    failed = 1;
                                    first_err = e2;
                                }
                            }
                        }
                    }
                    for (ch = 0; ch < 4; ch++) px[ch] = (float)r.rgba[ch];
                    pieces += r.pieces;
                    functions += r.functions;
                    samples += r.samples;
                    skipped += r.skipped;
                    terminated += (size_t)r.terminated;
                    clamped += r.clamped;
                }
        }
        wvol__spline_ws_free(&ws);
    }
    if (failed) {
        if (err) *err = first_err;
        return first_err.status ? first_err.status : WVOL_ERR_INTERNAL;
    }
    {
        wvol__counts c = {.rays_hit = rays_hit, .samples = samples, .pieces = pieces, .functions = functions,
                          .skipped = skipped, .terminated = terminated, .clamped = clamped};
        wvol__stats_fill(stats, img, t_start, c_start, &c);
    }
    return WVOL_OK;
}
