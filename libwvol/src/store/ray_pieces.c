/* SPDX-License-Identifier: MIT
 * f^ along a ray as exact piecewise polynomials (store/store_ray.h): the store's kept basis
 * functions whose support the ray crosses, each a product of three cubic spline pieces
 * composed with the ray, multiplied out and added to the pieces of its level's lattice:
 * factorised for the values (add_level: each (axis, translate, band) cubic composed once per
 * piece, the sum grouped by the x and then the y factor), function by function for the
 * gradient and the reference (add_hit). Shared by the spline integrator (render/spline.c) and
 * the implicit-surface ray tracer (iso/). Based on: Gross, Lippert et al. (paper, section 5,
 * eqs 34-40). */
#include "store/store_ray.h"
#include "core/alloc.h"
#include "core/clones.h"
#include "core/status_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NC WVOL__NC

typedef wvol__level_ws level_ws;
typedef wvol__spline_ws ray_ws;

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
    return wvol__grow(p, cap, need, elem, 256);
}

static double binom(int n, int k)
{
    double r = 1;
    int i;
    for (i = 1; i <= k; i++) r = r * (n - k + i) / i;
    return r;
}

/* Merges the sorted crossings x_a + s in grid Z of the three axes with [ta, tb] into
 * L->T and sets L->E, the number of pieces. */
static size_t lattice(const wvol__spline_geom *c, ray_ws *ws, level_ws *L, double grid, const double o[3], const double d[3],
                      double ta, double tb, int *ok)
{
    size_t n[3] = {0, 0, 0}, pos[3] = {0, 0, 0}, total = 2, E = 0;
    int a;
    /* crossings closer than eps are one: relative to the ray parameter's magnitude and to its
     * length per voxel (d is the voxel-space direction), never an absolute length, which at a
     * spacing of 1e-12 would merge whole pieces */
    double dmax = fmax(fabs(d[0]), fmax(fabs(d[1]), fabs(d[2])));
    double eps = 1e-12 * (fabs(ta) + fabs(tb) + (dmax > 0 ? 1.0 / dmax : 1.0));
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
WVOL__CLONES static void add_hit(const wvol__spline_geom *c, const level_ws *L, double *accbase, size_t elo, size_t ehi,
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
        if (nvar == 3 && !shading) {
            /* the general ray without shading: the weight folded into the last factor, the
             * product added straight into the piece */
            double f01[7], g2[4], wc = w * cval;
            mul33(f01, f[0], f[1]);
            for (j = 0; j < 4; j++) g2[j] = wc * f[2][j];
            addmul63(accbase + e * NC, 1.0, f01, g2);
            continue;
        }
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

/* The factorised build. On a piece of a lattice at least as fine as its level's, a level-m
 * function is w X(t) Y(t) Z(t), one composed cubic per axis, and the functions with the same
 * translate and band on an axis share that axis's cubic. So each (axis, translate, band)
 * cubic is composed once per piece (exactly as add_hit composes it), and the level's sum is
 * formed factorised, sum_x X (sum_y Y (sum_z w Z)): 4 multiply-adds per function and piece,
 * the products once per piece and (x) or (x, y) group. Only the order of the sums differs
 * from add_hit's: equal to rounding. Keys: 2 (j - jmin) + band bit, j the image's translate
 * on the axis (lo = j 2^m - s); an axis the transform leaves alone has the one key 0. */

/* First e in [lo, hi) with T[e] >= t, else hi. */
static size_t first_ge(const double *T, size_t lo, size_t hi, double t)
{
    while (lo < hi) {
        size_t m = (lo + hi) / 2;
        if (T[m] >= t) hi = m;
        else lo = m + 1;
    }
    return lo;
}

/* Fills key k's composed cubics on pieces [lo, hi) of T: the factor B((x_a - ref) / 2^m) of
 * band bit `which` along the ray; zero where the ray is outside the factor's support or the
 * piece is empty (add_hit skips those pieces). Inlined into add_level, so that it is compiled
 * with add_level's clones. */
static inline __attribute__((always_inline)) void axis_cubics(const wvol__spline_geom *c, const double *T, int a,
                                                              int which, double ref, double inv2m, const double o[3],
                                                              const double d[3], size_t lo, size_t hi, double *out)
{
    const wvol_basis *b = c->b;
    double base = (o[a] - ref) * inv2m, slope = d[a] * inv2m, cst = 1.0;
    size_t e;
    int constant = !c->info.transformed[a] || d[a] == 0.0;
    if (c->info.transformed[a] && d[a] == 0.0) {
        int i = wvol_basis_piece(b, base);
        double u = base - i * b->h;
        const double *k = i < 0 ? NULL : wvol_basis_coeffs(b, which, WVOL_BASIS_VALUE, i);
        cst = k ? k[0] + u * (k[1] + u * (k[2] + u * k[3])) : 0.0;
    }
    for (e = lo; e < hi; e++, out += 4) {
        double t0 = T[e], len = T[e + 1] - t0, a0, am;
        int i;
        out[0] = out[1] = out[2] = out[3] = 0.0;
        if (!(len > 0)) continue;
        if (constant) {
            out[0] = cst;
            continue;
        }
        a0 = base + t0 * slope;
        am = a0 + 0.5 * len * slope;
        i = wvol_basis_piece(b, am);
        if (i >= 0) compose3(out, wvol_basis_coeffs(b, which, WVOL_BASIS_VALUE, i), len * slope, a0 - i * b->h);
    }
}

/* acc += a * b, a degree 6, b cubic (no weight); in locals, then stored once. */
static inline void mac63(double *restrict acc, const double *restrict a, const double *restrict b)
{
    double r[NC];
    int i, j;
    for (i = 0; i < NC; i++) r[i] = acc[i];
    for (i = 0; i < 7; i++)
        for (j = 0; j < 4; j++) r[i + j] += a[i] * b[j];
    for (i = 0; i < NC; i++) acc[i] = r[i];
}

/* acc += a * b for cubics a, b (degree 6). */
static inline void mac33(double *restrict acc, const double *restrict a, const double *restrict b)
{
    double r[7];
    int i, j;
    for (i = 0; i < 7; i++) r[i] = acc[i];
    for (i = 0; i < 4; i++)
        for (j = 0; j < 4; j++) r[i + j] += a[i] * b[j];
    for (i = 0; i < 7; i++) acc[i] = r[i];
}

/* Last e in [0, E) with T[e] <= t (0 when none): add_hit's first piece of a function. */
static size_t last_le(const double *T, size_t E, double t)
{
    size_t lo = 0, hi = E;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (T[mid] <= t) lo = mid;
        else hi = mid;
    }
    return lo;
}

/* The pieces [s0, s1) of [elo, eend) the ray may be inside key q's support on: found as add_hit
 * finds a function's, from the slab's entry and exit. A piece just outside may come in through
 * rounding: its cubic is zero (axis_cubics). */
static void key_slab(const wvol__spline_geom *c, const double *T, size_t E, size_t elo, size_t eend, int a,
                     const double o[3], const double d[3], wvol__fact_key *q)
{
    double tin, tout;
    size_t e0;
    q->s0 = (uint32_t)elo;
    q->s1 = (uint32_t)eend;
    if (!c->info.transformed[a] || d[a] == 0.0) return;
    tin = (q->lo - o[a]) / d[a];
    tout = (q->hi - o[a]) / d[a];
    if (tin > tout) {
        double t = tin;
        tin = tout, tout = t;
    }
    e0 = last_le(T, E, tin);
    if (e0 < elo) e0 = elo;
    q->s0 = (uint32_t)(e0 < eend ? e0 : eend);
    q->s1 = (uint32_t)(e0 < eend ? first_ge(T, e0, eend, tout) : eend);
}

/* Adds the level-m functions among hits[0..n) to accbase's pieces [elo, ehi) of the lattice
 * T (E pieces). 0 when out of memory. */
WVOL__CLONES static int add_level(const wvol__spline_geom *c, wvol__fact_ws *f, const double *T, size_t E, double *accbase,
                                  size_t elo, size_t ehi, const double o[3], const double d[3], const wvol_store_hit *hits,
                                  size_t n, int m, wvol__spline_count *r)
{
    double inv2m = ldexp(1.0, -m);
    int64_t jmin[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, jmax[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
    size_t K[3], nm = 0, i, q, eend = E < ehi ? E : ehi, tot;
    int a, key_axis[3];
    if (elo >= eend) return 1;
    for (a = 0; a < 3; a++) key_axis[a] = c->info.transformed[a];
    for (i = 0; i < n; i++) {
        if (hits[i].level != m) continue;
        nm++;
        for (a = 0; a < 3; a++)
            if (key_axis[a]) {
                int64_t j = (int64_t)floor((hits[i].lo[a] + c->shift) * inv2m + 0.5);
                if (j < jmin[a]) jmin[a] = j;
                if (j > jmax[a]) jmax[a] = j;
            }
    }
    if (!nm) return 1;
    if (!grow((void **)&f->h, &f->capH, nm, sizeof *f->h) || !grow((void **)&f->s, &f->capS, nm, sizeof *f->s)) return 0;
    for (a = 0; a < 3; a++) {
        wvol__fact_axis *X = &f->ax[a];
        K[a] = key_axis[a] ? 2 * (size_t)(jmax[a] - jmin[a] + 1) : 1;
        if (!grow((void **)&X->key, &X->capK, K[a], sizeof *X->key)) return 0;
        for (q = 0; q < K[a]; q++) X->key[q].seen = 0;
    }
    /* per function: weight, keys, piece range (the intersection of its keys' slabs) */
    for (i = 0, q = 0; i < n; i++) {
        const wvol_store_hit *h = &hits[i];
        wvol__fact_hit *p;
        uint32_t e0 = (uint32_t)elo, e1 = (uint32_t)eend;
        if (h->level != m) continue;
        p = &f->h[q];
        for (a = 0; a < 3; a++) {
            wvol__fact_key *kq;
            uint32_t k = 0;
            if (key_axis[a])
                k = (uint32_t)(2 * ((int64_t)floor((h->lo[a] + c->shift) * inv2m + 0.5) - jmin[a]) + ((h->band >> a) & 1));
            p->k[a] = k;
            kq = &f->ax[a].key[k];
            if (!kq->seen) {
                kq->seen = 1;
                kq->lo = h->lo[a];
                kq->hi = h->hi[a];
                kq->e0 = UINT32_MAX;
                kq->e1 = 0;
                key_slab(c, T, E, elo, eend, a, o, d, kq);
            }
            if (kq->s0 > e0) e0 = kq->s0;
            if (kq->s1 < e1) e1 = kq->s1;
        }
        if (e0 >= e1) continue;
        p->w = (double)h->value * c->norm[m];
        p->e0 = e0;
        p->e1 = e1;
        for (a = 0; a < 3; a++) {
            wvol__fact_key *kq = &f->ax[a].key[p->k[a]];
            if (e0 < kq->e0) kq->e0 = e0;
            if (e1 > kq->e1) kq->e1 = e1;
        }
        r->pieces += e1 - e0;
        r->functions++;
        q++;
    }
    nm = q;
    if (!nm) return 1;
    /* every used key's cubics on its functions' pieces */
    for (a = 0; a < 3; a++) {
        wvol__fact_axis *X = &f->ax[a];
        for (tot = 0, q = 0; q < K[a]; q++) {
            wvol__fact_key *kq = &X->key[q];
            kq->off = tot;
            if (kq->seen && kq->e0 < kq->e1) tot += 4 * (size_t)(kq->e1 - kq->e0);
        }
        if (!grow((void **)&X->cub, &X->capC, tot, sizeof(double))) return 0;
        for (q = 0; q < K[a]; q++) {
            const wvol__fact_key *kq = &X->key[q];
            if (kq->seen && kq->e0 < kq->e1)
                axis_cubics(c, T, a, key_axis[a] ? (int)(q & 1) : 0, kq->lo, inv2m, o, d, kq->e0, kq->e1, X->cub + kq->off);
        }
    }
    /* sorted by (key x, key y): counting sort on y, then a stable one on x */
    {
        size_t nk = (K[0] > K[1] ? K[0] : K[1]) + 1, pass;
        if (!grow((void **)&f->count, &f->capN, nk, sizeof *f->count)) return 0;
        for (pass = 0; pass < 2; pass++) {
            int ax = pass == 0 ? 1 : 0;
            const wvol__fact_hit *src = pass == 0 ? f->h : f->s;
            wvol__fact_hit *dst = pass == 0 ? f->s : f->h;
            size_t sum = 0;
            memset(f->count, 0, nk * sizeof *f->count);
            for (q = 0; q < nm; q++) f->count[src[q].k[ax]]++;
            for (q = 0; q < K[ax]; q++) {
                size_t cq = f->count[q];
                f->count[q] = (uint32_t)sum;
                sum += cq;
            }
            for (q = 0; q < nm; q++) dst[f->count[src[q].k[ax]]++] = src[q];
        }
    }
    if (!grow((void **)&f->zs, &f->capZ, 4 * eend, sizeof(double)) || !grow((void **)&f->yz, &f->capY, 7 * eend, sizeof(double)))
        return 0;
    {
        const wvol__fact_hit *s = f->h;
        const wvol__fact_key *KX = f->ax[0].key, *KY = f->ax[1].key, *KZ = f->ax[2].key;
        double *zs = f->zs, *yz = f->yz;
        size_t ix = 0, e;
        while (ix < nm) {
            uint32_t kx = s[ix].k[0], xlo = KX[kx].e0, xhi = KX[kx].e1;
            size_t jx = ix, iy;
            const double *Xc = f->ax[0].cub + KX[kx].off;
            while (jx < nm && s[jx].k[0] == kx) jx++;
            memset(yz + 7 * (size_t)xlo, 0, 7 * (size_t)(xhi - xlo) * sizeof(double));
            for (iy = ix; iy < jx;) {
                uint32_t ky = s[iy].k[1], ylo = UINT32_MAX, yhi = 0;
                size_t jy = iy, p;
                const double *Yc = f->ax[1].cub + KY[ky].off;
                while (jy < jx && s[jy].k[1] == ky) {
                    if (s[jy].e0 < ylo) ylo = s[jy].e0;
                    if (s[jy].e1 > yhi) yhi = s[jy].e1;
                    jy++;
                }
                memset(zs + 4 * (size_t)ylo, 0, 4 * (size_t)(yhi - ylo) * sizeof(double));
                for (p = iy; p < jy; p++) {
                    const wvol__fact_hit *h = &s[p];
                    const wvol__fact_key *kz = &KZ[h->k[2]];
                    const double *Zc = f->ax[2].cub + kz->off + 4 * (size_t)(h->e0 - kz->e0);
                    double w = h->w, *z = zs + 4 * (size_t)h->e0;
                    for (e = h->e0; e < h->e1; e++, z += 4, Zc += 4) {
                        z[0] += w * Zc[0];
                        z[1] += w * Zc[1];
                        z[2] += w * Zc[2];
                        z[3] += w * Zc[3];
                    }
                }
                for (e = ylo; e < yhi; e++) mac33(yz + 7 * e, Yc + 4 * (e - KY[ky].e0), zs + 4 * e);
                iy = jy;
            }
            for (e = xlo; e < xhi; e++) mac63(accbase + e * NC, yz + 7 * e, Xc + 4 * (e - xlo));
            ix = jx;
        }
    }
    return 1;
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
WVOL__CLONES static int merge_levels(const wvol__spline_geom *c, ray_ws *ws, int shading)
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

int wvol__spline_add_finest_list(const wvol__spline_geom *g, wvol__spline_ws *ws, const double o[3], const double d[3],
                                 const wvol_store_hit *hits, size_t n, size_t elo, size_t ehi, wvol__spline_count *cnt)
{
    /* every level's knots lie on level 1's lattice: one polynomial per finest piece */
    const level_ws *F = &ws->lev[1];
    size_t i;
    int m;
    if (ws->per_function) {
        for (i = 0; i < n; i++) add_hit(g, F, ws->macc, elo, ehi, o, d, &hits[i], 0, cnt);
        return 1;
    }
    for (m = 1; m <= g->info.levels; m++)
        if (!add_level(g, &ws->f, F->T, F->E, ws->macc, elo, ehi, o, d, hits, n, m, cnt)) return 0;
    return 1;
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
    for (i = 0; i < n; i++) ws->lev[hits[i].level].used = 1;
    if (shading || ws->per_function) {
        for (i = 0; i < n; i++) {
            level_ws *L = &ws->lev[hits[i].level];
            add_hit(g, L, L->acc, 0, L->E, o, d, &hits[i], shading, cnt);
        }
    } else {
        for (m = 1; m <= M; m++)
            if (ws->lev[m].used == 1)
                WVOL_RETURN_IF(!add_level(g, &ws->f, ws->lev[m].T, ws->lev[m].E, ws->lev[m].acc, 0, ws->lev[m].E, o, d,
                                          hits, n, m, cnt),
                               err, WVOL_ERR_NOMEM, "render: out of memory for the ray's pieces");
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
    for (l = 0; l < 3; l++) {
        wvol__fact_axis *X = &ws->f.ax[l];
        free(ws->ax[l]);
        free(X->key), free(X->cub);
    }
    free(ws->f.h), free(ws->f.s), free(ws->f.count), free(ws->f.zs), free(ws->f.yz);
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
