/* SPDX-License-Identifier: MIT
 * Radiosity scenes: validation of planar convex quads, the built-in test configurations, ray
 * queries and the closed-form point-to-polygon form factor.
 * Based on: Lambert 1760 / Baum, Rushmeier, Winget 1989 (point-to-polygon form factor);
 * Moller & Trumbore 1997 (ray-triangle test). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "radiosity_internal.h"

static void sub3(const double *a, const double *b, double *r)
{
    r[0] = a[0] - b[0], r[1] = a[1] - b[1], r[2] = a[2] - b[2];
}
static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(const double *a, const double *b, double *r)
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
static double norm3(const double *a) { return sqrt(dot3(a, a)); }

void wvol__rad_point(const rad_patch *p, double u, double v, double x[3])
{
    for (int k = 0; k < 3; k++) x[k] = p->o[k] + u * p->a[k] + v * p->b[k] + u * v * p->c[k];
}

double wvol__rad_jacobian(const rad_patch *p, double u, double v) { return p->j0 + p->ju * u + p->jv * v; }

static const char *label_of(const char *const *labels, size_t i, char *buf, size_t cap)
{
    if (labels && labels[i]) return labels[i];
    snprintf(buf, cap, "quad %zu", i);
    return buf;
}

static wvol_status build_patch(rad_patch *p, const wvol_radiosity_quad *q, const char *name, wvol_error *err)
{
    double e[4][3], cr[3], nrm = 0, diag, ab[3], ac[3], cb[3], d;
    int k, c;
    memset(p, 0, sizeof *p);
    p->q = *q;
    for (k = 0; k < 4; k++)
        for (c = 0; c < 3; c++)
            WVOL_RETURN_IF(!isfinite(q->p[k][c]), err, WVOL_ERR_NONFINITE, "%s: corner %d is not finite", name, k);
    for (c = 0; c < 3; c++) {
        WVOL_RETURN_IF(!isfinite(q->emission[c]) || q->emission[c] < 0, err,
                       isfinite(q->emission[c]) ? WVOL_ERR_ARG : WVOL_ERR_NONFINITE,
                       "%s: emission[%d] = %g must be finite and >= 0", name, c, q->emission[c]);
        WVOL_RETURN_IF(!isfinite(q->reflectance[c]) || q->reflectance[c] < 0 || q->reflectance[c] > 1, err,
                       isfinite(q->reflectance[c]) ? WVOL_ERR_ARG : WVOL_ERR_NONFINITE,
                       "%s: reflectance[%d] = %g must be in [0, 1]", name, c, q->reflectance[c]);
    }
    for (k = 0; k < 4; k++)
        for (int c = 0; c < 3; c++)
            WVOL_RETURN_IF(!isfinite(q->p[k][c]), err, WVOL_ERR_NONFINITE, "%s: corner %d coordinate %d is %g (not finite)",
                           name, k, c, q->p[k][c]);
    /* form factors take up to fourth powers of lengths: beyond 1e60, or edges below 1e-60, they
     * leave double's range (a convex quad would test as degenerate, its area as NaN) */
    for (k = 0; k < 4; k++)
        for (int c = 0; c < 3; c++)
            WVOL_RETURN_IF(fabs(q->p[k][c]) > 1e60, err, WVOL_ERR_ARG,
                           "%s: corner %d coordinate %d is %g: coordinates must lie within +-1e60 (form factors "
                           "take fourth powers of lengths); scale the scene",
                           name, k, c, q->p[k][c]);
    for (k = 0; k < 4; k++) sub3(q->p[(k + 1) % 4], q->p[k], e[k]);
    /* Newell normal: robust for any planar polygon */
    for (k = 0; k < 4; k++) {
        const double *a = q->p[k], *b = q->p[(k + 1) % 4];
        p->n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        p->n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        p->n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    nrm = norm3(p->n);
    diag = 0;
    for (k = 0; k < 4; k++) diag = fmax(diag, norm3(e[k]));
    WVOL_RETURN_IF(diag > 0 && diag < 1e-60, err, WVOL_ERR_ARG,
                   "%s: its longest edge is %g: quads must be at least 1e-60 across (form factors take fourth "
                   "powers of lengths); scale the scene",
                   name, diag);
    WVOL_RETURN_IF(!(diag > 0) || !(nrm > 1e-10 * diag * diag), err, WVOL_ERR_ARG,
                   "%s: degenerate quad (area %g)", name, nrm / 2);
    for (k = 0; k < 3; k++) p->n[k] /= nrm;
    for (k = 0; k < 4; k++) {
        WVOL_RETURN_IF(norm3(e[k]) <= 1e-9 * diag, err, WVOL_ERR_ARG, "%s: degenerate quad (edge %d has length 0)",
                       name, k);
        sub3(q->p[k], q->p[0], ab);
        d = dot3(ab, p->n);
        WVOL_RETURN_IF(fabs(d) > 1e-6 * diag, err, WVOL_ERR_ARG,
                       "%s: non-planar quad (corner %d is %g off the plane)", name, k, d);
        cross3(e[k], e[(k + 1) % 4], cr);
        WVOL_RETURN_IF(dot3(cr, p->n) <= 1e-10 * diag * diag, err, WVOL_ERR_ARG,
                       "%s: non-convex or degenerate quad (corner %d)", name, (k + 1) % 4);
    }
    for (c = 0; c < 3; c++) {
        p->o[c] = q->p[0][c];
        p->a[c] = q->p[1][c] - q->p[0][c];
        p->b[c] = q->p[3][c] - q->p[0][c];
        p->c[c] = q->p[0][c] - q->p[1][c] + q->p[2][c] - q->p[3][c];
    }
    /* x_u x x_v = (a + c v) x (b + c u) = a x b + u (a x c) + v (c x b): all along n */
    cross3(p->a, p->b, ab);
    cross3(p->a, p->c, ac);
    cross3(p->c, p->b, cb);
    p->j0 = dot3(ab, p->n);
    p->ju = dot3(ac, p->n);
    p->jv = dot3(cb, p->n);
    p->area = p->j0 + 0.5 * p->ju + 0.5 * p->jv;
    for (c = 0; c < 3; c++) {
        p->lo[c] = p->hi[c] = q->p[0][c];
        for (k = 1; k < 4; k++) p->lo[c] = fmin(p->lo[c], q->p[k][c]), p->hi[c] = fmax(p->hi[c], q->p[k][c]);
    }
    return WVOL_OK;
}

wvol_status wvol__rad_scene_build(wvol_radiosity_scene **out, const wvol_radiosity_quad *q, size_t n,
                                  const char *const *labels, wvol_error *err)
{
    wvol_radiosity_scene *s;
    char buf[64];
    size_t i;
    int c;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "radiosity scene: out is NULL");
    *out = NULL;
    WVOL_RETURN_IF(n == 0 || !q, err, WVOL_ERR_ARG, "radiosity scene: empty scene (no quads)");
    s = calloc(1, sizeof *s);
    if (s) s->p = calloc(n, sizeof *s->p);
    if (!s || !s->p) {
        free(s);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "radiosity scene: %zu quads", n);
    }
    s->n = n;
    for (i = 0; i < n; i++) {
        wvol_status st = build_patch(&s->p[i], &q[i], label_of(labels, i, buf, sizeof buf), err);
        if (st != WVOL_OK) {
            wvol_radiosity_scene_destroy(s);
            return st;
        }
        for (c = 0; c < 3; c++) {
            s->lo[c] = i ? fmin(s->lo[c], s->p[i].lo[c]) : s->p[i].lo[c];
            s->hi[c] = i ? fmax(s->hi[c], s->p[i].hi[c]) : s->p[i].hi[c];
        }
    }
    s->scale = sqrt((s->hi[0] - s->lo[0]) * (s->hi[0] - s->lo[0]) + (s->hi[1] - s->lo[1]) * (s->hi[1] - s->lo[1]) +
                    (s->hi[2] - s->lo[2]) * (s->hi[2] - s->lo[2]));
    *out = s;
    return WVOL_OK;
}

wvol_status wvol_radiosity_scene_create(wvol_radiosity_scene **out, const wvol_radiosity_quad *quads, size_t n,
                                        wvol_error *err)
{
    return wvol__rad_scene_build(out, quads, n, NULL, err);
}

void wvol_radiosity_scene_destroy(wvol_radiosity_scene *s)
{
    if (!s) return;
    free(s->p);
    free(s);
}

size_t wvol_radiosity_scene_count(const wvol_radiosity_scene *s) { return s ? s->n : 0; }

const wvol_radiosity_quad *wvol_radiosity_scene_quad(const wvol_radiosity_scene *s, size_t i)
{
    return s && i < s->n ? &s->p[i].q : NULL;
}

void wvol_radiosity_scene_quad_geometry(const wvol_radiosity_scene *s, size_t i, double *area, double normal[3])
{
    if (!s || i >= s->n) return;
    if (area) *area = s->p[i].area;
    if (normal) memcpy(normal, s->p[i].n, sizeof s->p[i].n);
}

void wvol_radiosity_scene_bounds(const wvol_radiosity_scene *s, double lo[3], double hi[3])
{
    if (!s) return;
    memcpy(lo, s->lo, sizeof s->lo);
    memcpy(hi, s->hi, sizeof s->hi);
}

/* ---- built-in scenes ---------------------------------------------------------------------- */

static void set_quad(wvol_radiosity_quad *q, const double c[4][3], double e, const double rho[3])
{
    memcpy(q->p, c, sizeof q->p);
    for (int k = 0; k < 3; k++) q->emission[k] = e, q->reflectance[k] = rho[k];
}

/* Axis-aligned rectangle at coordinate `at` along `axis`, spanning [a0,a1] x [b0,b1] in the other
 * two axes (cyclic order), facing +axis (sign > 0) or -axis. */
static void rect(wvol_radiosity_quad *q, int axis, double at, double a0, double a1, double b0, double b1, int sign,
                 double e, const double rho[3])
{
    double c[4][3];
    int ia = (axis + 1) % 3, ib = (axis + 2) % 3, k;
    double ua[4] = {a0, a1, a1, a0}, ub[4] = {b0, b0, b1, b1};
    for (k = 0; k < 4; k++) {
        int kk = sign > 0 ? k : (4 - k) % 4;
        c[k][axis] = at;
        c[k][ia] = ua[kk];
        c[k][ib] = ub[kk];
    }
    set_quad(q, c, e, rho);
}

static void block(wvol_radiosity_quad *q, double x0, double x1, double y0, double y1, double top, const double rho[3])
{
    rect(&q[0], 2, top, x0, x1, y0, y1, +1, 0, rho); /* top: axis z, (x, y) */
    rect(&q[1], 0, x0, y0, y1, 0, top, -1, 0, rho);  /* axis x: (y, z) */
    rect(&q[2], 0, x1, y0, y1, 0, top, +1, 0, rho);
    rect(&q[3], 1, y0, 0, top, x0, x1, -1, 0, rho);  /* axis y: (z, x) */
    rect(&q[4], 1, y1, 0, top, x0, x1, +1, 0, rho);
}

wvol_status wvol_radiosity_scene_builtin(wvol_radiosity_scene **out, const char *name, wvol_error *err)
{
    wvol_radiosity_quad q[48];
    static const double black[3] = {0, 0, 0}, white[3] = {1, 1, 1}, grey[3] = {0.75, 0.75, 0.75},
                        red[3] = {0.75, 0.2, 0.2}, green[3] = {0.2, 0.75, 0.2};
    size_t n = 0;
    WVOL_RETURN_IF(!name, err, WVOL_ERR_ARG, "radiosity scene: no name");
    memset(q, 0, sizeof q);
    if (!strcmp(name, "parallel")) {
        rect(&q[n++], 2, 0.1, -0.5, 0.5, -0.5, 0.5, -1, 1, black); /* emitter, side 1, facing down */
        rect(&q[n++], 2, 0.0, -1, 1, -1, 1, +1, 0, white);         /* receiver, side 2 */
    } else if (!strcmp(name, "perpendicular")) {
        rect(&q[n++], 1, 0.0, 0, 1, -0.5, 0.5, +1, 1, black); /* emitter in y = 0: z in [0,1], x in [-0.5,0.5] */
        rect(&q[n++], 2, 0.0, -1, 1, 0, 2, +1, 0, white);     /* receiver in z = 0: x in [-1,1], y in [0,2] */
    } else if (!strcmp(name, "box")) {
        /* floor tiles around the blocks' footprints: a patch reaching under a block would send light
         * from points no ray leaves (an energy leak of the model, not of the solver) */
        static const double gx[6] = {0, 0.15, 0.45, 0.55, 0.85, 1}, gy[6] = {0, 0.15, 0.45, 0.5, 0.8, 1};
        for (int i = 0; i < 5; i++)
            for (int j = 0; j < 5; j++)
                if (!(i == 1 && j == 3) && !(i == 3 && j == 1)) rect(&q[n++], 2, 0, gx[i], gx[i + 1], gy[j], gy[j + 1], +1, 0, grey);
        rect(&q[n++], 2, 1, 0, 1, 0, 0.4, -1, 0, grey);    /* ceiling ring around the light */
        rect(&q[n++], 2, 1, 0, 1, 0.6, 1, -1, 0, grey);
        rect(&q[n++], 2, 1, 0, 0.4, 0.4, 0.6, -1, 0, grey);
        rect(&q[n++], 2, 1, 0.6, 1, 0.4, 0.6, -1, 0, grey);
        rect(&q[n++], 2, 1, 0.4, 0.6, 0.4, 0.6, -1, 10, grey); /* light */
        rect(&q[n++], 0, 0, 0, 1, 0, 1, +1, 0, red);       /* x = 0 wall */
        rect(&q[n++], 0, 1, 0, 1, 0, 1, -1, 0, green);     /* x = 1 wall */
        rect(&q[n++], 1, 0, 0, 1, 0, 1, +1, 0, grey);      /* y = 0 wall (front) */
        rect(&q[n++], 1, 1, 0, 1, 0, 1, -1, 0, grey);      /* y = 1 wall (back) */
        block(&q[n], 0.15, 0.45, 0.5, 0.8, 0.6, grey);     /* tall block */
        n += 5;
        block(&q[n], 0.55, 0.85, 0.15, 0.45, 0.3, grey);   /* short block */
        n += 5;
    } else {
        return wvol_error_set(err, WVOL_ERR_ARG, "radiosity scene: unknown built-in '%s' (parallel, perpendicular, box)",
                              name);
    }
    return wvol__rad_scene_build(out, q, n, NULL, err);
}

/* ---- rays -------------------------------------------------------------------------------- */

/* Ray o + t d against triangle (a, b, c): t, or -1. */
static double tri_hit(const double *o, const double *d, const double *a, const double *b, const double *c)
{
    double e1[3], e2[3], pv[3], tv[3], qv[3], det, inv, u, v;
    sub3(b, a, e1);
    sub3(c, a, e2);
    cross3(d, e2, pv);
    det = dot3(e1, pv);
    if (fabs(det) < 1e-300) return -1;
    inv = 1.0 / det;
    sub3(o, a, tv);
    u = dot3(tv, pv) * inv;
    if (u < 0 || u > 1) return -1;
    cross3(tv, e1, qv);
    v = dot3(d, qv) * inv;
    if (v < 0 || u + v > 1) return -1;
    return dot3(e2, qv) * inv;
}

static double quad_hit(const rad_patch *p, const double *o, const double *d)
{
    const double(*c)[3] = p->q.p;
    double t = tri_hit(o, d, c[0], c[1], c[2]);
    if (t < 0) t = tri_hit(o, d, c[0], c[2], c[3]);
    return t;
}

int wvol__rad_occluded(const wvol_radiosity_scene *s, const double x[3], const double y[3], size_t skip1,
                       size_t skip2)
{
    double d[3], lo, hi;
    size_t i;
    int k;
    if (skip1 > skip2) { /* one direction per pair of patches: grazing rays then agree both ways */
        const double *t = x;
        x = y, y = t;
    }
    sub3(y, x, d);
    for (i = 0; i < s->n; i++) {
        const rad_patch *p = &s->p[i];
        double t;
        if (i == skip1 || i == skip2) continue;
        for (k = 0; k < 3; k++) { /* segment bounding box against the patch's */
            lo = fmin(x[k], y[k]), hi = fmax(x[k], y[k]);
            if (hi < p->lo[k] - 1e-12 || lo > p->hi[k] + 1e-12) break;
        }
        if (k < 3) continue;
        t = quad_hit(p, x, d);
        if (t > 1e-9 && t < 1 - 1e-9) return 1;
    }
    return 0;
}

/* Parameters (u, v) of a point x on patch p: Newton on the bilinear map, in the plane. */
static void invert_bilinear(const rad_patch *p, const double x[3], double *uo, double *vo)
{
    double u = 0.5, v = 0.5, r[3], xu[3], xv[3], y[3];
    for (int it = 0; it < 20; it++) {
        double a11, a12, a22, b1, b2, det, du, dv;
        wvol__rad_point(p, u, v, y);
        sub3(x, y, r);
        for (int k = 0; k < 3; k++) xu[k] = p->a[k] + v * p->c[k], xv[k] = p->b[k] + u * p->c[k];
        a11 = dot3(xu, xu), a12 = dot3(xu, xv), a22 = dot3(xv, xv);
        b1 = dot3(xu, r), b2 = dot3(xv, r);
        det = a11 * a22 - a12 * a12;
        if (!(fabs(det) > 0)) break;
        du = (a22 * b1 - a12 * b2) / det;
        dv = (a11 * b2 - a12 * b1) / det;
        u += du, v += dv;
        if (fabs(du) + fabs(dv) < 1e-14) break;
    }
    *uo = fmin(fmax(u, 0), 1);
    *vo = fmin(fmax(v, 0), 1);
}

long wvol__rad_hit(const wvol_radiosity_scene *s, const double o[3], const double d[3], double tmin, double *u,
                   double *v)
{
    long best = -1;
    double bt = INFINITY, x[3];
    for (size_t i = 0; i < s->n; i++) {
        double t;
        if (dot3(d, s->p[i].n) >= 0) continue; /* back face */
        t = quad_hit(&s->p[i], o, d);
        if (t > tmin && t < bt) bt = t, best = (long)i;
    }
    if (best >= 0) {
        for (int k = 0; k < 3; k++) x[k] = o[k] + bt * d[k];
        invert_bilinear(&s->p[best], x, u, v);
    }
    return best;
}

/* ---- closed-form form factor -------------------------------------------------------------- */

double wvol__rad_polygon_ff(const double (*poly)[3], int nv, const double x[3], const double n[3])
{
    double clip[8][3], r[8][3], sum = 0;
    int nc = 0, i, k;
    /* clip to the half-space (y - x) . n >= 0 (Sutherland-Hodgman with one plane) */
    for (i = 0; i < nv; i++) {
        const double *a = poly[i], *b = poly[(i + 1) % nv];
        double da = (a[0] - x[0]) * n[0] + (a[1] - x[1]) * n[1] + (a[2] - x[2]) * n[2];
        double db = (b[0] - x[0]) * n[0] + (b[1] - x[1]) * n[1] + (b[2] - x[2]) * n[2];
        if (da >= 0) memcpy(clip[nc++], a, sizeof clip[0]);
        if ((da >= 0) != (db >= 0)) {
            double t = da / (da - db);
            for (k = 0; k < 3; k++) clip[nc][k] = a[k] + t * (b[k] - a[k]);
            nc++;
        }
    }
    if (nc < 3) return 0;
    for (i = 0; i < nc; i++) {
        double len;
        sub3(clip[i], x, r[i]);
        len = norm3(r[i]);
        if (!(len > 0)) return 0;
        for (k = 0; k < 3; k++) r[i][k] /= len;
    }
    for (i = 0; i < nc; i++) {
        const double *a = r[i], *b = r[(i + 1) % nc];
        double g[3], gl, ang;
        cross3(a, b, g);
        gl = norm3(g);
        if (!(gl > 1e-300)) continue;
        ang = atan2(gl, dot3(a, b));
        sum += ang * dot3(g, n) / gl;
    }
    return fabs(sum) / (2 * M_PI);
}

double wvol_radiosity_point_form_factor(const wvol_radiosity_scene *s, size_t i, const double x[3],
                                        const double n[3])
{
    const rad_patch *p;
    double d[3];
    if (!s || i >= s->n) return 0;
    p = &s->p[i];
    sub3(x, p->o, d);
    if (dot3(d, p->n) <= 0) return 0; /* x behind the emitting side */
    return wvol__rad_polygon_ff(p->q.p, 4, x, n);
}

void wvol_radiosity_geometry(const wvol_radiosity_scene *s, wvol_geometry *g)
{
    double ext = 0;
    int k;
    if (!s || !g) return;
    for (k = 0; k < 3; k++) ext = fmax(ext, s->hi[k] - s->lo[k]);
    for (k = 0; k < 3; k++) {
        g->dims[k] = 1;
        g->spacing[k] = fmax(s->hi[k] - s->lo[k], 1e-3 * ext);
        g->origin[k] = 0.5 * (s->lo[k] + s->hi[k]);
    }
}
