/* SPDX-License-Identifier: MIT
 * Transport coefficients between pure smoothing Haar bases (Lewis & Fournier 2002, §7.1.4.1):
 *   T_jk = 4^(l_j + l_k) * integral over the direction square S_k of G_j(k, l) A_jk(k, l),
 * G_j = 1 when the ray back along (k, l) leaves the source in j's direction cell, A_jk the area
 * of k's position cell covered by the parallel projection of j's position cell (polygon
 * clipping: the rectilinear mapping keeps lines straight). Plus tg_oracle (§7.2.4.1), here by
 * interval arithmetic, which is conservative where the paper's 16-corner test is not. */
#include "transport_internal.h"

#include <math.h>
#include <string.h>

#include "wvol/rng.h"

void wvol__tgeom_init(wvol__tgeom *g, const wvol_transport_quad *src, const wvol_transport_quad *dst)
{
    double d[3];
    wvol__tframe_init(&g->s, src);
    wvol__tframe_init(&g->d, dst);
    for (int c = 0; c < 3; c++) d[c] = g->s.o[c] - g->d.o[c];
    g->coplanar = fabs(fabs(wvol__dot3(g->s.n, g->d.n)) - 1) < 1e-12 &&
                  fabs(wvol__dot3(d, g->d.n)) <= 1e-12 * sqrt(g->s.area + g->d.area);
}

typedef struct pt2 {
    double x, y;
} pt2;

/* Sutherland-Hodgman against a*x + b*y + c >= 0 */
static int clip_half(pt2 *out, const pt2 *in, int n, double a, double b, double c)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        pt2 p = in[i], q = in[(i + 1) % n];
        double fp = a * p.x + b * p.y + c, fq = a * q.x + b * q.y + c;
        if (fp >= 0) out[m++] = p;
        if ((fp >= 0) != (fq >= 0)) {
            double t = fp / (fp - fq);
            out[m].x = p.x + t * (q.x - p.x);
            out[m].y = p.y + t * (q.y - p.y);
            m++;
        }
    }
    return m;
}

static double area2(const pt2 *p, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++) s += p[i].x * p[(i + 1) % n].y - p[(i + 1) % n].x * p[i].y;
    return 0.5 * fabs(s);
}

typedef struct integrand_ctx {
    const wvol__tgeom *g;
    double js[4], jh; /* j's cell origin (u, v, k, l) and side */
    double ks[2], kh; /* k's position cell origin and side */
} integrand_ctx;

static double integrand(void *user, double k, double l)
{
    const integrand_ctx *c = user;
    const wvol__tgeom *g = c->g;
    double wd[3], w[3], kl[2], nd_dot, a, b, cc;
    pt2 p[16], q[16];
    int n;
    if (!wvol__tframe_dir(&g->d, k, l, wd)) return 0;
    for (int i = 0; i < 3; i++) w[i] = -wd[i];
    if (!(wvol__dot3(w, g->s.n) > 0)) return 0;
    wvol__tframe_kl(&g->s, w, kl);
    if (kl[0] < c->js[2] || kl[0] >= c->js[2] + c->jh || kl[1] < c->js[3] || kl[1] >= c->js[3] + c->jh) return 0;
    /* j's position cell, clipped to the front of the destination's plane */
    p[0].x = c->js[0], p[0].y = c->js[1];
    p[1].x = c->js[0] + c->jh, p[1].y = c->js[1];
    p[2].x = c->js[0] + c->jh, p[2].y = c->js[1] + c->jh;
    p[3].x = c->js[0], p[3].y = c->js[1] + c->jh;
    {
        double d0[3];
        for (int i = 0; i < 3; i++) d0[i] = g->s.o[i] - g->d.o[i];
        cc = wvol__dot3(d0, g->d.n);
        a = wvol__dot3(g->s.eu, g->d.n);
        b = wvol__dot3(g->s.ev, g->d.n);
    }
    n = clip_half(q, p, 4, a, b, cc);
    if (n < 3) return 0;
    /* project each vertex back along wd onto the destination plane, to destination (u, v) */
    nd_dot = wvol__dot3(wd, g->d.n);
    for (int i = 0; i < n; i++) {
        double xs[3], s, uv[2];
        wvol__tframe_point(&g->s, q[i].x, q[i].y, xs);
        s = (a * q[i].x + b * q[i].y + cc) / nd_dot;
        for (int t = 0; t < 3; t++) xs[t] -= s * wd[t];
        wvol__tframe_param(&g->d, xs, uv);
        p[i].x = uv[0], p[i].y = uv[1];
    }
    n = clip_half(q, p, n, 1, 0, -c->ks[0]);
    n = clip_half(p, q, n, -1, 0, c->ks[0] + c->kh);
    n = clip_half(q, p, n, 0, 1, -c->ks[1]);
    n = clip_half(p, q, n, 0, -1, c->ks[1] + c->kh);
    return n < 3 ? 0 : area2(p, n);
}

static uint64_t pair_seed(uint64_t seed, const wvol_transport_index *j, const wvol_transport_index *k)
{
    uint64_t h = wvol_hash64(seed);
    h = wvol_hash64(h ^ ((uint64_t)j->level << 60 | (uint64_t)j->m[0] << 45 | (uint64_t)j->m[1] << 30 |
                         (uint64_t)j->m[2] << 15 | (uint64_t)j->m[3]));
    h = wvol_hash64(h ^ ((uint64_t)k->level << 60 | (uint64_t)k->m[0] << 45 | (uint64_t)k->m[1] << 30 |
                         (uint64_t)k->m[2] << 15 | (uint64_t)k->m[3]));
    return h;
}

double wvol__tc_eval(const wvol__tgeom *g, const wvol_transport_index *j, const wvol_transport_index *k,
                     const wvol_transport_params *p, size_t *evals)
{
    integrand_ctx c;
    double hk = ldexp(1.0, -k->level), s;
    if (g->coplanar) return 0;
    c.g = g;
    c.jh = ldexp(1.0, -j->level);
    for (int a = 0; a < 4; a++) c.js[a] = j->m[a] * c.jh;
    c.kh = hk;
    c.ks[0] = k->m[0] * hk;
    c.ks[1] = k->m[1] * hk;
    s = wvol__rule2d(p->quadrature, p->samples, pair_seed(p->seed, j, k), integrand, &c, k->m[2] * hk, k->m[3] * hk, hk,
                     evals);
    return ldexp(s, 2 * (j->level + k->level));
}

/* ---- the oracle: interval arithmetic over the destination hypercube ------------------------- */
typedef struct iv {
    double lo, hi;
} iv;

static iv iv_make(double a, double b) { return a <= b ? (iv){a, b} : (iv){b, a}; }
static iv iv_add(iv a, iv b) { return (iv){a.lo + b.lo, a.hi + b.hi}; }
static iv iv_scale(iv a, double s) { return iv_make(a.lo * s, a.hi * s); }
static iv iv_mul(iv a, iv b)
{
    double p[4] = {a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi}, lo = p[0], hi = p[0];
    for (int i = 1; i < 4; i++) lo = fmin(lo, p[i]), hi = fmax(hi, p[i]);
    return (iv){lo, hi};
}
static iv iv_sq(iv a)
{
    double x = a.lo * a.lo, y = a.hi * a.hi;
    if (a.lo <= 0 && a.hi >= 0) return (iv){0, fmax(x, y)};
    return iv_make(x, y);
}
/* a . v for an interval 3-vector a and a fixed vector v */
static iv iv_dot(const iv a[3], const double v[3])
{
    return iv_add(iv_add(iv_scale(a[0], v[0]), iv_scale(a[1], v[1])), iv_scale(a[2], v[2]));
}
static int iv_disjoint(iv a, double lo, double hi) { return a.hi <= lo || a.lo >= hi; }
static int iv_inside(iv a, double lo, double hi) { return a.lo > lo && a.hi < hi; }

wvol__oracle wvol__tg_oracle(const wvol__tgeom *g, const wvol_transport_index *j, const wvol_transport_index *k)
{
    double hj = ldexp(1.0, -j->level), hk = ldexp(1.0, -k->level), jl[4];
    iv mx, my, r2, r2j, mz, w[3], wn, kls[2], xd[3], num, s, xs[3], a, b, uv[2];
    if (g->coplanar) return WVOL__ORACLE_ZERO;
    for (int i = 0; i < 4; i++) jl[i] = j->m[i] * hj;
    mx = (iv){2 * k->m[2] * hk - 1, 2 * (k->m[2] + 1) * hk - 1};
    my = (iv){2 * k->m[3] * hk - 1, 2 * (k->m[3] + 1) * hk - 1};
    r2 = iv_add(iv_sq(mx), iv_sq(my));
    r2j = iv_add(iv_sq((iv){2 * jl[2] - 1, 2 * (jl[2] + hj) - 1}), iv_sq((iv){2 * jl[3] - 1, 2 * (jl[3] + hj) - 1}));
    if (r2.lo >= 1 || r2j.lo >= 1) return WVOL__ORACLE_ZERO; /* outside the unit disc */
    mz = (iv){sqrt(fmax(0, 1 - r2.hi)), sqrt(fmax(0, 1 - r2.lo))};
    for (int c = 0; c < 3; c++) /* w = -(mx t + my b + mz n): the travel direction */
        w[c] = iv_scale(iv_add(iv_add(iv_scale(mx, g->d.t[c]), iv_scale(my, g->d.b[c])), iv_scale(mz, g->d.n[c])), -1);
    wn = iv_dot(w, g->s.n);
    if (wn.hi <= 0) return WVOL__ORACLE_ZERO; /* arrives at the source's back */
    kls[0] = iv_scale(iv_add(iv_dot(w, g->s.t), (iv){1, 1}), 0.5);
    kls[1] = iv_scale(iv_add(iv_dot(w, g->s.b), (iv){1, 1}), 0.5);
    if (iv_disjoint(kls[0], jl[2], jl[2] + hj) || iv_disjoint(kls[1], jl[3], jl[3] + hj)) return WVOL__ORACLE_ZERO;
    if (wn.lo <= 0) return WVOL__ORACLE_UNKNOWN; /* grazing: the distance has no bound */
    for (int c = 0; c < 3; c++)
        xd[c] = iv_add(iv_add((iv){g->d.o[c], g->d.o[c]}, iv_scale((iv){k->m[0] * hk, (k->m[0] + 1) * hk}, g->d.eu[c])),
                       iv_scale((iv){k->m[1] * hk, (k->m[1] + 1) * hk}, g->d.ev[c]));
    /* x_s = x_d + s (-w), s = (o_s - x_d) . n_s / (-w . n_s) */
    num = iv_add((iv){wvol__dot3(g->s.o, g->s.n), wvol__dot3(g->s.o, g->s.n)}, iv_scale(iv_dot(xd, g->s.n), -1));
    s = iv_mul(num, iv_make(-1 / wn.lo, -1 / wn.hi));
    if (s.hi <= 0) return WVOL__ORACLE_ZERO; /* the source lies behind the destination */
    for (int c = 0; c < 3; c++) xs[c] = iv_add(iv_add(xd[c], iv_mul(s, iv_scale(w[c], -1))), (iv){-g->s.o[c], -g->s.o[c]});
    a = iv_dot(xs, g->s.eu);
    b = iv_dot(xs, g->s.ev);
    uv[0] = iv_add(iv_scale(a, g->s.ginv[0][0]), iv_scale(b, g->s.ginv[0][1]));
    uv[1] = iv_add(iv_scale(a, g->s.ginv[1][0]), iv_scale(b, g->s.ginv[1][1]));
    if (iv_disjoint(uv[0], jl[0], jl[0] + hj) || iv_disjoint(uv[1], jl[1], jl[1] + hj)) return WVOL__ORACLE_ZERO;
    if (r2.hi < 1 && s.lo > 0 && iv_inside(kls[0], jl[2], jl[2] + hj) && iv_inside(kls[1], jl[3], jl[3] + hj) &&
        iv_inside(uv[0], jl[0], jl[0] + hj) && iv_inside(uv[1], jl[1], jl[1] + hj))
        return WVOL__ORACLE_FULL;
    return WVOL__ORACLE_UNKNOWN;
}

static wvol_status check_index(const wvol_transport_index *x, const char *what, wvol_error *err)
{
    WVOL_RETURN_IF(!x, err, WVOL_ERR_ARG, "transport coefficient: NULL %s index", what);
    WVOL_RETURN_IF(x->level < 0 || x->level > WVOL_TRANSPORT_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "transport coefficient: %s level %d outside 0..%d", what, x->level, WVOL_TRANSPORT_MAX_LEVELS);
    for (int a = 0; a < 4; a++)
        WVOL_RETURN_IF(x->m[a] < 0 || x->m[a] >= 1 << x->level, err, WVOL_ERR_ARG,
                       "transport coefficient: %s m[%d] = %d outside 0..%d", what, a, x->m[a], (1 << x->level) - 1);
    return WVOL_OK;
}

wvol_status wvol__transport_params_check(const wvol_transport_params *p, wvol_error *err)
{
    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "transport: NULL params");
    WVOL_RETURN_IF(p->levels < 1 || p->levels > WVOL_TRANSPORT_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "transport: levels %d outside 1..%d", p->levels, WVOL_TRANSPORT_MAX_LEVELS);
    WVOL_RETURN_IF(!wvol_transport_quadrature_name(p->quadrature), err, WVOL_ERR_ARG, "transport: unknown quadrature %d",
                   (int)p->quadrature);
    WVOL_RETURN_IF(p->samples < 1 || p->samples > (1 << 24), err, WVOL_ERR_ARG, "transport: samples %d outside 1..2^24",
                   p->samples);
    WVOL_RETURN_IF(p->use_oracle != 0 && p->use_oracle != 1, err, WVOL_ERR_ARG, "transport: use_oracle %d (0 or 1)",
                   p->use_oracle);
    return WVOL_OK;
}

void wvol_transport_params_default(wvol_transport_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->levels = 3;
    p->quadrature = WVOL_TRANSPORT_QUADRATURE_TRAPEZOID;
    p->samples = 16;
    p->seed = 1;
    p->use_oracle = 1;
}

wvol_status wvol_transport_coefficient(double *T, const wvol_transport_quad *src, const wvol_transport_quad *dst,
                                       const wvol_transport_index *j, const wvol_transport_index *k,
                                       const wvol_transport_params *p, wvol_error *err)
{
    wvol__tgeom g;
    WVOL_RETURN_IF(!T, err, WVOL_ERR_ARG, "transport coefficient: NULL output");
    WVOL_FORWARD(wvol_transport_quad_check(src, err));
    WVOL_FORWARD(wvol_transport_quad_check(dst, err));
    WVOL_FORWARD(check_index(j, "source", err));
    WVOL_FORWARD(check_index(k, "destination", err));
    WVOL_FORWARD(wvol__transport_params_check(p, err));
    wvol__tgeom_init(&g, src, dst);
    *T = wvol__tc_eval(&g, j, k, p, NULL);
    WVOL_RETURN_IF(!isfinite(*T), err, WVOL_ERR_INTERNAL, "transport coefficient: integration gave %g", *T);
    return WVOL_OK;
}
