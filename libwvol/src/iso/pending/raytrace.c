/* SPDX-License-Identifier: MIT */
/* Ray tracing the implicit surface f^ = iso of a coefficient store, with no
 * missed hit. Along a ray x(t) = o + t d (t in world units, |d| = 1 in world),
 * intervals [a, b] are processed front to back. An interval is discarded when
 * the store's rigorous bounds on the segment's bounding box exclude iso
 * (vmin > iso or vmax < iso), or when the Lipschitz bound
 *   |df^/dt| <= L = sum_a |d_a| max|df^/dx_a|   (per-axis gradient bounds of the box)
 * forbids a root: a root t* needs |f(a) - iso| <= L (t* - a) and |f(b) - iso| <= L (b - t*),
 * so |f(a) - iso| + |f(b) - iso| > L (b - a) excludes one. Other intervals are halved.
 * The first interval (in depth order) no longer than the tolerance whose end values
 * straddle iso holds the first crossing: every earlier interval was excluded by a
 * rigorous bound, so no earlier crossing exists, except a pair of crossings both
 * inside one interval shorter than tolerance / 16 (a sliver below the tolerance,
 * counted as a graze). Box bounds are refreshed every other halving; in between
 * the parent's Lipschitz bound still holds (the child's box lies inside).
 * Haar's f^ is piecewise constant on unit boxes (faces at k + 1/2): the ray walks
 * the boxes (3D DDA), one evaluation per box, and the first sign change is a face:
 * the depth is exact and the normal is the face's.
 * Based on: Kalra & Barr 1989 (guaranteed ray intersection with implicit surfaces);
 * DESIGN.md section 9. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "wvol/iso.h"

void wvol_iso_trace_params_default(wvol_iso_trace_params *p)
{
    memset(p, 0, sizeof *p);
    p->tolerance = 0.0; /* 1e-3 of the smallest spacing */
    p->step = 4.0;
    p->threads = 0;
    p->color[0] = 0.93f, p->color[1] = 0.89f, p->color[2] = 0.80f;
    p->ambient = 0.15f;
}

typedef struct iv {
    double a, b, fa, fb;
    double L;   /* Lipschitz bound of the parent box (valid here: the child's box is inside) */
    int level;
} iv;

typedef struct tracer {
    const wvol_store *s;
    wvol_store_info info;
    double iso, tol, step;
    int smooth;
} tracer;

static double eval_at(const tracer *tr, const double ov[3], const double dv[3], double t, double g[3])
{
    double x[3] = {ov[0] + t * dv[0], ov[1] + t * dv[1], ov[2] + t * dv[2]};
    return wvol_store_eval(tr->s, x, g);
}

/* Gradient-free normal (Haar): central differences of half a voxel. */
static void fd_normal(const tracer *tr, const double x[3], double g[3])
{
    int a;
    for (a = 0; a < 3; a++) {
        double p[3] = {x[0], x[1], x[2]}, q[3] = {x[0], x[1], x[2]};
        p[a] += 0.5;
        q[a] -= 0.5;
        g[a] = tr->info.transformed[a] ? (wvol_store_eval(tr->s, p, NULL) - wvol_store_eval(tr->s, q, NULL)) : 0.0;
    }
}

static wvol_status trace(const tracer *tr, const double o[3], const double d[3], wvol_iso_hit *h)
{
    double ov[3], dv[3], t0 = 0.0, t1 = INFINITY, speed = 0.0, seg;
    size_t n[3] = {tr->info.nx, tr->info.ny, tr->info.nz};
    iv stack[128];
    int a, sp;
    memset(h, 0, sizeof *h);
    h->t = INFINITY;
    wvol_store_world_to_voxel(tr->s, o, ov);
    wvol_store_dir_to_voxel(tr->s, d, dv);
    /* clip to the sample extent [0, n - 1] */
    for (a = 0; a < 3; a++) {
        double lo = 0.0, hi = (double)n[a] - 1.0;
        speed += dv[a] * dv[a];
        if (!tr->info.transformed[a] || n[a] < 2) continue;
        if (dv[a] == 0.0) {
            if (ov[a] < lo || ov[a] > hi) return WVOL_OK;
            continue;
        }
        {
            double ta = (lo - ov[a]) / dv[a], tb = (hi - ov[a]) / dv[a];
            if (ta > tb) {
                double tmp = ta;
                ta = tb, tb = tmp;
            }
            if (ta > t0) t0 = ta;
            if (tb < t1) t1 = tb;
        }
    }
    if (!(t0 <= t1) || !isfinite(t1) || speed == 0.0) return WVOL_OK;
    if (!tr->smooth) { /* Haar: f^ is constant on unit boxes with faces at k + 1/2 */
        double t = t0, prev = eval_at(tr, ov, dv, t0, NULL);
        int prev_axis = -1;
        h->evals++;
        while (t < t1) {
            double tn = t1, mid, f;
            int ax = -1;
            for (a = 0; a < 3; a++) {
                double x, face, tf;
                if (dv[a] == 0.0 || !tr->info.transformed[a]) continue;
                x = ov[a] + t * dv[a];
                face = dv[a] > 0 ? floor(x - 0.5 + 1e-9) + 1.5 : ceil(x + 0.5 - 1e-9) - 1.5;
                tf = (face - ov[a]) / dv[a];
                if (tf <= t) tf = t + 1e-12;
                if (tf < tn) tn = tf, ax = a;
            }
            mid = 0.5 * (t + tn);
            f = eval_at(tr, ov, dv, mid, NULL);
            h->evals++;
            if ((f >= tr->iso) != (prev >= tr->iso)) {
                h->hit = 1;
                h->t = t;
                h->value = f;
                for (a = 0; a < 3; a++) {
                    h->pos[a] = o[a] + t * d[a];
                    h->normal[a] = 0.0;
                }
                if (prev_axis >= 0) /* -grad points back across the face when entering f >= iso */
                    h->normal[prev_axis] = ((f >= tr->iso) ? -1.0 : 1.0) * (dv[prev_axis] > 0 ? 1.0 : -1.0);
                return WVOL_OK;
            }
            prev = f;
            prev_axis = ax;
            t = tn;
        }
        return WVOL_OK;
    }
    seg = tr->step / sqrt(speed); /* coarse segments of `step` voxels */
    {
        double fa = eval_at(tr, ov, dv, t0, NULL), ta = t0;
        h->evals++;
        while (ta < t1) {
            double tb = ta + seg < t1 ? ta + seg : t1, fb = eval_at(tr, ov, dv, tb, NULL);
            h->evals++;
            sp = 0;
            stack[sp++] = (iv){ta, tb, fa, fb, INFINITY, 0};
            while (sp > 0) {
                iv c = stack[--sp];
                double lo[3], hi[3], m, fm;
                int sa, sb;
                wvol_store_bounds bd;
                for (a = 0; a < 3; a++) {
                    double p = ov[a] + c.a * dv[a], q = ov[a] + c.b * dv[a];
                    lo[a] = p < q ? p : q;
                    hi[a] = p < q ? q : p;
                }
                /* fresh box bounds every other level (they cost ~10 point evaluations);
                 * in between, the parent's Lipschitz bound holds on the smaller box */
                if (c.level % 2 == 0 || !isfinite(c.L)) {
                    if (wvol_store_box_bounds(tr->s, lo, hi, &bd, NULL) != WVOL_OK) return WVOL_ERR_INTERNAL;
                    h->bounds++;
                    if (tr->iso < bd.vmin || tr->iso > bd.vmax) continue;
                    c.L = fabs(dv[0]) * bd.grad[0] + fabs(dv[1]) * bd.grad[1] + fabs(dv[2]) * bd.grad[2];
                }
                if (fabs(c.fa - tr->iso) + fabs(c.fb - tr->iso) > c.L * (c.b - c.a) * (1.0 + 1e-9)) continue;
                sa = c.fa >= tr->iso;
                sb = c.fb >= tr->iso;
                if (sa != sb && c.b - c.a <= tr->tol) {
                    double x[3], g[3], gw[3], len = 0.0;
                    h->hit = 1;
                    h->t = 0.5 * (c.a + c.b);
                    for (a = 0; a < 3; a++) x[a] = ov[a] + h->t * dv[a];
                    h->value = wvol_store_eval(tr->s, x, g);
                    if (!tr->smooth || (g[0] == 0.0 && g[1] == 0.0 && g[2] == 0.0)) fd_normal(tr, x, g);
                    for (a = 0; a < 3; a++) {
                        gw[a] = g[a] / tr->info.spacing[a];
                        len += gw[a] * gw[a];
                        h->pos[a] = o[a] + h->t * d[a];
                    }
                    len = sqrt(len);
                    for (a = 0; a < 3; a++) h->normal[a] = len > 0 ? -gw[a] / len : 0.0;
                    return WVOL_OK;
                }
                if (c.b - c.a <= tr->tol / 16) {
                    h->grazes++;
                    continue;
                }
                if (sp + 2 > (int)(sizeof stack / sizeof stack[0])) {
                    h->grazes++;
                    continue;
                }
                m = 0.5 * (c.a + c.b);
                fm = eval_at(tr, ov, dv, m, NULL);
                h->evals++;
                stack[sp++] = (iv){m, c.b, fm, c.fb, c.L, c.level + 1};
                stack[sp++] = (iv){c.a, m, c.fa, fm, c.L, c.level + 1};
            }
            ta = tb;
            fa = fb;
        }
    }
    return WVOL_OK;
}

static wvol_status make_tracer(tracer *tr, const wvol_store *s, double iso, const wvol_iso_trace_params *p,
                               wvol_error *err)
{
    double smin;
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "iso trace: store is NULL");
    WVOL_RETURN_IF(!isfinite(iso), err, WVOL_ERR_ARG, "iso trace: iso-value %g is not finite", iso);
    memset(tr, 0, sizeof *tr);
    tr->s = s;
    wvol_store_get_info(s, &tr->info);
    tr->iso = iso;
    tr->smooth = tr->info.filter && tr->info.filter->length > 2;
    smin = fmin(tr->info.spacing[0], fmin(tr->info.spacing[1], tr->info.spacing[2]));
    tr->tol = p && p->tolerance > 0 ? p->tolerance : 1e-3 * smin;
    tr->step = p && p->step > 0 ? p->step : 4.0;
    return WVOL_OK;
}

wvol_status wvol_iso_trace_ray(const wvol_store *s, double iso, const double o[3], const double d[3],
                               const wvol_iso_trace_params *p, wvol_iso_hit *hit, wvol_error *err)
{
    tracer tr;
    double dn[3], len;
    WVOL_RETURN_IF(!o || !d || !hit, err, WVOL_ERR_ARG, "iso trace: NULL argument");
    WVOL_FORWARD(make_tracer(&tr, s, iso, p, err));
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    WVOL_RETURN_IF(!(len > 0) || !isfinite(len), err, WVOL_ERR_ARG, "iso trace: direction has no length");
    dn[0] = d[0] / len, dn[1] = d[1] / len, dn[2] = d[2] / len;
    if (trace(&tr, o, dn, hit) != WVOL_OK)
        return wvol_error_set(err, WVOL_ERR_INTERNAL, "iso trace: store bounds failed");
    return WVOL_OK;
}

wvol_status wvol_iso_raytrace(float *rgb, float *depth, float *normals, int width, int height,
                              wvol_iso_ray_fn camera, void *camera_user, const wvol_store *s, double iso,
                              const wvol_iso_trace_params *p, wvol_iso_trace_stats *st, wvol_error *err)
{
    tracer tr;
    wvol_iso_trace_params def;
    long row;
    int nth, bad = 0;
    size_t hits = 0, evals = 0, bounds = 0, grazes = 0;
    double t0;
    WVOL_RETURN_IF(width < 1 || height < 1, err, WVOL_ERR_ARG, "iso trace: image %dx%d", width, height);
    WVOL_RETURN_IF(!camera, err, WVOL_ERR_ARG, "iso trace: no camera");
    if (!p) {
        wvol_iso_trace_params_default(&def);
        p = &def;
    }
    WVOL_FORWARD(make_tracer(&tr, s, iso, p, err));
#ifdef _OPENMP
    nth = p->threads > 0 ? p->threads : omp_get_max_threads();
    t0 = omp_get_wtime();
#else
    nth = 1;
    t0 = 0.0;
#endif
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth) reduction(+ : hits, evals, bounds, grazes, bad)
#endif
    for (row = 0; row < height; row++) {
        int x;
        for (x = 0; x < width; x++) {
            double o[3], d[3], len, l[3];
            wvol_iso_hit h;
            size_t px = (size_t)row * (size_t)width + (size_t)x;
            int a;
            camera(camera_user, x + 0.5, row + 0.5, o, d);
            len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (a = 0; a < 3; a++) d[a] /= len;
            if (trace(&tr, o, d, &h) != WVOL_OK) bad++;
            evals += (size_t)h.evals;
            bounds += (size_t)h.bounds;
            grazes += (size_t)h.grazes;
            if (depth) depth[px] = h.hit ? (float)h.t : INFINITY;
            if (normals)
                for (a = 0; a < 3; a++) normals[3 * px + a] = h.hit ? (float)h.normal[a] : 0.0f;
            if (rgb) {
                double lam = 0.0;
                if (h.hit) {
                    double ll = 0.0;
                    hits++;
                    for (a = 0; a < 3; a++) {
                        l[a] = (p->light[0] || p->light[1] || p->light[2]) ? p->light[a] : -d[a];
                        ll += l[a] * l[a];
                    }
                    ll = sqrt(ll);
                    for (a = 0; a < 3; a++) lam += h.normal[a] * l[a] / ll;
                    lam = fabs(lam); /* two-sided */
                }
                for (a = 0; a < 3; a++)
                    rgb[3 * px + a] = h.hit ? (float)(p->color[a] * (p->ambient + (1.0 - p->ambient) * lam)) : 0.0f;
            } else if (h.hit) {
                hits++;
            }
        }
    }
    if (st) {
        memset(st, 0, sizeof *st);
        st->rays = (size_t)width * (size_t)height;
        st->hits = hits;
        st->evals = evals;
        st->bounds = bounds;
        st->grazes = grazes;
#ifdef _OPENMP
        st->seconds = omp_get_wtime() - t0;
#endif
        if (hits == 0) {
            wvol_store_bounds bd;
            double lo[3] = {0, 0, 0}, hi[3] = {(double)tr.info.nx - 1, (double)tr.info.ny - 1, (double)tr.info.nz - 1};
            if (wvol_store_box_bounds(s, lo, hi, &bd, NULL) == WVOL_OK && (iso < bd.vmin || iso > bd.vmax))
                snprintf(st->message, sizeof st->message,
                         "iso-value %.9g is outside the range of f^ (bounded by [%.9g, %.9g]): no surface", iso,
                         bd.vmin, bd.vmax);
            else
                snprintf(st->message, sizeof st->message, "no ray meets the surface f^ = %.9g: empty image", iso);
        }
    }
    if (bad) return wvol_error_set(err, WVOL_ERR_INTERNAL, "iso trace: store bounds failed on %d rays", bad);
    return WVOL_OK;
}
