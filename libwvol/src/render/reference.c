/* SPDX-License-Identifier: MIT
 * Reference integrator (paper eq 33): front-to-back compositing of samples taken at a
 * regular step along each ray, with step-corrected opacity alpha = 1 - exp(-kappa dt)
 * (or the linearised kappa dt in absorption-linear mode), early ray termination and
 * empty-space skipping over a min/max brick grid. Samples are trilinear interpolation of
 * the voxels, or f^ through the spline tables (the converged reference of the spline model).
 * Based on: Levoy 1988 (ray casting); Max 1995 (optical models); DESIGN.md section 8. */
#include "render_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>



static double trilinear_slow(const wvol_volume *v, const double x[3]);

/* Trilinear sample at index position x; the common case (strictly inside the sample grid)
 * without clamping branches. */
static inline double trilinear(const wvol_volume *v, const double x[3])
{
    size_t nx = v->nx, ny = v->ny;
    if (x[0] > 0 && x[1] > 0 && x[2] > 0 && x[0] < (double)(nx - 1) && x[1] < (double)(ny - 1) &&
        x[2] < (double)(v->nz - 1)) {
        size_t i = (size_t)x[0], j = (size_t)x[1], k = (size_t)x[2];
        double wx = x[0] - (double)i, wy = x[1] - (double)j, wz = x[2] - (double)k;
        const float *p = v->data + i + nx * (j + ny * k);
        size_t sy = nx, sz = nx * ny;
        double c00 = p[0] + wx * (p[1] - p[0]);
        double c10 = p[sy] + wx * (p[sy + 1] - p[sy]);
        double c01 = p[sz] + wx * (p[sz + 1] - p[sz]);
        double c11 = p[sz + sy] + wx * (p[sz + sy + 1] - p[sz + sy]);
        double c0 = c00 + wy * (c10 - c00), c1 = c01 + wy * (c11 - c01);
        return c0 + wz * (c1 - c0);
    }
    return trilinear_slow(v, x);
}

static double trilinear_slow(const wvol_volume *v, const double x[3])
{
    size_t n[3] = {v->nx, v->ny, v->nz}, i0[3], i1[3];
    double w[3];
    int a;
    for (a = 0; a < 3; a++) {
        double xa = x[a], f;
        if (n[a] == 1 || !(xa > 0)) {
            i0[a] = i1[a] = 0;
            w[a] = 0;
            if (n[a] > 1 && xa != xa) w[a] = 0;
            continue;
        }
        if (xa >= (double)(n[a] - 1)) {
            i0[a] = i1[a] = n[a] - 1;
            w[a] = 0;
            continue;
        }
        f = floor(xa);
        i0[a] = (size_t)f;
        i1[a] = i0[a] + 1;
        w[a] = xa - f;
    }
    {
        const float *d = v->data;
        size_t sx = 1, sy = v->nx, sz = v->nx * v->ny;
        size_t b00 = i0[1] * sy + i0[2] * sz, b10 = i1[1] * sy + i0[2] * sz, b01 = i0[1] * sy + i1[2] * sz,
               b11 = i1[1] * sy + i1[2] * sz;
        double c00 = d[b00 + i0[0] * sx] + w[0] * (d[b00 + i1[0] * sx] - d[b00 + i0[0] * sx]);
        double c10 = d[b10 + i0[0] * sx] + w[0] * (d[b10 + i1[0] * sx] - d[b10 + i0[0] * sx]);
        double c01 = d[b01 + i0[0] * sx] + w[0] * (d[b01 + i1[0] * sx] - d[b01 + i0[0] * sx]);
        double c11 = d[b11 + i0[0] * sx] + w[0] * (d[b11 + i1[0] * sx] - d[b11 + i0[0] * sx]);
        double c0 = c00 + w[1] * (c10 - c00), c1 = c01 + w[1] * (c11 - c01);
        return c0 + w[2] * (c1 - c0);
    }
}

/* Value at index position x; world gradient into grad when not NULL. */
static double sample_at(const wvol__sampler *s, const double x[3], double grad[3])
{
    if (s->v) {
        double val = trilinear(s->v, x);
        if (grad) {
            int a;
            for (a = 0; a < 3; a++) {
                double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
                xp[a] += 0.5;
                xm[a] -= 0.5;
                grad[a] = (trilinear(s->v, xp) - trilinear(s->v, xm)) / s->spacing[a];
            }
        }
        return val;
    } else {
        double g[3], val = s->eval(s->ctx, x, grad ? g : NULL);
        if (grad) {
            int a;
            for (a = 0; a < 3; a++) grad[a] = g[a] / s->spacing[a];
        }
        return val;
    }
}

/* The colour volume's RGB at the voxel nearest to index position x (clamped to the grid):
 * nearest rather than trilinear so that segmented classes keep their own colours. */
static void nearest_color(const wvol__sampler *s, const float *colors, const double x[3], double rgb[3])
{
    size_t i[3], off;
    int a;
    for (a = 0; a < 3; a++) {
        double r = floor(x[a] + 0.5);
        i[a] = r > 0 ? (size_t)r : 0;
        if (i[a] > s->n[a] - 1) i[a] = s->n[a] - 1;
    }
    off = 3 * (i[0] + s->n[0] * (i[1] + s->n[1] * i[2]));
    for (a = 0; a < 3; a++) rgb[a] = colors[off + (size_t)a];
}

/* Largest kappa of the TF over [lo, hi] (piecewise linear: endpoints and knots inside). */
static double tf_max_kappa(const wvol_tf *tf, double lo, double hi)
{
    double k, m;
    int i;
    wvol_tf_eval(tf, lo, NULL, &m);
    wvol_tf_eval(tf, hi, NULL, &k);
    if (k > m) m = k;
    for (i = 0; i < tf->count; i++)
        if (tf->points[i].value > lo && tf->points[i].value < hi && tf->points[i].opacity > m) m = tf->points[i].opacity;
    return m;
}

/* Marks bricks whose samples cannot contribute. Each brick covers the voxel cells
 * [b*B - 1/2, (b+1)*B - 1/2) and its min/max is taken over voxels b*B-1 .. (b+1)*B, every
 * voxel a trilinear sample inside the brick can touch. */
static wvol_status build_bricks(wvol__sampler *s, const wvol_tf *tf, wvol_render_mode mode, wvol_error *err)
{
    const wvol_volume *v = s->v;
    size_t bi, bj, bk, nb;
    int a, B = s->B;
    for (a = 0; a < 3; a++) s->bn[a] = (s->n[a] + (size_t)B - 1) / (size_t)B;
    nb = s->bn[0] * s->bn[1] * s->bn[2];
    s->empty = malloc(nb);
    WVOL_RETURN_IF(!s->empty, err, WVOL_ERR_NOMEM, "render: out of memory for %zu bricks", nb);
    for (bk = 0; bk < s->bn[2]; bk++)
        for (bj = 0; bj < s->bn[1]; bj++)
            for (bi = 0; bi < s->bn[0]; bi++) {
                size_t lo[3], hi[3], b[3] = {bi, bj, bk}, i, j, k;
                double mn = INFINITY, mx = -INFINITY;
                for (a = 0; a < 3; a++) {
                    lo[a] = b[a] * (size_t)B;
                    lo[a] = lo[a] > 0 ? lo[a] - 1 : 0;
                    hi[a] = (b[a] + 1) * (size_t)B + 1;
                    if (hi[a] > s->n[a]) hi[a] = s->n[a];
                }
                for (k = lo[2]; k < hi[2]; k++)
                    for (j = lo[1]; j < hi[1]; j++) {
                        const float *row = v->data + v->nx * (j + v->ny * k);
                        for (i = lo[0]; i < hi[0]; i++) {
                            if (row[i] < mn) mn = row[i];
                            if (row[i] > mx) mx = row[i];
                        }
                    }
                s->empty[bi + s->bn[0] * (bj + s->bn[1] * bk)] =
                    mode == WVOL_MODE_XRAY ? (mn == 0 && mx == 0) : (tf_max_kappa(tf, mn, mx) <= 0);
            }
    return WVOL_OK;
}

/* Index of the brick holding x (clamped to the grid). */
static inline long brick_id(const wvol__sampler *s, const double x[3])
{
    long b[3];
    int a;
    for (a = 0; a < 3; a++) {
        double c = (x[a] + 0.5) / s->B;
        b[a] = c > 0 ? (long)c : 0;
        if (b[a] > (long)s->bn[a] - 1) b[a] = (long)s->bn[a] - 1;
    }
    return b[0] + (long)s->bn[0] * (b[1] + (long)s->bn[1] * b[2]);
}

/* If x lies in an empty brick, the ray parameter where the ray (index direction e) leaves it. */
static int empty_exit(const wvol__sampler *s, const double x[3], const double e[3], double t, double *t_exit)
{
    size_t b[3];
    int a;
    double te = INFINITY;
    for (a = 0; a < 3; a++) {
        double c = floor((x[a] + 0.5) / s->B);
        if (c < 0) c = 0;
        if (c > (double)(s->bn[a] - 1)) c = (double)(s->bn[a] - 1);
        b[a] = (size_t)c;
    }
    if (!s->empty[b[0] + s->bn[0] * (b[1] + s->bn[1] * b[2])]) return 0;
    for (a = 0; a < 3; a++) {
        double lo = (double)b[a] * s->B - 0.5, hi = lo + s->B, ta;
        if (e[a] > 0) ta = (hi - x[a]) / e[a];
        else if (e[a] < 0) ta = (lo - x[a]) / e[a];
        else continue;
        if (ta < te) te = ta;
    }
    *t_exit = t + te;
    return 1;
}

typedef struct ray_out {
    double rgba[4];
    size_t samples, skipped;
    int terminated, clamped;
} ray_out;

static void march(const wvol__sampler *s, const wvol_tf *tf, const wvol_render_params *p, const double o[3],
                  const double d[3], double t0, double t1, double dt, ray_out *out)
{
    double x0[3], e[3], T = 1.0, acc[3] = {0, 0, 0}, xr = 0;
    long k, nsteps;
    int a;
    for (a = 0; a < 3; a++) {
        x0[a] = (o[a] - s->origin[a]) / s->spacing[a];
        e[a] = d[a] / s->spacing[a];
    }
    long last_brick = -1;
    int last_empty = 0;
    nsteps = (long)ceil((t1 - t0) / dt);
    if (nsteps < 1) nsteps = 1;
    for (k = 0; k < nsteps; k++) {
        double ta = t0 + k * dt, tb = ta + dt, t, x[3], val, grad[3], rgb[3], kappa, h;
        if (tb > t1) tb = t1;
        h = tb - ta;
        if (!(h > 0)) break;
        t = 0.5 * (ta + tb);
        for (a = 0; a < 3; a++) x[a] = x0[a] + t * e[a];
        if (s->empty) {
            double te;
            long bid = brick_id(s, x);
            if (bid != last_brick) {
                last_brick = bid;
                last_empty = s->empty[bid];
            }
            if (last_empty && empty_exit(s, x, e, t, &te)) {
                long kn = (long)floor((te - t0) / dt);
                out->skipped++;
                if (kn > k) k = kn - 1;
                continue;
            }
        }
        out->samples++;
        if (p->mode == WVOL_MODE_XRAY) {
            xr += sample_at(s, x, NULL) * h;
            continue;
        }
        val = sample_at(s, x, NULL);
        wvol_tf_eval(tf, val, rgb, &kappa);
        if (kappa > 0 && p->colors) nearest_color(s, p->colors, x, rgb);
        if (kappa > 0) {
            double alpha, shade = 1.0;
            if (p->mode == WVOL_MODE_ABSORPTION) {
                alpha = -expm1(-kappa * h);
            } else {
                alpha = kappa * h;
                if (alpha > 1) {
                    alpha = 1;
                    out->clamped++;
                }
            }
            if (p->shading) {
                sample_at(s, x, grad);
                shade = wvol__shade(grad, d, p->ambient);
            }
            for (a = 0; a < 3; a++) acc[a] += T * alpha * rgb[a] * shade;
            T *= 1.0 - alpha;
            if (T < p->termination) {
                out->terminated = 1;
                break;
            }
        }
    }
    if (p->mode == WVOL_MODE_XRAY) {
        out->rgba[0] = out->rgba[1] = out->rgba[2] = xr;
        out->rgba[3] = 1.0;
    } else {
        for (a = 0; a < 3; a++) out->rgba[a] = acc[a];
        out->rgba[3] = 1.0 - T;
    }
}

wvol_status wvol__render_sampled(wvol_image *img, wvol__sampler *s, const wvol_camera *cam, const wvol_tf *tf_in,
                          const wvol_render_params *pin, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_geometry g;
    wvol_tf tf;
    wvol__cam k;
    double lo[3], hi[3], dt, t_start, c_start;
    int ntiles, tx, a;
    size_t rays_hit = 0, samples = 0, skipped = 0, terminated = 0, clamped = 0;

    wvol__params(&p, pin);
    WVOL_FORWARD(wvol__render_check(img, cam, tf_in, &p, err));
    WVOL_FORWARD(wvol__check_colors(&p, s->n, 1, err));
    for (a = 0; a < 3; a++) {
        g.dims[a] = s->n[a];
        g.spacing[a] = s->spacing[a];
        g.origin[a] = s->origin[a];
        WVOL_RETURN_IF(!(s->spacing[a] > 0) || !isfinite(s->spacing[a]) || !isfinite(s->origin[a]), err, WVOL_ERR_ARG,
                       "render: spacing and origin must be finite, spacing > 0");
    }
    if (p.mode != WVOL_MODE_XRAY) wvol__tf_world(&tf, tf_in, &g);
    else memset(&tf, 0, sizeof tf);
    wvol_geometry_bounds(&g, lo, hi);
    dt = p.step * fmin(s->spacing[0], fmin(s->spacing[1], s->spacing[2]));
    t_start = wvol__now();
    c_start = wvol__cpu_now();
    s->empty = NULL;
    if (s->v && p.brick > 0) {
        s->B = p.brick;
        WVOL_FORWARD(build_bricks(s, &tf, p.mode, err));
    }
    wvol__cam_init(&k, cam);
    ntiles = wvol__tiles(img->width, img->height, p.tile);
    tx = (img->width + p.tile - 1) / p.tile;
#pragma omp parallel for schedule(dynamic, 1) num_threads(wvol__threads(p.threads)) \
    reduction(+ : rays_hit, samples, skipped, terminated, clamped)
    for (int ti = 0; ti < ntiles; ti++) {
        int x0 = (ti % tx) * p.tile, y0 = (ti / tx) * p.tile, x, y;
        for (y = y0; y < y0 + p.tile && y < img->height; y++)
            for (x = x0; x < x0 + p.tile && x < img->width; x++) {
                double o[3], d[3], t0, t1;
                float *px = img->rgba + 4 * ((size_t)x + (size_t)img->width * (size_t)y);
                ray_out r;
                memset(&r, 0, sizeof r);
                wvol__cam_ray(&k, x + 0.5, y + 0.5, o, d);
                if (wvol__ray_box(o, d, lo, hi, &t0, &t1)) {
                    if (cam->projection == WVOL_PERSPECTIVE && t0 < 0) t0 = 0;
                    if (t1 > t0) {
                        rays_hit++;
                        march(s, &tf, &p, o, d, t0, t1, dt, &r);
                    }
                }
                for (int c = 0; c < 4; c++) px[c] = (float)r.rgba[c];
                samples += r.samples;
                skipped += r.skipped;
                terminated += (size_t)r.terminated;
                clamped += (size_t)r.clamped;
            }
    }
    free(s->empty);
    s->empty = NULL;
    if (stats) {
        memset(stats, 0, sizeof *stats);
        stats->seconds = wvol__now() - t_start;
        stats->cpu_seconds = wvol__cpu_now() - c_start;
        stats->rays = (size_t)img->width * (size_t)img->height;
        stats->rays_hit = rays_hit;
        stats->samples = samples;
        stats->skipped = skipped;
        stats->terminated = terminated;
        stats->clamped = clamped;
    }
    return WVOL_OK;
}

wvol_status wvol_render_reference(wvol_image *img, const wvol_volume *v, const wvol_camera *cam, const wvol_tf *tf,
                                  const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol__sampler s;
    int a;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "render: no volume");
    memset(&s, 0, sizeof s);
    s.v = v;
    s.n[0] = v->nx;
    s.n[1] = v->ny;
    s.n[2] = v->nz;
    for (a = 0; a < 3; a++) {
        s.spacing[a] = v->spacing[a];
        s.origin[a] = v->origin[a];
    }
    return wvol__render_sampled(img, &s, cam, tf, params, stats, err);
}
