/* SPDX-License-Identifier: MIT */
/* Queries on the store's octree: kept basis functions touching a box or a ray
 * segment, rigorous bounds of f^ and its gradient on a box, point evaluation.
 *
 * Periodic wrap without splitting: a basis function's periodic images are
 * indexed by an unbounded integer j per axis (position p = j mod E, support
 * [2^m j - s, 2^m (j + L - 1) - s]). The roots' j ranges that can meet the query
 * follow in closed form from its bounding box; a child of image j is image
 * 2j + bit, and a child's support lies inside its parent's, so descending an
 * image never misses and never repeats a function image.
 * Based on: Lewis & Fournier 7.2.4.1 (reject impossible interactions before any
 * integration); Kalra & Barr 1989 (value and Lipschitz bounds for ray tracing). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "store/store_internal.h"

typedef struct trav trav;
/* One node (or low-pass function) image that meets the query: mask bit l = band l
 * present, vals in increasing band order. */
typedef void (*visit_fn)(const trav *tv, void *arg, int m, unsigned mask, const float *vals, const size_t pos[3],
                         const double lo[3], const double hi[3], double t0, double t1);

struct trav {
    const wvol_store *s;
    int ray;
    double a[3], b[3];               /* the box, or the segment's bounding box */
    double o[3], d[3], tmin, tmax;   /* ray */
    visit_fn fn;
    void *arg;
};

static inline void image_box(const wvol_store *s, int m, const int64_t j[3], double lo[3], double hi[3])
{
    for (int a = 0; a < 3; a++) {
        if (s->ly.tr[a]) {
            lo[a] = (double)j[a] * s->pow2[m] - s->ly.s;
            hi[a] = (double)(j[a] + s->ly.L - 1) * s->pow2[m] - s->ly.s;
        } else {
            lo[a] = -INFINITY, hi[a] = INFINITY;
        }
    }
}

static inline int meets(const trav *tv, const double lo[3], const double hi[3], double *t0, double *t1)
{
    if (!tv->ray) {
        for (int a = 0; a < 3; a++)
            if (hi[a] < tv->a[a] || lo[a] > tv->b[a]) return 0;
        *t0 = *t1 = 0.0;
        return 1;
    }
    double u0 = tv->tmin, u1 = tv->tmax;
    for (int a = 0; a < 3; a++) {
        if (lo[a] == -INFINITY) continue;
        if (tv->d[a] == 0.0) {
            if (tv->o[a] < lo[a] || tv->o[a] > hi[a]) return 0;
            continue;
        }
        double ta = (lo[a] - tv->o[a]) / tv->d[a], tb = (hi[a] - tv->o[a]) / tv->d[a];
        if (ta > tb) {
            double t = ta;
            ta = tb, tb = t;
        }
        if (ta > u0) u0 = ta;
        if (tb < u1) u1 = tb;
        if (u0 > u1) return 0;
    }
    *t0 = u0, *t1 = u1;
    return 1;
}

static inline size_t pmod(int64_t j, size_t e)
{
    int64_t r = j % (int64_t)e;
    return (size_t)(r < 0 ? r + (int64_t)e : r);
}

static void descend(const trav *tv, size_t ni, int m, const int64_t j[3])
{
    const wvol_store *s = tv->s;
    const wvol__node *nd = s->nodes + ni;
    double lo[3], hi[3], t0, t1;
    image_box(s, m, j, lo, hi);
    if (!meets(tv, lo, hi, &t0, &t1)) return;
    if (nd->band_mask) {
        size_t pos[3];
        wvol__key_pos(nd->key, pos);
        tv->fn(tv, tv->arg, m, (unsigned)nd->band_mask << 1, s->values + nd->coef_first, pos, lo, hi, t0, t1);
    }
    if (!nd->child_mask) return;
    for (int ci = 0, k = 0; ci < 8; ci++) {
        int64_t cj[3];
        if (!((nd->child_mask >> ci) & 1)) continue;
        for (int a = 0; a < 3; a++) cj[a] = s->ly.tr[a] ? 2 * j[a] + ((ci >> a) & 1) : 0;
        descend(tv, nd->child_first + (size_t)k++, m - 1, cj);
    }
}

/* Refuses boxes that are not finite or span more than 16 periods on an axis
 * (every image would be returned, one per period). */
static wvol_status check_extent(const wvol_store *s, const double a[3], const double b[3], wvol_error *err)
{
    for (int x = 0; x < 3; x++) {
        WVOL_RETURN_IF(!isfinite(a[x]) || !isfinite(b[x]), err, WVOL_ERR_ARG, "store query: non-finite bounds on axis %d",
                       x);
        WVOL_RETURN_IF(b[x] - a[x] > 16.0 * (double)s->ly.P[x] + 2.0 * (s->ly.L - 1) * ldexp(1.0, s->ly.levels), err,
                       WVOL_ERR_ARG, "store query: extent %g on axis %d spans more than 16 periods (%zu)",
                       b[x] - a[x], x, s->ly.P[x]);
    }
    return WVOL_OK;
}

/* One root-level image: its low-pass function, then the root node's subtree. */
static void root_image(const trav *tv, const int64_t j[3])
{
    const wvol_store *s = tv->s;
    int M = s->ly.levels;
    double lo[3], hi[3], t0, t1;
    size_t pos[3], i;
    image_box(s, M, j, lo, hi);
    if (!meets(tv, lo, hi, &t0, &t1)) return;
    for (int a = 0; a < 3; a++) pos[a] = s->ly.tr[a] ? pmod(j[a], s->E[a]) : 0;
    i = pos[0] + s->E[0] * (pos[1] + s->E[1] * pos[2]);
    tv->fn(tv, tv->arg, M, 1u, s->lowpass + i, pos, lo, hi, t0, t1);
    if (s->root_of[i] >= 0) descend(tv, (size_t)s->root_of[i], M, j);
}

/* Root images j along axis a whose slab can hold [x0, x1]. */
static inline void root_range(const wvol_store *s, int a, double x0, double x1, int64_t *j0, int64_t *j1)
{
    double unit = s->pow2[s->ly.levels];
    if (!s->ly.tr[a]) {
        *j0 = *j1 = 0;
        return;
    }
    *j0 = (int64_t)ceil((x0 + s->ly.s) / unit - (s->ly.L - 1));
    *j1 = (int64_t)floor((x1 + s->ly.s) / unit);
}

/* Rays: the root images are enumerated axis by axis, each axis' slab narrowing
 * the parameter interval, so a long oblique ray costs what it meets rather than
 * the volume of its bounding box. */
static void ray_roots(const trav *tv, int a, double u0, double u1, int64_t j[3])
{
    const wvol_store *s = tv->s;
    int64_t j0, j1;
    if (a == 3) {
        root_image(tv, j);
        return;
    }
    double p0 = tv->o[a] + u0 * tv->d[a], p1 = tv->o[a] + u1 * tv->d[a];
    root_range(s, a, wvol__min(p0, p1), wvol__max(p0, p1), &j0, &j1);
    for (j[a] = j0; j[a] <= j1; j[a]++) {
        double v0 = u0, v1 = u1;
        if (s->ly.tr[a] && tv->d[a] != 0.0) {
            double lo = (double)j[a] * s->pow2[s->ly.levels] - s->ly.s;
            double hi = (double)(j[a] + s->ly.L - 1) * s->pow2[s->ly.levels] - s->ly.s;
            double ta = (lo - tv->o[a]) / tv->d[a], tb = (hi - tv->o[a]) / tv->d[a];
            if (ta > tb) {
                double t = ta;
                ta = tb, tb = t;
            }
            v0 = wvol__max(v0, ta), v1 = wvol__min(v1, tb);
            if (v0 > v1) continue;
        }
        ray_roots(tv, a + 1, v0, v1, j);
    }
}

static void traverse(const trav *tv)
{
    int64_t j0[3], j1[3], j[3];
    if (tv->ray) {
        ray_roots(tv, 0, tv->tmin, tv->tmax, j);
        return;
    }
    for (int a = 0; a < 3; a++) root_range(tv->s, a, tv->a[a], tv->b[a], j0 + a, j1 + a);
    for (j[2] = j0[2]; j[2] <= j1[2]; j[2]++)
        for (j[1] = j0[1]; j[1] <= j1[1]; j[1]++)
            for (j[0] = j0[0]; j[0] <= j1[0]; j[0]++) root_image(tv, j);
}

/* ---- hit lists ----------------------------------------------------------------------------- */

void wvol_store_hits_free(wvol_store_hits *h)
{
    if (!h) return;
    free(h->hits);
    h->hits = NULL;
    h->count = h->capacity = 0;
}

typedef struct collect {
    wvol_store_hits *out;
    int oom;
} collect;

static void collect_fn(const trav *tv, void *arg, int m, unsigned mask, const float *vals, const size_t pos[3],
                       const double lo[3], const double hi[3], double t0, double t1)
{
    collect *cl = arg;
    wvol_store_hits *h = cl->out;
    int k = 0;
    if (cl->oom) return;
    for (int l = 0; l < 8; l++) {
        wvol_store_hit *e;
        if (!((mask >> l) & 1)) continue;
        if (h->count == h->capacity) {
            size_t cap = h->capacity ? 2 * h->capacity : 256;
            wvol_store_hit *n = realloc(h->hits, cap * sizeof *n);
            if (!n) {
                cl->oom = 1;
                return;
            }
            h->hits = n, h->capacity = cap;
        }
        e = h->hits + h->count++;
        memcpy(e->lo, lo, sizeof e->lo);
        memcpy(e->hi, hi, sizeof e->hi);
        e->t0 = t0, e->t1 = t1;
        e->norm = tv->s->norm[m];
        e->value = vals[k++];
        e->level = (uint8_t)m, e->band = (uint8_t)l;
        e->reserved = 0;
        e->p = (uint32_t)pos[0], e->q = (uint32_t)pos[1], e->r = (uint32_t)pos[2];
    }
}

wvol_status wvol_store_query_box(const wvol_store *s, const double lo[3], const double hi[3], wvol_store_hits *out,
                                 wvol_error *err)
{
    trav tv;
    collect cl = {out, 0};
    WVOL_RETURN_IF(!s || !lo || !hi || !out, err, WVOL_ERR_ARG, "wvol_store_query_box: NULL argument");
    WVOL_RETURN_IF(s->file, err, WVOL_ERR_UNSUPPORTED,
                   "%s: a store opened on a .wvc file is read through brick reconstructions only (bricked render, "
                   "marching cubes); build a store in memory for this", "wvol_store_query_box");
    out->count = 0;
    WVOL_FORWARD(check_extent(s, lo, hi, err));
    memset(&tv, 0, sizeof tv);
    tv.s = s, tv.fn = collect_fn, tv.arg = &cl;
    for (int a = 0; a < 3; a++) {
        WVOL_RETURN_IF(lo[a] > hi[a], err, WVOL_ERR_ARG, "wvol_store_query_box: lo %g > hi %g on axis %d", lo[a], hi[a], a);
        tv.a[a] = lo[a], tv.b[a] = hi[a];
    }
    traverse(&tv);
    WVOL_RETURN_IF(cl.oom, err, WVOL_ERR_NOMEM, "wvol_store_query_box: out of memory for %zu hits", out->count);
    return WVOL_OK;
}

wvol_status wvol_store_query_ray(const wvol_store *s, const double o[3], const double d[3], double tmin, double tmax,
                                 wvol_store_hits *out, wvol_error *err)
{
    trav tv;
    collect cl = {out, 0};
    WVOL_RETURN_IF(!s || !o || !d || !out, err, WVOL_ERR_ARG, "wvol_store_query_ray: NULL argument");
    WVOL_RETURN_IF(s->file, err, WVOL_ERR_UNSUPPORTED,
                   "%s: a store opened on a .wvc file is read through brick reconstructions only (bricked render, "
                   "marching cubes); build a store in memory for this", "wvol_store_query_ray");
    out->count = 0;
    WVOL_RETURN_IF(!isfinite(tmin) || !isfinite(tmax) || tmin > tmax, err, WVOL_ERR_ARG,
                   "wvol_store_query_ray: bad parameter interval [%g, %g]", tmin, tmax);
    memset(&tv, 0, sizeof tv);
    tv.s = s, tv.fn = collect_fn, tv.arg = &cl, tv.ray = 1, tv.tmin = tmin, tv.tmax = tmax;
    for (int a = 0; a < 3; a++) {
        WVOL_RETURN_IF(!isfinite(o[a]) || !isfinite(d[a]), err, WVOL_ERR_ARG, "wvol_store_query_ray: non-finite ray");
        double p0 = o[a] + tmin * d[a], p1 = o[a] + tmax * d[a];
        tv.o[a] = o[a], tv.d[a] = d[a];
        tv.a[a] = p0 < p1 ? p0 : p1, tv.b[a] = p0 < p1 ? p1 : p0;
    }
    WVOL_FORWARD(check_extent(s, tv.a, tv.b, err));
    traverse(&tv);
    WVOL_RETURN_IF(cl.oom, err, WVOL_ERR_NOMEM, "wvol_store_query_ray: out of memory for %zu hits", out->count);
    return WVOL_OK;
}

/* ---- bounds ------------------------------------------------------------------------------ */

typedef struct iv {
    double lo, hi;
} iv;

static inline iv imul(iv x, iv y)
{
    double a = x.lo * y.lo, b = x.lo * y.hi, c = x.hi * y.lo, d = x.hi * y.hi;
    iv r = {wvol__min(wvol__min(a, b), wvol__min(c, d)), wvol__max(wvol__max(a, b), wvol__max(c, d))};
    return r;
}

static inline double iabs(iv x) { return wvol__max(fabs(x.lo), fabs(x.hi)); }

/* The 1D factors of one axis on the box: ranges of phi, psi (R) and of their
 * derivatives per voxel (D), and phi, psi at the box centre (C). */
typedef struct axisf {
    iv R[2], D[2];
    double C[2];
} axisf;

/* Every node image at level m shares the factors of its j along each axis, and
 * only the j in [j0, j0 + span) can meet the box: they are computed once. */
#define BC_LEVELS 8
#define BC_SPAN 24

typedef struct bacc {
    double vmin, vmax, vabs, g[3];
    double centre[3], fc, fc_abs;   /* f^ at the box centre, and the sum of |terms| there */
    size_t touching;
    int64_t j0[BC_LEVELS + 1][3];
    unsigned char have[BC_LEVELS + 1][3][BC_SPAN];
    axisf cache[BC_LEVELS + 1][3][BC_SPAN];
} bacc;

static inline void spline4(const wvol_store *s, double u, double out[4]);

static void axis_factors(const wvol_store *s, const trav *tv, const bacc *ac, int m, int a, double lo, axisf *f)
{
    double scale = s->ipow2[m], u0 = (tv->a[a] - lo) * scale, u1 = (tv->b[a] - lo) * scale, c4[4];
    for (int w = 0; w < 2; w++) {
        wvol__ranges_query(&s->rg, w ? WVOL__PSI : WVOL__PHI, u0, u1, &f->R[w].lo, &f->R[w].hi);
        wvol__ranges_query(&s->rg, w ? WVOL__DPSI : WVOL__DPHI, u0, u1, &f->D[w].lo, &f->D[w].hi);
        f->D[w].lo *= scale, f->D[w].hi *= scale;
    }
    spline4(s, (ac->centre[a] - lo) * scale, c4);
    f->C[0] = c4[0], f->C[1] = c4[1];
}

static void bounds_fn(const trav *tv, void *arg, int m, unsigned mask, const float *vals, const size_t pos[3],
                      const double lo[3], const double hi[3], double t0, double t1)
{
    static const axisf unit = {{{1.0, 1.0}, {1.0, 1.0}}, {{0.0, 0.0}, {0.0, 0.0}}, {1.0, 1.0}};
    const wvol_store *s = tv->s;
    bacc *ac = arg;
    axisf local[3];
    const axisf *F[3];
    int k = 0;
    (void)pos, (void)hi, (void)t0, (void)t1;
    for (int a = 0; a < 3; a++) {
        if (!s->ly.tr[a]) {
            F[a] = &unit;
            continue;
        }
        if (m <= BC_LEVELS) {
            int64_t idx = (int64_t)floor((lo[a] + s->ly.s) * s->ipow2[m] + 0.5) - ac->j0[m][a];
            if (idx >= 0 && idx < BC_SPAN) {
                axisf *e = &ac->cache[m][a][idx];
                if (!ac->have[m][a][idx]) axis_factors(s, tv, ac, m, a, lo[a], e), ac->have[m][a][idx] = 1;
                F[a] = e;
                continue;
            }
        }
        axis_factors(s, tv, ac, m, a, lo[a], local + a);
        F[a] = local + a;
    }
    for (int l = 0; l < 8; l++) {
        if (!((mask >> l) & 1)) continue;
        double c = vals[k++], nm = s->norm[m], ac_ = fabs(c) * nm;
        int b0 = l & 1, b1 = (l >> 1) & 1, b2 = (l >> 2) & 1;
        double tc = c * nm * F[0]->C[b0] * F[1]->C[b1] * F[2]->C[b2];
        ac->fc += tc, ac->fc_abs += fabs(tc);
        iv ryz = imul(F[1]->R[b1], F[2]->R[b2]);
        iv v = imul(F[0]->R[b0], ryz);
        iv g0 = imul(F[0]->D[b0], ryz);
        iv g1 = imul(imul(F[0]->R[b0], F[1]->D[b1]), F[2]->R[b2]);
        iv g2 = imul(imul(F[0]->R[b0], F[1]->R[b1]), F[2]->D[b2]);
        double x = c * nm * v.lo, y = c * nm * v.hi;
        ac->vmin += wvol__min(x, y);
        ac->vmax += wvol__max(x, y);
        ac->vabs += ac_ * iabs(v);
        ac->g[0] += ac_ * iabs(g0);
        ac->g[1] += ac_ * iabs(g1);
        ac->g[2] += ac_ * iabs(g2);
        ac->touching++;
    }
}

wvol_status wvol_store_box_bounds(const wvol_store *s, const double lo[3], const double hi[3], wvol_store_bounds *out,
                                  wvol_error *err)
{
    trav tv;
    bacc ac;
    double margin;
    WVOL_RETURN_IF(!s || !lo || !hi || !out, err, WVOL_ERR_ARG, "wvol_store_box_bounds: NULL argument");
    WVOL_RETURN_IF(s->file, err, WVOL_ERR_UNSUPPORTED,
                   "%s: a store opened on a .wvc file is read through brick reconstructions only (bricked render, "
                   "marching cubes); build a store in memory for this", "wvol_store_box_bounds");
    memset(out, 0, sizeof *out);
    WVOL_FORWARD(check_extent(s, lo, hi, err));
    memset(&tv, 0, sizeof tv);
    ac.vmin = ac.vmax = ac.vabs = ac.fc = ac.fc_abs = 0.0;
    ac.g[0] = ac.g[1] = ac.g[2] = 0.0;
    ac.touching = 0;
    for (int m = 1; m <= s->ly.levels && m <= BC_LEVELS; m++)
        for (int a = 0; a < 3; a++) {
            ac.j0[m][a] = (int64_t)ceil((lo[a] + s->ly.s) * s->ipow2[m] - (s->ly.L - 1));
            memset(ac.have[m][a], 0, BC_SPAN);
        }
    tv.s = s, tv.fn = bounds_fn, tv.arg = &ac;
    for (int a = 0; a < 3; a++) {
        WVOL_RETURN_IF(lo[a] > hi[a], err, WVOL_ERR_ARG, "wvol_store_box_bounds: lo %g > hi %g on axis %d", lo[a], hi[a],
                       a);
        tv.a[a] = lo[a], tv.b[a] = hi[a];
        ac.centre[a] = 0.5 * (lo[a] + hi[a]);
    }
    traverse(&tv);
    /* rounding of the sums here and of any evaluation of f^ (terms <= vabs) */
    margin = 1e-10 * ac.vabs;
    out->vmin = ac.vmin - margin;
    out->vmax = ac.vmax + margin;
    out->vabs = ac.vabs + margin;
    out->grad_norm = 0.0;
    for (int a = 0; a < 3; a++) {
        out->grad[a] = ac.g[a] * (1.0 + 1e-10);
        out->grad_norm += out->grad[a] * out->grad[a];
    }
    out->grad_norm = sqrt(out->grad_norm) * (1.0 + 1e-12);
    /* centred form: f^ is continuous and piecewise C^1, hence Lipschitz along every
       axis with the constants grad[a], so |f^(x) - f^(c)| <= sum_a grad[a] |x_a - c_a|;
       Haar's f^ jumps, so not there */
    if (s->ly.L > 2) {
        double r = 0.0, e = 1e-10 * (ac.fc_abs + ac.vabs);
        for (int a = 0; a < 3; a++)
            if (s->ly.tr[a]) r += out->grad[a] * 0.5 * (hi[a] - lo[a]);
        out->vmin = fmax(out->vmin, ac.fc - r - e);
        out->vmax = fmin(out->vmax, ac.fc + r + e);
    }
    out->touching = ac.touching;
    return WVOL_OK;
}

/* ---- point evaluation ------------------------------------------------------------------- */

/* phi, psi, phi', psi' at local u (0 outside [0, support)). */
static inline void spline4(const wvol_store *s, double u, double out[4])
{
    const wvol_basis *b = s->basis;
    int i;
    double t;
    if (!(u >= 0.0) || u >= s->rg.support) {
        out[0] = out[1] = out[2] = out[3] = 0.0;
        return;
    }
    i = (int)(u * s->rg.per_unit);
    if (i >= b->pieces) i = b->pieces - 1;
    t = u - i * s->rg.h;
    out[0] = wvol__horner3(b->phi + 4 * (size_t)i, t);
    out[1] = wvol__horner3(b->psi + 4 * (size_t)i, t);
    out[2] = wvol__horner3(b->dphi + 4 * (size_t)i, t);
    out[3] = wvol__horner3(b->dpsi + 4 * (size_t)i, t);
}

/* Point evaluation caches the 1D factors: at level m only the S + 1 images j in
 * [j0, j0 + S] along an axis have a support holding x, and every node there
 * shares them. */
#define EV_LEVELS 12
#define EV_SPAN 32

typedef struct evacc {
    double x[3];
    double f, g[3];
    int cached;                                   /* levels <= EV_LEVELS and S + 1 <= EV_SPAN */
    int64_t j0[EV_LEVELS + 1][3];
    double B[EV_LEVELS + 1][3][EV_SPAN][4];       /* phi, psi, phi', psi' (per voxel) */
} evacc;

static void eval_fn(const trav *tv, void *arg, int m, unsigned mask, const float *vals, const size_t pos[3],
                    const double lo[3], const double hi[3], double t0, double t1)
{
    const wvol_store *s = tv->s;
    evacc *ev = arg;
    double B[3][4], scale = s->ipow2[m], nm = s->norm[m];
    int k = 0;
    (void)pos, (void)hi, (void)t0, (void)t1;
    for (int a = 0; a < 3; a++) {
        if (!s->ly.tr[a]) {
            B[a][0] = B[a][1] = 1.0, B[a][2] = B[a][3] = 0.0;
            continue;
        }
        if (ev->cached) {
            int64_t idx = (int64_t)floor((lo[a] + s->ly.s) * scale + 0.5) - ev->j0[m][a];
            if (idx >= 0 && idx < s->ly.L) {
                memcpy(B[a], ev->B[m][a][idx], sizeof B[a]);
                continue;
            }
        }
        spline4(s, (ev->x[a] - lo[a]) * scale, B[a]);
        B[a][2] *= scale, B[a][3] *= scale;
    }
    for (int l = 0; l < 8; l++) {
        if (!((mask >> l) & 1)) continue;
        double c = vals[k++] * nm;
        int b0 = l & 1, b1 = (l >> 1) & 1, b2 = (l >> 2) & 1;
        double x = B[0][b0], y = B[1][b1], z = B[2][b2];
        ev->f += c * x * y * z;
        ev->g[0] += c * B[0][2 + b0] * y * z;
        ev->g[1] += c * x * B[1][2 + b1] * z;
        ev->g[2] += c * x * y * B[2][2 + b2];
    }
}

double wvol_store_eval(const wvol_store *s, const double x[3], double grad[3])
{
    trav tv;
    evacc ev;
    if (!s || !x) return NAN;
    memset(&tv, 0, sizeof tv);
    ev.f = ev.g[0] = ev.g[1] = ev.g[2] = 0.0;
    for (int a = 0; a < 3; a++) {
        double xa = x[a], P = (double)s->ly.P[a];
        if (!isfinite(xa)) return NAN;
        /* f^ is periodic: a point far outside is brought within a period first, exactly
         * (fmod), before the supports' integer translates are taken from it */
        if (xa < -P || xa >= 2 * P) {
            xa = fmod(xa, P);
            if (xa < 0) xa += P;
        }
        tv.a[a] = tv.b[a] = ev.x[a] = xa;
    }
    tv.s = s, tv.fn = eval_fn, tv.arg = &ev;
    ev.cached = s->ly.levels <= EV_LEVELS && s->ly.L <= EV_SPAN;
    if (ev.cached)
        for (int m = 1; m <= s->ly.levels; m++) {
            double scale = s->ipow2[m];
            for (int a = 0; a < 3; a++) {
                if (!s->ly.tr[a]) continue;
                int64_t j0 = (int64_t)ceil((ev.x[a] + s->ly.s) * scale - (s->ly.L - 1));
                ev.j0[m][a] = j0;
                for (int i = 0; i < s->ly.L; i++) {
                    double *B = ev.B[m][a][i];
                    spline4(s, (ev.x[a] - ((double)(j0 + i) * s->pow2[m] - s->ly.s)) * scale, B);
                    B[2] *= scale, B[3] *= scale;
                }
            }
        }
    traverse(&tv);
    if (grad)
        for (int a = 0; a < 3; a++) grad[a] = ev.g[a];
    return ev.f;
}
