/* SPDX-License-Identifier: MIT
 * One ray of the implicit-surface ray tracer (raytrace.c says how and why): chunk by chunk,
 * f^'s piece polynomials from the store (store/store_ray.h), the small functions bounded
 * rather than expanded, Bernstein subdivision of the undecided pieces down to a single sign
 * change, bisection to the tolerance; the cell grid's decided cells stepped over.
 * Based on: Kalra & Barr 1989; Lane & Riesenfeld 1981. */
#include <float.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "iso_internal.h"

#define NC WVOL__NC
#define PAD_REL 1e-10
#define SMALL_BUDGET (1.0 / 16) /* the small functions' |c| max|w| sum to at most this share of the largest */
#define HINT_MARGIN 1.0     /* voxels a chunk reaches past the neighbour's hit */
#define RUN_MAX 32         /* undecided pieces refined at once */

typedef wvol__tracer tracer;
typedef wvol__trace_ws tws;

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
        if (m <= u0 || m >= u1) break; /* adjacent doubles: as fine as the interval gets */
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

/* Clips o + t d (voxel space), t >= tmin, to the traced extent [tr->lo, tr->hi] (the sample
 * extent less the bands where f^ reaches across the periodic wrap; wvol__iso_model_extent):
 * 1 and [*t0, *t1] when something is left. */
static int clip(const tracer *tr, const double ov[3], const double dv[3], double tmin, double *t0, double *t1)
{
    double a0 = tmin, a1 = INFINITY;
    int a;
    for (a = 0; a < 3; a++) {
        double lo = tr->lo[a], hi = tr->hi[a], ta, tb;
        if (!tr->g.info.transformed[a]) continue;
        if (!(lo <= hi)) return 0;
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

void wvol__trace_ws_free(tws *w)
{
    wvol__spline_ws_free(&w->s);
    free(w->env);
    free(w->cut);
    wvol__cell_ws_free(&w->cellq);
    memset(w, 0, sizeof *w);
}

/* The class of f^ on piece e from the big functions' polynomial and the small ones'
 * envelope: 1 (surely >= iso), 0 (surely < iso) or -1 (undecided). */
static int decide(const tracer *tr, const double *a, double env)
{
    double B[NC], lo = INFINITY, hi = -INFINITY, pad, r = 0;
    int j;
    /* first the monomial form's bound |p(u) - a_0| <= sum_{k >= 1} |a_k| on [0, 1]: on a short
     * piece far from iso it decides without the Bernstein coefficients. Its rounding (a few
     * DBL_EPSILON of the summed magnitudes) is far below the pad. */
    for (j = 1; j < NC; j++) r += fabs(a[j]);
    pad = PAD_REL * (fabs(a[0]) + r + fabs(tr->iso) + env);
    r += env + pad;
    if (a[0] - tr->iso > r) return 1;
    if (tr->iso - a[0] > r) return 0;
    pad = PAD_REL * (wvol__bernstein(&tr->g, a, B) + fabs(tr->iso) + env);
    for (j = 0; j < NC; j++) { /* B is finite: no fmin/fmax (a call each on baseline x86-64) */
        lo = B[j] < lo ? B[j] : lo;
        hi = B[j] > hi ? B[j] : hi;
    }
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

/* frexp's exponent of a finite x > 0, without the library call for normal numbers (small_cut
 * takes it of every function of every chunk). */
static inline int binary_exponent(double x)
{
    uint64_t b;
    int e;
    memcpy(&b, &x, sizeof b);
    e = (int)((b >> 52) & 0x7ff);
    if (e == 0) frexp(x, &e); /* subnormal */
    else e -= 1022;
    return e;
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
    ex = binary_exponent(wmax);
    for (i = 0; i < n; i++) {
        double wb = fabs((double)hits[i].value) * tr->k.fb[hits[i].level][hits[i].band];
        if (!(wb > 0)) continue;
        k = ex - binary_exponent(wb); /* 0: the largest bucket */
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
 * whole; runs of undecided pieces get the small functions added exactly and are searched.
 * Chunks are `chunk` voxels long, except with a hint (w->hint, the depth of the image's
 * previous pixel's hit): the chunk that holds hint + HINT_MARGIN ends there, and past it the
 * chunks grow geometrically from it (each as long as the distance gone past the hint), so the
 * pieces built after a hit near the neighbour's are few. Where the chunks end changes only how
 * the work is cut: every piece before a hit is still built and searched in order (the same
 * guarantee; a depth moves only within the tolerance, where the bisection's intervals fall). */
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
        if (w->has_hint) { /* end the chunk near the neighbour's hit (trace_span's comment) */
            double th = w->hint + HINT_MARGIN / speed;
            if (th > ta && th < tb) tb = th;
            else if (th <= ta && ta + (ta - w->hint) < tb) tb = ta + (ta - w->hint);
        }
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
            WVOL_RETURN_IF(!wvol__spline_add_finest_list(&tr->g, &w->s, ov, dv, hits + nb, n - nb, e, e2, &cnt), err,
                           WVOL_ERR_NOMEM, "iso trace: out of memory");
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

/* Crossings of the cell planes x_a = C k inside (t0, t1), merged with t0 and t1 into w->cut in
 * increasing order: each axis's crossings are generated in increasing t (k runs the way the ray
 * goes), then the three runs are merged. */
static size_t cell_cuts(const tracer *tr, tws *w, const double ov[3], const double dv[3], double t0, double t1)
{
    size_t n = 0, cap = 8, run[4] = {0, 0, 0, 0}, pos[3], m = 0;
    double *in, *out;
    int a;
    for (a = 0; a < 3; a++)
        if (dv[a] != 0.0 && tr->g.info.transformed[a])
            cap += (size_t)(fabs((t1 - t0) * dv[a]) / tr->cell) + 2;
    if (2 * cap > w->capC) {
        double *q = realloc(w->cut, 2 * cap * sizeof *q);
        if (!q) return 0;
        w->cut = q;
        w->capC = 2 * cap;
    }
    in = w->cut + cap; /* the three runs */
    out = w->cut;
    for (a = 0; a < 3; a++) {
        double x0, x1, k0, k1, k;
        run[a] = n;
        if (dv[a] == 0.0 || !tr->g.info.transformed[a]) continue;
        x0 = ov[a] + t0 * dv[a];
        x1 = ov[a] + t1 * dv[a];
        k0 = floor(fmin(x0, x1) / tr->cell) + 1;
        k1 = ceil(fmax(x0, x1) / tr->cell) - 1;
        for (k = dv[a] > 0 ? k0 : k1; k >= k0 && k <= k1 && n < cap - 2; k += dv[a] > 0 ? 1 : -1) {
            double t = (k * tr->cell - ov[a]) / dv[a];
            if (t > t0 && t < t1) in[n++] = t;
        }
    }
    run[3] = n;
    for (a = 0; a < 3; a++) pos[a] = run[a];
    out[m++] = t0;
    for (;;) {
        int best = -1;
        for (a = 0; a < 3; a++)
            if (pos[a] < run[a + 1] && (best < 0 || in[pos[a]] < in[pos[best]])) best = a;
        if (best < 0) break;
        out[m++] = in[pos[best]++];
    }
    out[m++] = t1;
    return m;
}

/* Runs of the cells the grid leaves undecided are traced exactly (trace_span). */
wvol_status wvol__trace(const tracer *tr, tws *w, const double o[3], const double d[3], double tmin, wvol_iso_hit *h,
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
    if (!tr->cls[0]) return trace_span(tr, w, o, d, ov, dv, t0, t1, speed, &prev, h, err);
    n = cell_cuts(tr, w, ov, dv, t0, t1);
    WVOL_RETURN_IF(n < 2, err, WVOL_ERR_NOMEM, "iso trace: out of memory");
    for (i = 0; i + 1 < n;) {
        double tm = 0.5 * (w->cut[i] + w->cut[i + 1]), x[3];
        size_t j;
        int a, cls;
        for (a = 0; a < 3; a++) x[a] = ov[a] + tm * dv[a];
        cls = wvol__trace_cell_class(tr, &w->cellq, x, &w->cells, &w->cell_seconds);
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
            if (wvol__trace_cell_class(tr, &w->cellq, x, &w->cells, &w->cell_seconds) >= 0) break;
        }
        WVOL_FORWARD(trace_span(tr, w, o, d, ov, dv, w->cut[i], w->cut[j], speed, &prev, h, err));
        if (h->hit) return WVOL_OK;
        i = j;
    }
    return WVOL_OK;
}
