/* SPDX-License-Identifier: MIT
 * Spline-projected integrator (paper eqs 34-47, DESIGN.md section 8): the low-albedo
 * integral along each ray from the kept basis functions of a store, with no dense volume.
 *
 * Along a ray x(t) = o + t d (voxel coordinates, t the world ray parameter) a basis
 * function of level m is norm * prod_a B_a((x_a(t) - lo_a) / 2^m), each factor a cubic
 * spline piece in t between the knots x_a + s in 2^{m-J} Z. All levels' knots lie on the
 * finest lattice x_a + s in 2^{1-J} Z, so f^(t) is one polynomial of degree <= 9 on each
 * piece between consecutive lattice crossings. Per ray (store/ray_pieces.c): the lattice
 * pieces are merged from the three axes, the store's octree query gives the basis functions
 * the ray crosses, and each one adds (three composed cubics multiplied out) to the
 * polynomial of every piece it covers, in the piece's normalised variable u in [0, 1]. The
 * modes then integrate those polynomials: exactly (X-ray), or with the optical depth exact and the exponential sampled
 * at Gauss-Legendre nodes of sub-pieces split where f^ crosses a TF knot (absorption).
 * Based on: Gross, Lippert et al. (paper, section 5); Max 1995; Weiss & Westermann 2021
 * (ray splitting at TF control points). */
#include "render_internal.h"
#include "store/store_ray.h"
#include "core/quadrature.h"

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

/* Integral of the polynomial from 0 to u. */
static double pint(const double *a, double u)
{
    double r = a[NC - 1] / NC;
    int k;
    for (k = NC - 2; k >= 0; k--) r = r * u + a[k] / (k + 1);
    return r * u;
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

static void integrate(const spline_ctx *c, ray_ws *ws, const double d_world[3], ray_res *r)
{
    const wvol_render_params *p = &c->p;
    double T = 1.0, col[3] = {0, 0, 0}, xr = 0;
    size_t e, E = ws->lev[1].E;
    const double *Tb = ws->lev[1].T;
    int ch, q, m;
    if (p->mode == WVOL_RENDER_MODE_XRAY) {
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
                Tq = p->mode == WVOL_RENDER_MODE_ABSORPTION ? T * exp(-dtau) : T * fmax(0.0, 1.0 - dtau);
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
            if (p->mode == WVOL_RENDER_MODE_ABSORPTION) {
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

static wvol_status trace(const spline_ctx *c, ray_ws *ws, const double ow[3], const double dw[3], double ta, double tb,
                         ray_res *r, wvol_error *err)
{
    double o[3], d[3];
    wvol__spline_count cnt = {0, 0};
    wvol_store_world_to_voxel(c->g.s, ow, o);
    wvol_store_dir_to_voxel(c->g.s, dw, d);
    WVOL_FORWARD(wvol__spline_ray(&c->g, ws, o, d, ta, tb, c->p.shading, c->p.mode != WVOL_RENDER_MODE_XRAY, &cnt, err));
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
    WVOL_RETURN_IF(c.p.gradient_levels > 0, err, WVOL_ERR_UNSUPPORTED,
                   "render: gradient_levels is for method bricks (spline shades with the model's exact gradient)");
    WVOL_RETURN_IF(c.p.preintegrate, err, WVOL_ERR_UNSUPPORTED,
                   "render: pre-integration is for the sampling methods (reference, reference-fhat, bricks); spline "
                   "integrates the model exactly already");
    WVOL_FORWARD(wvol__spline_geom_init(&c.g, s, err));
    for (a = 0; a < 3; a++) {
        g.dims[a] = a == 0 ? c.g.info.nx : a == 1 ? c.g.info.ny : c.g.info.nz;
        g.spacing[a] = c.g.info.spacing[a];
        g.origin[a] = c.g.info.origin[a];
    }
    if (c.p.mode != WVOL_RENDER_MODE_XRAY) wvol__tf_world(&c.tf, tf_in, &g);
    c.stop = stop;
    c.gl_n = c.p.spline.gauss_nodes;
    wvol__gauss_legendre(c.gl_n, c.gl_x, c.gl_w);
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
                        if (cam->projection == WVOL_PROJECTION_PERSPECTIVE && t0 < 0) t0 = 0;
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
    return wvol__image_check_range(img, err);
}
