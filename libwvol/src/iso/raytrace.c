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
 * The guarantee. "Crossing" means f^ - iso changes sign in the classification f^ >= iso.
 * For the computed piece polynomials, the reported hit is the first crossing along the ray
 * inside the sample extent [0, n-1] (and t >= tmin), with |t - t*| <= tolerance / 2, except
 * that a pair of crossings closer together than tolerance / 8 may be skipped (a graze).
 * Rounding: the piece polynomials are sums of products of the spline tables' cubics in
 * float64; pad = 1e-10 (sum of |B_j| terms + |iso|), far above their rounding, so a rounded
 * coefficient never hides a sign. Nothing relies on the store's box bounds.
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
#include "render/spline_ray.h"
#include "wvol/iso.h"

#define NC WVOL__NC
#define PAD_REL 1e-10

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
} tracer;

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

/* d: unit world direction. */
static wvol_status trace(const tracer *tr, wvol__spline_ws *ws, const double o[3], const double d[3], double tmin,
                         wvol_iso_hit *h, wvol_error *err)
{
    double ov[3], dv[3], t0, t1, ta, speed, prev = 0.0;
    int have_prev = 0;
    memset(h, 0, sizeof *h);
    h->t = INFINITY;
    wvol_store_world_to_voxel(tr->g.s, o, ov);
    wvol_store_dir_to_voxel(tr->g.s, d, dv);
    speed = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
    if (!(speed > 0) || !clip(tr, ov, dv, tmin, &t0, &t1)) return WVOL_OK;
    for (ta = t0; ta < t1;) {
        double tb = ta + tr->chunk / speed;
        const wvol__level_ws *F = &ws->lev[1];
        wvol__spline_count cnt = {0, 0};
        size_t e;
        if (tb > t1 || t1 - tb < 1e-9 * (t1 - t0)) tb = t1;
        WVOL_FORWARD(wvol__spline_ray(&tr->g, ws, ov, dv, ta, tb, 0, 1, &cnt, err));
        h->functions += cnt.functions;
        h->pieces += F->E;
        for (e = 0; e < F->E; e++) {
            const double *a = ws->macc + e * NC;
            double len = F->T[e + 1] - F->T[e], u, first = a[0], last = 0.0;
            int k;
            if (!(len > 0)) continue;
            if (have_prev && (prev >= tr->iso) != (first >= tr->iso)) { /* a jump across iso */
                set_hit(tr, o, d, ov, dv, F->T[e], h);
                return WVOL_OK;
            }
            u = piece_root(tr, a, len, h);
            if (u >= 0) {
                set_hit(tr, o, d, ov, dv, F->T[e] + u * len, h);
                return WVOL_OK;
            }
            for (k = 0; k < NC; k++) last += a[k];
            prev = last;
            have_prev = 1;
        }
        ta = tb;
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
    return WVOL_OK;
}

wvol_status wvol_iso_trace_ray(const wvol_store *s, double iso, const double o[3], const double d[3],
                               const wvol_iso_trace_params *p, wvol_iso_hit *hit, wvol_error *err)
{
    tracer tr;
    wvol__spline_ws ws;
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
    wvol__spline_ws_free(&ws);
    return st;
}

/* The empty-image message: the store's bound of f^ over the extent tells whether iso is out of range. */
static void empty_message(const tracer *tr, double iso, char *msg, size_t cap)
{
    wvol_store_bounds bd;
    double lo[3] = {0, 0, 0},
           hi[3] = {(double)tr->g.info.nx - 1, (double)tr->g.info.ny - 1, (double)tr->g.info.nz - 1};
    if (wvol_store_box_bounds(tr->g.s, lo, hi, &bd, NULL) == WVOL_OK && (iso < bd.vmin || iso > bd.vmax))
        snprintf(msg, cap, "iso-value %.9g is outside the range of f^ (bounded by [%.9g, %.9g]): empty image", iso,
                 bd.vmin, bd.vmax);
    else
        snprintf(msg, cap, "no ray meets the surface f^ = %.9g: empty image", iso);
}

wvol_status wvol_iso_raytrace(wvol_image *img, float *depth, float *normals, const wvol_store *s,
                              const wvol_camera *cam, double iso, const wvol_iso_trace_params *p,
                              wvol_iso_trace_stats *st, wvol_error *err)
{
    tracer tr;
    wvol_iso_trace_params def;
    wvol__cam k;
    int nth, failed = 0;
    size_t hits = 0, functions = 0, pieces = 0, intervals = 0, evals = 0, grazes = 0;
    double t_start = wvol__now(), c_start = wvol__cpu_now(), tmin;
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
    wvol__cam_init(&k, cam);
    /* an orthographic ray is the whole line (as in the renderer); a perspective one starts at the eye */
    tmin = cam->projection == WVOL_PERSPECTIVE ? 0.0 : -INFINITY;
    nth = wvol__threads(p->threads);
    wvol_error_clear(&first_err);
#pragma omp parallel num_threads(nth) reduction(+ : hits, functions, pieces, intervals, evals, grazes)
    {
        wvol__spline_ws ws;
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
        wvol__spline_ws_free(&ws);
    }
    if (failed) {
        if (err) *err = first_err;
        return first_err.status ? first_err.status : WVOL_ERR_INTERNAL;
    }
    if (st) {
        memset(st, 0, sizeof *st);
        st->rays = (size_t)img->width * (size_t)img->height;
        st->hits = hits;
        st->functions = functions;
        st->pieces = pieces;
        st->intervals = intervals;
        st->evals = evals;
        st->grazes = grazes;
        st->seconds = wvol__now() - t_start;
        st->cpu_seconds = wvol__cpu_now() - c_start;
        if (hits == 0) empty_message(&tr, iso, st->message, sizeof st->message);
    }
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
