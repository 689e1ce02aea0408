/* SPDX-License-Identifier: MIT */
/* Ray tracing the implicit surface f^ = iso of a coefficient store with no missed hit
 * (Kalra-Barr's guarantee), on the exact piecewise-polynomial form of f^ along the ray.
 *
 * Along x(t) = o + t d, f^(t) is one polynomial of degree <= 9 on each piece between
 * consecutive knots of the finest spline lattice (render/spline_ray.h: the kept basis
 * functions whose support the ray crosses, from the store's octree, each a product of three
 * composed cubic pieces). The ray is cut into chunks of `chunk` voxels, built one after the
 * other front to back, so a ray that meets the surface early builds little. On each piece:
 *   - the Bernstein coefficients B_j of p(u) - iso on [u0, u1] (u the piece's normalised
 *     variable) bound it: p - iso lies in their convex hull, so when every B_j > pad or
 *     every B_j < -pad the interval holds no crossing and is discarded;
 *   - by Descartes' rule for the Bernstein basis the number of roots in (u0, u1) is at most
 *     the number V of sign changes of B_j, with the same parity: when no B_j is within pad
 *     of 0 and V = 1 the interval holds exactly one crossing (its end values B_0 and B_n,
 *     which equal p(u0) - iso and p(u1) - iso, have opposite signs), found by bisection of
 *     p - iso to `tolerance`;
 *   - otherwise the interval is split in two (de Casteljau) and the left half goes first.
 * An interval shorter than the tolerance that is still undecided is a hit when p - iso
 * changes sign between its ends or at 8 interior points, else a graze (counted): a tangent
 * touch or two crossings closer together than tolerance / 8.
 * Crossings at piece boundaries (f^ jumps there for Haar, whose pieces are constants) are
 * detected by comparing the last value of a piece with the first of the next.
 *
 * Cost. Building a function's polynomials costs ~2 us; two rigorous shortcuts avoid most:
 *   - small functions (the smallest |c| max|w|, summing to <= 1/16 of the chunk's largest)
 *     are not expanded but bounded per piece (sum of |c| max|w| of those covering it); a
 *     piece whose hull widened by that envelope excludes iso is decided, and only runs of
 *     undecided pieces get the small functions added exactly;
 *   - images first classify a grid of cells (8 voxels, undecided ones split to 4) by
 *     wvol__iso_box_range (low-pass coefficients fitted by a plane through the spline's
 *     partition of unity and first moment, the rest as |c| max|w|): rays step over cells
 *     whose bound excludes iso and trace runs of the others.
 *
 * The guarantee. "Crossing" means f^ - iso changes sign in the classification f^ >= iso.
 * For the computed piece polynomials, the reported hit is the first crossing along the ray
 * inside the sample extent [0, n-1] (and t >= tmin), with |t - t*| <= tolerance / 2, except
 * that a pair of crossings closer together than tolerance / 8 may be skipped (a graze).
 * Rounding: the piece polynomials are sums of products of the spline tables' cubics in
 * float64; pad = 1e-10 (sum of |B_j| terms + |iso|), far above their rounding, so a rounded
 * coefficient never hides a sign; the envelope and the cell bounds are padded alike.
 * Based on: Kalra & Barr 1989; Lane & Riesenfeld 1981 (Bernstein subdivision root isolation);
 * DESIGN.md section 9; docs/iso.md. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "render/render_internal.h"
#include "store/store_ray.h"
#include "iso_internal.h"
#include "wvol/iso.h"

#define NC WVOL__NC
#define PAD_REL 1e-10
#define SMALL_BUDGET (1.0 / 16) /* the small functions' |c| max|w| sum to at most this share of the largest */
#define RUN_MAX 32         /* undecided pieces refined at once */
#define CELL 8.0           /* cell grid side, voxels */

void wvol_iso_trace_params_default(wvol_iso_trace_params *p)
{
    memset(p, 0, sizeof *p);
    p->tolerance = 0.0; /* 1e-3 of the smallest spacing */
    p->chunk = 16.0;
    p->threads = 0;
    p->color[0] = 0.93f, p->color[1] = 0.89f, p->color[2] = 0.80f;
    p->ambient = 0.15f;
}

typedef struct tracer {
    wvol__spline_geom g;
    double iso, tol, chunk;
    wvol__iso_boxk k;   /* function bounds for the cells and the small functions' envelope */
    /* cell grid (images only): cells of `cell` voxels, class 1 (f^ >= iso on the whole closed
     * cell), 0 (f^ < iso) or -1 (undecided), from the store's rigorous box bounds */
    double cell;
    size_t nc[3];
    signed char *cls;
} tracer;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Range over [0, 1] of the polynomial a (degree deg <= 4): the hull of its Bernstein
 * coefficients, padded for rounding. */
static void bern_range(const double *a, int deg, double *lo, double *hi)
{
    static const double C[5][5] = {{1}, {1, 1}, {1, 2, 1}, {1, 3, 3, 1}, {1, 4, 6, 4, 1}};
    int j, i;
    for (j = 0; j <= deg; j++) {
        double b = 0, mag = 0;
        for (i = 0; i <= j; i++) {
            double t = C[j][i] / C[deg][i] * a[i];
            b += t;
            mag += fabs(t);
        }
        *lo = fmin(*lo, b - 1e-12 * mag);
        *hi = fmax(*hi, b + 1e-12 * mag);
    }
}

/* Ranges over all y of s(y) = sum_p phi(y - p) (the spline phi's partition of unity, ~1)
 * and m(y) = sum_p (y - p) phi(y - p) (its first moment, ~ the centre): per piece of the
 * unit, sums of the pieces' cubics (times the linear y - p for m). */
static void phi_sums_range(const wvol_basis *b, double s[2], double m[2])
{
    int j, q, k;
    s[0] = m[0] = INFINITY;
    s[1] = m[1] = -INFINITY;
    for (j = 0; j < b->per_unit && j < b->pieces; j++) {
        double c[4] = {0, 0, 0, 0}, c4[5] = {0, 0, 0, 0, 0}, hk = 1;
        for (q = j; q < b->pieces; q += b->per_unit) {
            const double *pc = wvol_basis_coeffs(b, WVOL_PHI, WVOL_BASIS_VALUE, q);
            double v0 = q * b->h; /* y - p = v0 + u on this piece */
            for (k = 0; k < 4; k++) {
                c[k] += pc[k];
                c4[k] += v0 * pc[k];
                c4[k + 1] += pc[k];
            }
        }
        for (k = 0; k < 5; k++, hk *= b->h) { /* in u / h on [0, 1] */
            if (k < 4) c[k] *= hk;
            c4[k] *= hk;
        }
        bern_range(c, 3, &s[0], &s[1]);
        bern_range(c4, 4, &m[0], &m[1]);
    }
}

/* Interval product. */
static void imul(double a0, double a1, double b0, double b1, double *lo, double *hi)
{
    double p[4] = {a0 * b0, a0 * b1, a1 * b0, a1 * b1};
    *lo = fmin(fmin(p[0], p[1]), fmin(p[2], p[3]));
    *hi = fmax(fmax(p[0], p[1]), fmax(p[2], p[3]));
}

void wvol__iso_boxk_init(wvol__iso_boxk *k, const wvol_store *s)
{
    wvol_store_info info;
    const wvol_basis *b = wvol_store_basis(s);
    int m, l, a;
    memset(k, 0, sizeof *k);
    wvol_store_get_info(s, &info);
    k->levels = info.levels;
    for (m = 1; m <= info.levels; m++)
        for (l = 0; l < 8; l++) wvol_store_function_bounds(s, m, l, &k->fb[m][l], NULL);
    phi_sums_range(b, k->s1, k->m1);
    for (a = 0; a < 3; a++) k->transformed[a] = info.transformed[a];
    k->norm = pow(2.0, -0.5 * info.levels * (info.transformed[0] + info.transformed[1] + info.transformed[2]));
    k->scale = ldexp(1.0, info.levels);
    k->shift = b->center;
}

/* The product of s over the transformed axes other than `skip` (-1: all). */
static void s_product(const wvol__iso_boxk *k, int skip, double *lo, double *hi)
{
    int a;
    *lo = *hi = 1;
    for (a = 0; a < 3; a++)
        if (a != skip && k->transformed[a]) imul(*lo, *hi, k->s1[0], k->s1[1], lo, hi);
}

wvol_status wvol__iso_box_range(const wvol__iso_boxk *k, const wvol_store *s, wvol_store_hits *hl, const double lo[3],
                                const double hi[3], double *vmin, double *vmax, wvol_error *err)
{
    size_t i, nlow = 0;
    double a0 = 0, pbar[3] = {0, 0, 0}, g[3] = {0, 0, 0}, sxx[3] = {0, 0, 0}, dev = 0, mag = 0, blo, bhi, t0, t1;
    int a;
    WVOL_FORWARD(wvol_store_query_box(s, lo, hi, hl, err));
    /* low-pass coefficients ~ a0 + g . (p - pbar), least squares over the touching ones
     * (p: the function's position on the level-M grid, periodic images included) */
    for (i = 0; i < hl->count; i++) {
        const wvol_store_hit *h = &hl->hits[i];
        if (h->band != 0) continue;
        nlow++;
        a0 += h->value;
        for (a = 0; a < 3; a++)
            if (k->transformed[a]) pbar[a] += (h->lo[a] + k->shift) / k->scale;
    }
    if (nlow) {
        a0 /= (double)nlow;
        for (a = 0; a < 3; a++) pbar[a] /= (double)nlow;
        for (i = 0; i < hl->count; i++) {
            const wvol_store_hit *h = &hl->hits[i];
            if (h->band != 0) continue;
            for (a = 0; a < 3; a++)
                if (k->transformed[a]) {
                    double dp = (h->lo[a] + k->shift) / k->scale - pbar[a];
                    g[a] += (double)h->value * dp;
                    sxx[a] += dp * dp;
                }
        }
        for (a = 0; a < 3; a++) g[a] = sxx[a] > 0 ? g[a] / sxx[a] : 0.0;
    }
    for (i = 0; i < hl->count; i++) {
        const wvol_store_hit *h = &hl->hits[i];
        double c = h->value;
        if (h->band == 0)
            for (a = 0, c -= a0; a < 3; a++)
                if (k->transformed[a]) c -= g[a] * ((h->lo[a] + k->shift) / k->scale - pbar[a]);
        dev += fabs(c) * k->fb[h->level][h->band];
        mag += fabs((double)h->value) * k->fb[h->level][h->band];
    }
    /* a0 sum_p w_p = a0 norm S(x) */
    s_product(k, -1, &t0, &t1);
    imul(a0 * k->norm, a0 * k->norm, t0, t1, &blo, &bhi);
    /* g_a sum_p (p_a - pbar_a) w_p = g_a norm [(y_a - pbar_a) s(y_a) - m(y_a)] prod_{b != a} s(y_b) */
    for (a = 0; a < 3; a++) {
        double y0, y1, l0, l1, o0, o1;
        if (!k->transformed[a] || g[a] == 0.0) continue;
        y0 = (lo[a] + k->shift) / k->scale - pbar[a];
        y1 = (hi[a] + k->shift) / k->scale - pbar[a];
        imul(y0, y1, k->s1[0], k->s1[1], &l0, &l1);
        l0 -= k->m1[1];
        l1 -= k->m1[0];
        s_product(k, a, &o0, &o1);
        imul(l0, l1, o0, o1, &l0, &l1);
        imul(g[a] * k->norm, g[a] * k->norm, l0, l1, &l0, &l1);
        blo += l0;
        bhi += l1;
    }
    dev += 1e-9 * (mag + fabs(blo) + fabs(bhi)); /* rounding of the sums */
    *vmin = blo - dev;
    *vmax = bhi + dev;
    return WVOL_OK;
}

/* Class of the closed box of cell idx (side `side` voxels): 1 when f^ > iso on all of it,
 * 0 when f^ < iso, -1 undecided. */
static int box_class(const tracer *tr, wvol_store_hits *hl, double side, const size_t idx[3], int *bad)
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz};
    double lo[3], hi[3], blo, bhi;
    int k;
    for (k = 0; k < 3; k++) {
        lo[k] = (double)idx[k] * side;
        hi[k] = fmin(lo[k] + side, n[k] > 1 ? (double)n[k] - 1 : 0.0);
    }
    if (wvol__iso_box_range(&tr->k, tr->g.s, hl, lo, hi, &blo, &bhi, NULL) != WVOL_OK) {
        (*bad)++;
        return -1;
    }
    return blo > tr->iso ? 1 : bhi < tr->iso ? 0 : -1;
}

/* Classifies cells of CELL voxels by wvol__iso_box_range, then halves the undecided ones
 * (cells of CELL/2; the decided ones pass their class on). Threads over cells. */
static wvol_status build_cells(tracer *tr, int nth, wvol_error *err)
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz}, nc[3], total = 1, ftotal = 1;
    signed char *coarse;
    int a, bad = 0;
    for (a = 0; a < 3; a++) {
        nc[a] = n[a] > 1 ? (size_t)ceil(((double)n[a] - 1) / CELL) : 1;
        tr->nc[a] = n[a] > 1 ? (size_t)ceil(((double)n[a] - 1) / (0.5 * CELL)) : 1;
        total *= nc[a];
        ftotal *= tr->nc[a];
    }
    tr->cell = 0.5 * CELL;
    coarse = malloc(total);
    tr->cls = malloc(ftotal);
    if (!coarse || !tr->cls) {
        free(coarse);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "iso trace: out of memory for %zu cells", ftotal);
    }
#pragma omp parallel num_threads(nth) reduction(+ : bad)
    {
        wvol_store_hits hl;
        memset(&hl, 0, sizeof hl);
#pragma omp for schedule(dynamic, 16)
        for (long c = 0; c < (long)total; c++) {
            size_t idx[3] = {(size_t)c % nc[0], ((size_t)c / nc[0]) % nc[1], (size_t)c / (nc[0] * nc[1])};
            coarse[c] = (signed char)box_class(tr, &hl, CELL, idx, &bad);
        }
#pragma omp for schedule(dynamic, 64)
        for (long c = 0; c < (long)ftotal; c++) {
            size_t idx[3] = {(size_t)c % tr->nc[0], ((size_t)c / tr->nc[0]) % tr->nc[1],
                             (size_t)c / (tr->nc[0] * tr->nc[1])};
            size_t p = idx[0] / 2 + nc[0] * (idx[1] / 2 + nc[1] * (idx[2] / 2));
            tr->cls[c] =
                coarse[p] >= 0 ? coarse[p] : (signed char)box_class(tr, &hl, 0.5 * CELL, idx, &bad);
        }
        wvol_store_hits_free(&hl);
    }
    free(coarse);
    WVOL_RETURN_IF(bad, err, WVOL_ERR_INTERNAL, "iso trace: store bounds failed on %d cells", bad);
    return WVOL_OK;
}

typedef struct sub {
    double u0, u1, B[NC];
} sub;

/* Splits the Bernstein coefficients B on [0, 1] at 1/2 into L and R (de Casteljau). */
static void casteljau(const double *B, double *L, double *R)
{
    double w[NC];
    int i, k;
    memcpy(w, B, sizeof w);
    L[0] = w[0];
    R[NC - 1] = w[NC - 1];
    for (k = 1; k < NC; k++) {
        for (i = 0; i < NC - k; i++) w[i] = 0.5 * (w[i] + w[i + 1]);
        L[k] = w[0];
        R[NC - 1 - k] = w[NC - 1 - k];
    }
}

/* Sign class of p(u) - iso: 1 when f^ >= iso. */
static int pos(const double *a, double u, double iso)
{
    return wvol__poly_eval(a, u) >= iso;
}

/* Bisection of p - iso on [u0, u1] where the ends differ in class, to a length <= du. */
static double bisect(const double *a, double iso, double u0, double u1, double du, int *evals)
{
    int s0 = pos(a, u0, iso);
    while (u1 - u0 > du) {
        double m = 0.5 * (u0 + u1);
        (*evals)++;
        if (pos(a, m, iso) == s0) u0 = m;
        else u1 = m;
    }
    return 0.5 * (u0 + u1);
}

/* The first crossing of p(u) = iso in [0, 1] (a piece of length len in t), or -1. */
static double piece_root(const tracer *tr, const double *a, double len, wvol_iso_hit *h)
{
    sub st[64];
    double B[NC], mag, pad, du = len > 0 ? tr->tol / len : 1.0;
    int sp = 0, j;
    mag = wvol__bernstein(&tr->g, a, B);
    pad = PAD_REL * (mag + fabs(tr->iso));
    st[0].u0 = 0;
    st[0].u1 = 1;
    for (j = 0; j < NC; j++) st[0].B[j] = B[j] - tr->iso;
    sp = 1;
    while (sp > 0) {
        sub c = st[--sp];
        int above = 0, below = 0, unsure = 0, V = 0, last = 0;
        h->intervals++;
        for (j = 0; j < NC; j++) {
            int sg = c.B[j] > pad ? 1 : c.B[j] < -pad ? -1 : 0;
            above += sg > 0;
            below += sg < 0;
            unsure += sg == 0;
            if (sg) {
                if (last && sg != last) V++;
                last = sg;
            }
        }
        if (above == NC || below == NC) continue; /* the hull excludes iso */
        if (!unsure && V == 1) return bisect(a, tr->iso, c.u0, c.u1, du, &h->evals);
        if (c.u1 - c.u0 <= du || sp + 2 > (int)(sizeof st / sizeof st[0])) {
            /* undecided at the tolerance: a sign change at the ends or inside is a hit */
            int k, s0 = pos(a, c.u0, tr->iso);
            for (k = 1; k <= 9; k++) {
                double u = c.u0 + (c.u1 - c.u0) * k / 9.0;
                h->evals++;
                if (pos(a, u, tr->iso) != s0) return bisect(a, tr->iso, c.u0 + (c.u1 - c.u0) * (k - 1) / 9.0, u, du, &h->evals);
            }
            h->grazes++;
            continue;
        }
        {
            double m = 0.5 * (c.u0 + c.u1);
            sub *R = &st[sp++], *L = &st[sp++];
            casteljau(c.B, L->B, R->B);
            L->u0 = c.u0, L->u1 = m;
            R->u0 = m, R->u1 = c.u1;
        }
    }
    return -1.0;
}

/* Gradient-free normal (Haar: f^ is piecewise constant): central differences over a voxel. */
static void fd_gradient(const tracer *tr, const double x[3], double g[3])
{
    int a;
    for (a = 0; a < 3; a++) {
        double p[3] = {x[0], x[1], x[2]}, q[3] = {x[0], x[1], x[2]};
        p[a] += 0.5;
        q[a] -= 0.5;
        g[a] = tr->g.info.transformed[a] ? wvol_store_eval(tr->g.s, p, NULL) - wvol_store_eval(tr->g.s, q, NULL) : 0.0;
    }
}

static void set_hit(const tracer *tr, const double o[3], const double d[3], const double ov[3], const double dv[3],
                    double t, wvol_iso_hit *h)
{
    double x[3], g[3], gw[3], len = 0.0;
    int a;
    h->hit = 1;
    h->t = t;
    for (a = 0; a < 3; a++) x[a] = ov[a] + t * dv[a];
    h->value = wvol_store_eval(tr->g.s, x, g);
    if (tr->g.b->exact || (g[0] == 0.0 && g[1] == 0.0 && g[2] == 0.0)) fd_gradient(tr, x, g);
    for (a = 0; a < 3; a++) {
        gw[a] = g[a] / tr->g.info.spacing[a];
        len += gw[a] * gw[a];
        h->pos[a] = o[a] + t * d[a];
    }
    len = sqrt(len);
    for (a = 0; a < 3; a++) h->normal[a] = len > 0 ? -gw[a] / len : 0.0;
}

/* Clips o + t d (voxel space), t >= tmin, to the sample extent [0, n-1] of the transformed
 * axes: 1 and [*t0, *t1] when something is left. */
static int clip(const tracer *tr, const double ov[3], const double dv[3], double tmin, double *t0, double *t1)
{
    size_t n[3] = {tr->g.info.nx, tr->g.info.ny, tr->g.info.nz};
    double a0 = tmin, a1 = INFINITY;
    int a;
    for (a = 0; a < 3; a++) {
        double lo = 0.0, hi = (double)n[a] - 1.0, ta, tb;
        if (!tr->g.info.transformed[a]) continue;
        if (dv[a] == 0.0) {
            if (!(ov[a] >= lo && ov[a] <= hi)) return 0;
            continue;
        }
        ta = (lo - ov[a]) / dv[a];
        tb = (hi - ov[a]) / dv[a];
        if (ta > tb) {
            double tmp = ta;
            ta = tb, tb = tmp;
        }
        if (ta > a0) a0 = ta;
        if (tb < a1) a1 = tb;
    }
    *t0 = a0;
    *t1 = a1;
    return a0 < a1 && isfinite(a0) && isfinite(a1);
}

/* Per-thread scratch. */
typedef struct tws {
    wvol__spline_ws s;
    double *env;        /* per level-1 piece: sum of |c| max|w| of the small functions covering it */
    size_t capE;
    double *cut;        /* cell boundaries along the ray */
    size_t capC;
} tws;

static void tws_free(tws *w)
{
    wvol__spline_ws_free(&w->s);
    free(w->env);
    free(w->cut);
    memset(w, 0, sizeof *w);
}

/* The class of f^ on piece e from the big functions' polynomial and the small ones'
 * envelope: 1 (surely >= iso), 0 (surely < iso) or -1 (undecided). */
static int decide(const tracer *tr, const double *a, double env)
{
    double B[NC], lo = INFINITY, hi = -INFINITY, pad;
    int j;
    pad = PAD_REL * (wvol__bernstein(&tr->g, a, B) + fabs(tr->iso) + env);
    for (j = 0; j < NC; j++) lo = fmin(lo, B[j]), hi = fmax(hi, B[j]);
    if (lo - env - tr->iso > pad) return 1;
    if (hi + env - tr->iso < -pad) return 0;
    return -1;
}

/* First piece index e with T[e + 1] > t (T has E + 1 breakpoints). */
static size_t piece_at(const double *T, size_t E, double t)
{
    size_t lo = 0, hi = E;
    while (lo < hi) {
        size_t m = (lo + hi) / 2;
        if (T[m + 1] > t) hi = m;
        else lo = m + 1;
    }
    return lo;
}

/* The cut tau: functions with |c| max|w| <= tau are "small"; together they sum to at most
 * SMALL_BUDGET of the largest one (buckets by binary exponent, smallest first). */
static double small_cut(const wvol_store_hit *hits, size_t n, const tracer *tr, double wmax)
{
    enum { NB = 80 };
    double sum[NB], acc = 0, budget = SMALL_BUDGET * wmax;
    size_t i;
    int k, ex;
    if (!(wmax > 0)) return 0;
    memset(sum, 0, sizeof sum);
    frexp(wmax, &ex);
    for (i = 0; i < n; i++) {
        double wb = fabs((double)hits[i].value) * tr->k.fb[hits[i].level][hits[i].band];
        int e;
        if (!(wb > 0)) continue;
        frexp(wb, &e);
        k = ex - e; /* 0: the largest bucket */
        sum[k < NB - 1 ? k : NB - 1] += wb;
    }
    for (k = NB - 1; k > 0; k--) {
        if (acc + sum[k] > budget) break;
        acc += sum[k];
    }
    /* buckets k+1.. are small: wb < 2^(ex - k - 1) */
    return ldexp(1.0, ex - k - 1);
}

/* d: unit world direction. Chunk by chunk: the big functions (the low-pass band and details
 * with |c| max|w| above TAU_REL of the chunk's largest) are expanded into polynomials, the
 * small ones only bound per piece (their |c| max|w| summed over the pieces they cover). A
 * piece whose polynomial's Bernstein hull, widened by that bound, excludes iso is decided
 * whole; runs of undecided pieces get the small functions added exactly and are searched. */
static wvol_status trace_span(const tracer *tr, tws *w, const double o[3], const double d[3], const double ov[3],
                              const double dv[3], double t0, double t1, double speed, int *prevp, wvol_iso_hit *h,
                              wvol_error *err)
{
    double ta;
    int prev = *prevp;
    for (ta = t0; ta < t1;) {
        double tb = ta + tr->chunk / speed, wmax = 0, wsum = 0, tau;
        wvol_store_hit *hits;
        wvol__spline_count cnt = {0, 0};
        const wvol__level_ws *F = &w->s.lev[1];
        size_t n, nb = 0, i, e, E;
        if (tb > t1 || t1 - tb < 1e-9 * (t1 - t0)) tb = t1;
        WVOL_FORWARD(wvol_store_query_ray(tr->g.s, ov, dv, ta, tb, &w->s.hits, err));
        hits = w->s.hits.hits;
        n = w->s.hits.count;
        for (i = 0; i < n; i++) {
            double wb = fabs((double)hits[i].value) * tr->k.fb[hits[i].level][hits[i].band];
            if (wb > wmax) wmax = wb;
        }
        tau = small_cut(hits, n, tr, wmax);
        for (i = 0; i < n; i++) /* big ones first */
            if (fabs((double)hits[i].value) * tr->k.fb[hits[i].level][hits[i].band] >= tau) {
                wvol_store_hit tmp = hits[nb];
                hits[nb++] = hits[i];
                hits[i] = tmp;
            }
        WVOL_FORWARD(wvol__spline_build(&tr->g, &w->s, ov, dv, ta, tb, hits, nb, 0, 1, &cnt, err));
        E = F->E;
        h->pieces += E;
        if (E + 1 > w->capE) {
            double *q = realloc(w->env, (E + 1) * sizeof *q);
            WVOL_RETURN_IF(!q, err, WVOL_ERR_NOMEM, "iso trace: out of memory");
            w->env = q;
            w->capE = E + 1;
        }
        memset(w->env, 0, (E + 1) * sizeof *w->env);
        for (i = nb; i < n; i++) { /* difference array, then prefix sums */
            double wb = fabs((double)hits[i].value) * tr->k.fb[hits[i].level][hits[i].band];
            size_t e0 = piece_at(F->T, E, hits[i].t0), e1 = piece_at(F->T, E, hits[i].t1);
            if (e0 >= E) continue;
            if (e1 >= E) e1 = E - 1;
            w->env[e0] += wb;
            wsum += wb;
            w->env[e1 + 1] -= wb;
        }
        for (e = 1; e < E; e++) w->env[e] += w->env[e - 1];
        /* the prefix sums' rounding: n * DBL_EPSILON of the total at most */
        for (e = 0; e < E; e++) w->env[e] = w->env[e] + 1e-11 * wsum;
        for (e = 0; e < E;) {
            int cls = decide(tr, w->s.macc + e * NC, w->env[e]);
            size_t e2, q;
            if (cls >= 0) {
                if (prev >= 0 && prev != cls) { /* a jump across iso at the piece boundary */
                    set_hit(tr, o, d, ov, dv, F->T[e], h);
                    h->functions += cnt.functions;
                    return WVOL_OK;
                }
                prev = cls;
                e++;
                continue;
            }
            for (e2 = e + 1; e2 < E && e2 - e < RUN_MAX && decide(tr, w->s.macc + e2 * NC, w->env[e2]) < 0;)
                e2++;
            for (i = nb; i < n; i++)
                if (hits[i].t1 >= F->T[e] && hits[i].t0 <= F->T[e2])
                    wvol__spline_add_finest(&tr->g, &w->s, ov, dv, &hits[i], e, e2, &cnt);
            h->refined += e2 - e;
            for (q = e; q < e2; q++) {
                const double *a = w->s.macc + q * NC;
                double len = F->T[q + 1] - F->T[q], u, last = 0;
                int k;
                if (!(len > 0)) continue;
                if (prev >= 0 && prev != (a[0] >= tr->iso)) {
                    set_hit(tr, o, d, ov, dv, F->T[q], h);
                    h->functions += cnt.functions;
                    return WVOL_OK;
                }
                u = piece_root(tr, a, len, h);
                if (u >= 0) {
                    set_hit(tr, o, d, ov, dv, F->T[q] + u * len, h);
                    h->functions += cnt.functions;
                    return WVOL_OK;
                }
                for (k = 0; k < NC; k++) last += a[k];
                prev = last >= tr->iso;
            }
            e = e2;
        }
        h->functions += cnt.functions;
        ta = tb;
    }
    *prevp = prev;
    return WVOL_OK;
}

/* Crossings of the cell planes x_a = C k inside (t0, t1), merged with t0 and t1 into w->cut. */
static size_t cell_cuts(const tracer *tr, tws *w, const double ov[3], const double dv[3], double t0, double t1)
{
    size_t n = 0, cap = 8;
    int a;
    for (a = 0; a < 3; a++)
        if (dv[a] != 0.0 && tr->g.info.transformed[a])
            cap += (size_t)(fabs((t1 - t0) * dv[a]) / tr->cell) + 2;
    if (cap > w->capC) {
        double *q = realloc(w->cut, cap * sizeof *q);
        if (!q) return 0;
        w->cut = q;
        w->capC = cap;
    }
    w->cut[n++] = t0;
    for (a = 0; a < 3; a++) {
        double x0, x1, k0, k1, k;
        if (dv[a] == 0.0 || !tr->g.info.transformed[a]) continue;
        x0 = ov[a] + t0 * dv[a];
        x1 = ov[a] + t1 * dv[a];
        k0 = floor(fmin(x0, x1) / tr->cell) + 1;
        k1 = ceil(fmax(x0, x1) / tr->cell) - 1;
        for (k = k0; k <= k1 && n < w->capC - 1; k++) {
            double t = (k * tr->cell - ov[a]) / dv[a];
            if (t > t0 && t < t1) w->cut[n++] = t;
        }
    }
    w->cut[n++] = t1;
    qsort(w->cut + 1, n - 2, sizeof *w->cut, cmp_double);
    return n;
}

/* The class of f^ in the cell holding x (voxel coords): 1, 0 or -1 (undecided). */
static int cell_class(const tracer *tr, const double x[3])
{
    size_t idx = 0, stride = 1;
    int a;
    for (a = 0; a < 3; a++) {
        double c = floor(x[a] / tr->cell);
        size_t ci = c < 0 ? 0 : (size_t)c;
        if (ci >= tr->nc[a]) ci = tr->nc[a] - 1;
        idx += ci * stride;
        stride *= tr->nc[a];
    }
    return tr->cls[idx];
}

/* d: unit world direction. With the cell grid, cells whose rigorous bounds exclude iso are
 * stepped over; runs of the others are traced exactly (trace_span). */
static wvol_status trace(const tracer *tr, tws *w, const double o[3], const double d[3], double tmin, wvol_iso_hit *h,
                         wvol_error *err)
{
    double ov[3], dv[3], t0, t1, speed;
    size_t n, i;
    int prev = -1; /* class of f^ at the end of what is done, -1 before the start */
    memset(h, 0, sizeof *h);
    h->t = INFINITY;
    wvol_store_world_to_voxel(tr->g.s, o, ov);
    wvol_store_dir_to_voxel(tr->g.s, d, dv);
    speed = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
    if (!(speed > 0) || !clip(tr, ov, dv, tmin, &t0, &t1)) return WVOL_OK;
    if (!tr->cls) return trace_span(tr, w, o, d, ov, dv, t0, t1, speed, &prev, h, err);
    n = cell_cuts(tr, w, ov, dv, t0, t1);
    WVOL_RETURN_IF(n < 2, err, WVOL_ERR_NOMEM, "iso trace: out of memory");
    for (i = 0; i + 1 < n;) {
        double tm = 0.5 * (w->cut[i] + w->cut[i + 1]), x[3];
        size_t j;
        int a, cls;
        for (a = 0; a < 3; a++) x[a] = ov[a] + tm * dv[a];
        cls = cell_class(tr, x);
        if (cls >= 0) {
            if (prev >= 0 && prev != cls) { /* a jump across iso on the cell face */
                set_hit(tr, o, d, ov, dv, w->cut[i], h);
                return WVOL_OK;
            }
            prev = cls;
            i++;
            continue;
        }
        for (j = i + 1; j + 1 < n; j++) { /* the run of undecided cells */
            double tj = 0.5 * (w->cut[j] + w->cut[j + 1]);
            for (a = 0; a < 3; a++) x[a] = ov[a] + tj * dv[a];
            if (cell_class(tr, x) >= 0) break;
        }
        WVOL_FORWARD(trace_span(tr, w, o, d, ov, dv, w->cut[i], w->cut[j], speed, &prev, h, err));
        if (h->hit) return WVOL_OK;
        i = j;
    }
    return WVOL_OK;
}

static wvol_status make_tracer(tracer *tr, const wvol_store *s, double iso, const wvol_iso_trace_params *p,
                               wvol_error *err)
{
    double smin;
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "iso trace: store is NULL");
    WVOL_RETURN_IF(!isfinite(iso), err, WVOL_ERR_ARG, "iso trace: iso-value %g is not finite", iso);
    WVOL_RETURN_IF(p && (!isfinite(p->tolerance) || !isfinite(p->chunk) || p->chunk < 0), err, WVOL_ERR_ARG,
                   "iso trace: tolerance %g / chunk %g not valid", p->tolerance, p->chunk);
    memset(tr, 0, sizeof *tr);
    WVOL_FORWARD(wvol__spline_geom_init(&tr->g, s, err));
    tr->iso = iso;
    smin = fmin(tr->g.info.spacing[0], fmin(tr->g.info.spacing[1], tr->g.info.spacing[2]));
    tr->tol = p && p->tolerance > 0 ? p->tolerance : 1e-3 * smin;
    tr->chunk = p && p->chunk > 0 ? p->chunk : 16.0;
    wvol__iso_boxk_init(&tr->k, s);
    return WVOL_OK;
}

wvol_status wvol_iso_trace_ray(const wvol_store *s, double iso, const double o[3], const double d[3],
                               const wvol_iso_trace_params *p, wvol_iso_hit *hit, wvol_error *err)
{
    tracer tr;
    tws ws;
    double dn[3], len;
    wvol_status st;
    WVOL_RETURN_IF(!o || !d || !hit, err, WVOL_ERR_ARG, "iso trace: NULL argument");
    WVOL_RETURN_IF(!isfinite(o[0]) || !isfinite(o[1]) || !isfinite(o[2]), err, WVOL_ERR_ARG,
                   "iso trace: ray origin is not finite");
    WVOL_FORWARD(make_tracer(&tr, s, iso, p, err));
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    WVOL_RETURN_IF(!(len > 0) || !isfinite(len), err, WVOL_ERR_ARG, "iso trace: direction has no length");
    dn[0] = d[0] / len, dn[1] = d[1] / len, dn[2] = d[2] / len;
    memset(&ws, 0, sizeof ws);
    st = trace(&tr, &ws, o, dn, 0.0, hit, err);
    tws_free(&ws);
    return st;
}

/* The empty-image message. Every cell decided alike proves iso outside the range of f^;
 * otherwise the samples of the reconstruction (which f^ interpolates to the spline's error)
 * tell whether iso is outside the data's range. */
static void empty_message(const tracer *tr, double iso, char *msg, size_t cap)
{
    size_t i, total = tr->nc[0] * tr->nc[1] * tr->nc[2], cnt[3] = {0, 0, 0};
    wvol_coeffs *c = NULL;
    wvol_volume *v = NULL;
    double vmin = 0, vmax = 0;
    for (i = 0; i < total; i++) cnt[tr->cls[i] + 1]++;
    if (cnt[1] == total || cnt[2] == total) {
        snprintf(msg, cap, "iso-value %.9g is %s f^ everywhere (rigorous bounds): empty image", iso,
                 cnt[1] == total ? "above" : "below");
        return;
    }
    if (wvol_store_densify(tr->g.s, &c, NULL) == WVOL_OK && wvol_idwt3(&v, c, NULL) == WVOL_OK) {
        wvol_volume_range(v, &vmin, &vmax, NULL);
        if (iso < vmin || iso > vmax)
            snprintf(msg, cap, "iso-value %.9g is outside the range [%.9g, %.9g] of the reconstructed samples: empty image",
                     iso, vmin, vmax);
        else
            snprintf(msg, cap, "no ray meets the surface f^ = %.9g (samples range over [%.9g, %.9g]): empty image", iso,
                     vmin, vmax);
    } else {
        snprintf(msg, cap, "no ray meets the surface f^ = %.9g: empty image", iso);
    }
    wvol_volume_destroy(v);
    wvol_coeffs_destroy(c);
}

wvol_status wvol_iso_raytrace(wvol_image *img, float *depth, float *normals, const wvol_store *s,
                              const wvol_camera *cam, double iso, const wvol_iso_trace_params *p,
                              wvol_iso_trace_stats *st, wvol_error *err)
{
    tracer tr;
    wvol_iso_trace_params def;
    wvol__cam k;
    int nth, failed = 0;
    size_t hits = 0, functions = 0, pieces = 0, refined = 0, intervals = 0, evals = 0, grazes = 0;
    double t_start = wvol__now(), c_start = wvol__cpu_now(), tmin, t_cells;
    wvol_error first_err;
    WVOL_RETURN_IF(!img || !img->rgba, err, WVOL_ERR_ARG, "iso trace: no image");
    WVOL_RETURN_IF(!cam, err, WVOL_ERR_ARG, "iso trace: no camera");
    WVOL_FORWARD(wvol_camera_check(cam, err));
    WVOL_RETURN_IF(cam->width != img->width || cam->height != img->height, err, WVOL_ERR_ARG,
                   "iso trace: image %dx%d does not match the camera's %dx%d", img->width, img->height, cam->width,
                   cam->height);
    if (!p) {
        wvol_iso_trace_params_default(&def);
        p = &def;
    }
    WVOL_FORWARD(make_tracer(&tr, s, iso, p, err));
    nth = wvol__threads(p->threads);
    if (build_cells(&tr, nth, err) != WVOL_OK) {
        free(tr.cls);
        return err ? err->status : WVOL_ERR_INTERNAL;
    }
    t_cells = wvol__now() - t_start;
    wvol__cam_init(&k, cam);
    /* an orthographic ray is the whole line (as in the renderer); a perspective one starts at the eye */
    tmin = cam->projection == WVOL_PERSPECTIVE ? 0.0 : -INFINITY;
    wvol_error_clear(&first_err);
#pragma omp parallel num_threads(nth) reduction(+ : hits, functions, pieces, refined, intervals, evals, grazes)
    {
        tws ws;
        memset(&ws, 0, sizeof ws);
#pragma omp for schedule(dynamic, 1)
        for (int row = 0; row < img->height; row++) {
            for (int x = 0; x < img->width; x++) {
                double o[3], d[3], l[3], ll = 0.0, lam = 0.0;
                wvol_iso_hit h;
                size_t px = (size_t)row * (size_t)img->width + (size_t)x;
                float *c = img->rgba + 4 * px;
                int a;
                wvol_error e2;
                wvol__cam_ray(&k, x + 0.5, row + 0.5, o, d);
                memset(&h, 0, sizeof h);
                if (!failed && trace(&tr, &ws, o, d, tmin, &h, &e2) != WVOL_OK) {
#pragma omp critical(wvol_iso_err)
                    if (!failed) {
                        failed = 1;
                        first_err = e2;
                    }
                }
                functions += h.functions;
                pieces += h.pieces;
                refined += h.refined;
                intervals += h.intervals;
                evals += (size_t)h.evals;
                grazes += (size_t)h.grazes;
                if (depth) depth[px] = h.hit ? (float)h.t : INFINITY;
                if (normals)
                    for (a = 0; a < 3; a++) normals[3 * px + a] = h.hit ? (float)h.normal[a] : 0.0f;
                if (!h.hit) {
                    c[0] = c[1] = c[2] = c[3] = 0.0f;
                    continue;
                }
                hits++;
                for (a = 0; a < 3; a++) {
                    l[a] = (p->light[0] || p->light[1] || p->light[2]) ? p->light[a] : -d[a];
                    ll += l[a] * l[a];
                }
                ll = sqrt(ll);
                for (a = 0; a < 3; a++) lam += h.normal[a] * l[a] / ll;
                lam = fabs(lam); /* two-sided */
                for (a = 0; a < 3; a++) c[a] = (float)(p->color[a] * (p->ambient + (1.0 - p->ambient) * lam));
                c[3] = 1.0f;
            }
        }
        tws_free(&ws);
    }
    if (failed) {
        free(tr.cls);
        if (err) *err = first_err;
        return first_err.status ? first_err.status : WVOL_ERR_INTERNAL;
    }
    if (st) {
        memset(st, 0, sizeof *st);
        st->rays = (size_t)img->width * (size_t)img->height;
        st->hits = hits;
        st->functions = functions;
        st->pieces = pieces;
        st->refined = refined;
        st->intervals = intervals;
        st->evals = evals;
        st->grazes = grazes;
        st->seconds = wvol__now() - t_start;
        st->cpu_seconds = wvol__cpu_now() - c_start;
        st->seconds_cells = t_cells;
        if (hits == 0) empty_message(&tr, iso, st->message, sizeof st->message);
        st->seconds = wvol__now() - t_start;
    }
    free(tr.cls);
    return WVOL_OK;
}

wvol_status wvol_iso_render_hybrid(wvol_image *img, float *depth, const wvol_store *s, const wvol_camera *cam,
                                   const wvol_tf *tf, double iso, const wvol_render_params *rp,
                                   const wvol_iso_trace_params *tp, wvol_iso_trace_stats *tstats,
                                   wvol_render_stats *rstats, wvol_error *err)
{
    wvol_image *surf = NULL;
    float *z = depth;
    wvol_status stt;
    size_t i, n;
    WVOL_RETURN_IF(!img || !cam, err, WVOL_ERR_ARG, "iso hybrid: no image or camera");
    WVOL_FORWARD(wvol_image_create(&surf, img->width, img->height, err));
    n = (size_t)img->width * (size_t)img->height;
    if (!z) z = malloc(n * sizeof *z);
    if (!z) {
        wvol_image_destroy(surf);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "iso hybrid: out of memory for the depth buffer");
    }
    stt = wvol_iso_raytrace(surf, z, NULL, s, cam, iso, tp, tstats, err);
    /* the volume in front of the surface (the whole ray where there is none) */
    if (stt == WVOL_OK) stt = wvol_render_spline_until(img, s, cam, tf, rp, z, rstats, err);
    if (stt == WVOL_OK)
        for (i = 0; i < n; i++) { /* premultiplied "over": volume in front, opaque surface behind */
            float *v = img->rgba + 4 * i;
            const float *f = surf->rgba + 4 * i;
            float T = 1.0f - v[3];
            int ch;
            for (ch = 0; ch < 4; ch++) v[ch] += T * f[ch];
        }
    if (z != depth) free(z);
    wvol_image_destroy(surf);
    return stt;
}
