/* SPDX-License-Identifier: MIT */
/* Ray tracing the implicit surface f^ = iso of a coefficient store with no missed hit
 * (Kalra-Barr's guarantee), on the exact piecewise-polynomial form of f^ along the ray.
 *
 * Along x(t) = o + t d, f^(t) is one polynomial of degree <= 9 on each piece between
 * consecutive knots of the finest spline lattice (store/store_ray.h: the kept basis
 * functions whose support the ray crosses, from the store's octree, each a product of three
 * composed cubic pieces). The ray is cut into chunks of `chunk` voxels, built one after the
 * other front to back, so a ray that meets the surface early builds little; in an image, the
 * chunk that holds the previous pixel's hit ends just past it (trace_ray.c, trace_span), so
 * little is built past a hit there either. On each piece:
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
 * Cost. Building the polynomials (factorised per piece: store/store_ray.h) and the store's
 * queries are the expense; two rigorous shortcuts avoid most:
 *   - small functions (the smallest |c| max|w|, summing to <= 1/16 of the chunk's largest)
 *     are not expanded but bounded per piece (sum of |c| max|w| of those covering it); a
 *     piece whose hull widened by that envelope excludes iso is decided, and only runs of
 *     undecided pieces get the small functions added exactly;
 *   - images walk a hierarchy of cells (16 down to 2 voxels), each classified the first time
 *     a ray reaches it by wvol__iso_box_range (low-pass coefficients fitted by a plane through
 *     the spline's partition of unity and first moment, every other term the interval of its
 *     function's range on the cell): rays step over cells whose range excludes iso and trace
 *     runs of the others; an undecided cell's children are classified only where that can pay
 *     (more so the denser the rays: trace_cells.c).
 *
 * The guarantee. "Crossing" means f^ - iso changes sign in the classification f^ >= iso.
 * For the computed piece polynomials, the reported hit is the first crossing along the ray
 * inside the sample extent [0, n-1] (and t >= tmin), with |t - t*| <= tolerance / 2, except
 * that a pair of crossings closer together than tolerance / 8 may be skipped (a graze).
 * Rounding: the piece polynomials are sums of products of the spline tables' cubics in
 * float64; pad = 1e-10 (sum of |B_j| terms + |iso|), far above their rounding, so a rounded
 * coefficient never hides a sign; the envelope and the cell bounds are padded alike.
 * Based on: Kalra & Barr 1989; Lane & Riesenfeld 1981 (Bernstein subdivision root isolation);
 * DESIGN.md section 9; docs/iso.md.
 * This file: the API (one ray, an image, the hybrid picture). One ray: trace_ray.c; the
 * bounds and the cell grid: trace_cells.c. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/clock.h"
#include "iso_internal.h"
#include "wvol/iso.h"

typedef wvol__tracer tracer;
typedef wvol__trace_ws tws;

void wvol_iso_trace_params_default(wvol_iso_trace_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->tolerance = 0.0; /* 1e-3 of the smallest spacing */
    p->chunk = 16.0;
    p->threads = 0;
    p->color[0] = 0.93f, p->color[1] = 0.89f, p->color[2] = 0.80f;
    p->ambient = 0.15f;
}

wvol_status wvol__iso_image_check(const wvol_image *img, const wvol_camera *cam, const char *what, wvol_error *err)
{
    WVOL_RETURN_IF(!img || !img->rgba, err, WVOL_ERR_ARG, "%s: no image", what);
    WVOL_RETURN_IF(!cam, err, WVOL_ERR_ARG, "%s: no camera", what);
    WVOL_FORWARD(wvol_camera_check(cam, err));
    WVOL_RETURN_IF(cam->width != img->width || cam->height != img->height, err, WVOL_ERR_ARG,
                   "%s: image %dx%d does not match the camera's %dx%d", what, img->width, img->height, cam->width,
                   cam->height);
    return WVOL_OK;
}

wvol_status wvol__iso_shading_check(const double light[3], const float color[3], float ambient, const char *what,
                                    wvol_error *err)
{
    WVOL_RETURN_IF(!(ambient >= 0 && ambient <= 1), err, WVOL_ERR_ARG, "%s: ambient %g (must be in [0, 1])", what,
                   (double)ambient);
    for (int a = 0; a < 3; a++) {
        WVOL_RETURN_IF(!isfinite(light[a]), err, WVOL_ERR_ARG, "%s: light[%d] = %g (must be finite)", what, a,
                       light[a]);
        WVOL_RETURN_IF(!isfinite(color[a]), err, WVOL_ERR_ARG, "%s: colour[%d] = %g (must be finite)", what, a,
                       (double)color[a]);
    }
    return WVOL_OK;
}

void wvol__iso_shade(float rgba[4], const wvol_iso_hit *h, const double d[3], const double light[3],
                     const float color[3], float ambient)
{
    double l[3], ll = 0.0, lam = 0.0;
    int a, head = !(light[0] || light[1] || light[2]);
    if (!h->hit) {
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
        return;
    }
    for (a = 0; a < 3; a++) {
        l[a] = head ? -d[a] : light[a];
        ll += l[a] * l[a];
    }
    ll = sqrt(ll);
    for (a = 0; a < 3; a++) lam += h->normal[a] * l[a] / ll;
    lam = fabs(lam); /* two-sided */
    for (a = 0; a < 3; a++) rgba[a] = (float)(color[a] * (ambient + (1.0 - ambient) * lam));
    rgba[3] = 1.0f;
}

void wvol__iso_model_extent(const wvol_store *s, double lo[3], double hi[3])
{
    const wvol_basis *b = wvol_store_basis(s);
    wvol_store_info info;
    size_t n[3], P[3];
    double r0 = 0.0, r1 = 0.0, vmax = 0.0, *pm;
    int i, a, k, deg1;
    wvol_store_get_info(s, &info);
    n[0] = info.nx, n[1] = info.ny, n[2] = info.nz;
    P[0] = info.px, P[1] = info.py, P[2] = info.pz;
    for (a = 0; a < 3; a++) lo[a] = 0.0, hi[a] = (double)n[a] - 1.0;
    if (!b) return;
    r1 = b->support;
    deg1 = b->exact ? 1 : 4;
    pm = malloc((size_t)b->pieces * sizeof *pm);
    if (pm && !b->exact) { /* per piece a bound of |phi|: the sum of its |coefficients| */
        for (i = 0; i < b->pieces; i++) {
            pm[i] = 0;
            for (k = 0; k < deg1; k++) pm[i] += fabs(b->phi[deg1 * i + k]);
            if (pm[i] > vmax) vmax = pm[i];
        }
        for (i = 0; i < b->pieces && pm[i] <= 1e-3 * vmax; i++) r0 = (i + 1) * b->h;
        for (i = b->pieces - 1; i >= 0 && pm[i] <= 1e-3 * vmax; i--) r1 = i * b->h;
    }
    free(pm);
    for (a = 0; a < 3; a++) {
        if (!info.transformed[a]) continue;
        lo[a] = fmax(0.0, r1 - 1.0 - b->center);
        hi[a] = fmin((double)n[a] - 1.0, (double)P[a] + r0 - b->center);
    }
}

static wvol_status make_tracer(tracer *tr, const wvol_store *s, double iso, const wvol_iso_trace_params *p,
                               wvol_error *err)
{
    double smin;
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "iso trace: store is NULL");
    WVOL_RETURN_IF(!isfinite(iso), err, WVOL_ERR_ARG, "iso trace: iso-value %g is not finite", iso);
    WVOL_RETURN_IF(p && (!isfinite(p->tolerance) || !isfinite(p->chunk) || p->chunk < 0), err, WVOL_ERR_ARG,
                   "iso trace: tolerance %g / chunk %g not valid", p->tolerance, p->chunk);
    /* a ray is built a chunk at a time: chunks far below a voxel would take without end */
    WVOL_RETURN_IF(p && p->chunk > 0 && p->chunk < 0.5, err, WVOL_ERR_ARG,
                   "iso trace: chunk %g voxels is below 0.5 (0: the default, 16)", p->chunk);
    if (p) {
        WVOL_RETURN_IF(p->surface != WVOL_ISO_SURFACE_EXACT && p->surface != WVOL_ISO_SURFACE_CAST, err, WVOL_ERR_ARG,
                       "iso trace: unknown surface %d (0: exact, 1: cast)", (int)p->surface);
        WVOL_FORWARD(wvol__iso_shading_check(p->light, p->color, p->ambient, "iso trace", err));
    }
    memset(tr, 0, sizeof *tr);
    WVOL_FORWARD(wvol__spline_geom_init(&tr->g, s, err));
    tr->iso = iso;
    smin = fmin(tr->g.info.spacing[0], fmin(tr->g.info.spacing[1], tr->g.info.spacing[2]));
    /* the depth is refined by bisection in float64: a tolerance near the positions' rounding
     * cannot be reached */
    WVOL_RETURN_IF(p && p->tolerance > 0 && p->tolerance < 1e-9 * smin, err, WVOL_ERR_ARG,
                   "iso trace: tolerance %g is below 1e-9 of the smallest spacing %g (<= 0: the default)",
                   p->tolerance, smin);
    tr->tol = p && p->tolerance > 0 ? p->tolerance : 1e-3 * smin;
    tr->chunk = p && p->chunk > 0 ? p->chunk : 16.0;
    wvol__iso_boxk_init(&tr->k, s);
    wvol__iso_model_extent(s, tr->lo, tr->hi);
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
    if (!(len > 0) || !isfinite(len)) {
        wvol__iso_boxk_free(&tr.k);
        return wvol_error_set(err, WVOL_ERR_ARG, "iso trace: direction has no length");
    }
    dn[0] = d[0] / len, dn[1] = d[1] / len, dn[2] = d[2] / len;
    memset(&ws, 0, sizeof ws);
    st = wvol__trace(&tr, &ws, o, dn, 0.0, hit, err);
    wvol__trace_ws_free(&ws);
    wvol__iso_boxk_free(&tr.k);
    return st;
}

/* The empty-image message. Every cell decided alike proves iso outside the range of f^;
 * otherwise the samples of the reconstruction (which f^ interpolates to the spline's error)
 * tell whether iso is outside the data's range. */
static void empty_message(const tracer *tr, double iso, char *msg, size_t cap)
{
    size_t cnt[3] = {0, 0, 0}, total;
    wvol_coeffs *c = NULL;
    wvol_volume *v = NULL;
    wvol_store_hits hl;
    double vmin = 0, vmax = 0;
    memset(&hl, 0, sizeof hl);
    wvol__trace_cells_top(tr, &hl, cnt);
    wvol_store_hits_free(&hl);
    total = cnt[0] + cnt[1] + cnt[2];
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

/* The distance (voxels) between the rays of neighbouring pixels where the central pixel's ray
 * passes closest to the volume's centre: the geometric mean over the two image axes, 0 when
 * not defined. */
static double ray_spacing(const tracer *tr, const wvol_camera *cam)
{
    double o[3][3], d[3][3], ov[3][3], dv[3][3], c[3], t, dd = 0, sp[2];
    double px = 0.5 * cam->width, py = 0.5 * cam->height;
    int a, k;
    c[0] = 0.5 * ((double)tr->g.info.nx - 1), c[1] = 0.5 * ((double)tr->g.info.ny - 1), c[2] = 0.5 * ((double)tr->g.info.nz - 1);
    wvol_camera_ray(cam, px, py, o[0], d[0]);
    wvol_camera_ray(cam, px + 1, py, o[1], d[1]);
    wvol_camera_ray(cam, px, py + 1, o[2], d[2]);
    for (k = 0; k < 3; k++) {
        wvol_store_world_to_voxel(tr->g.s, o[k], ov[k]);
        wvol_store_dir_to_voxel(tr->g.s, d[k], dv[k]);
    }
    for (t = 0, a = 0; a < 3; a++) t += (c[a] - ov[0][a]) * dv[0][a], dd += dv[0][a] * dv[0][a];
    if (!(dd > 0)) return 0;
    t /= dd;
    for (k = 0; k < 2; k++) {
        double s2 = 0;
        for (a = 0; a < 3; a++) {
            double q = (ov[k + 1][a] + t * dv[k + 1][a]) - (ov[0][a] + t * dv[0][a]);
            s2 += q * q;
        }
        sp[k] = sqrt(s2);
    }
    t = sqrt(sp[0] * sp[1]);
    return isfinite(t) ? t : 0;
}

wvol_status wvol_iso_raytrace(wvol_image *img, float *depth, float *normals, const wvol_store *s,
                              const wvol_camera *cam, double iso, const wvol_iso_trace_params *p,
                              wvol_iso_trace_stats *st, wvol_error *err)
{
    tracer tr;
    wvol_iso_trace_params def;
    int nth, failed = 0;
    size_t hits = 0, functions = 0, pieces = 0, refined = 0, intervals = 0, evals = 0, grazes = 0, cells = 0;
    double t_start = wvol__now(), c_start = wvol__cpu_now(), tmin, t_cells = 0;
    wvol_error first_err;
    WVOL_FORWARD(wvol__iso_image_check(img, cam, "iso trace", err));
    if (!p) {
        wvol_iso_trace_params_default(&def);
        p = &def;
    }
    WVOL_FORWARD(wvol__threads_check(p->threads, "iso trace", err));
    WVOL_FORWARD(make_tracer(&tr, s, iso, p, err));
    nth = wvol__threads(p->threads);
    if (wvol__trace_cells(&tr, ray_spacing(&tr, cam), err) != WVOL_OK) {
        wvol__trace_cells_free(&tr);
        wvol__iso_boxk_free(&tr.k);
        return err ? err->status : WVOL_ERR_INTERNAL;
    }
    /* an orthographic ray is the whole line (as in the renderer); a perspective one starts at the eye */
    tmin = cam->projection == WVOL_PROJECTION_PERSPECTIVE ? 0.0 : -INFINITY;
    wvol_error_clear(&first_err);
#pragma omp parallel num_threads(nth) reduction(+ : hits, functions, pieces, refined, intervals, evals, grazes, cells, t_cells)
    {
        tws ws;
        memset(&ws, 0, sizeof ws);
#pragma omp for schedule(dynamic, 1)
        for (int row = 0; row < img->height; row++) {
            for (int x = 0; x < img->width; x++) {
                double o[3], d[3];
                wvol_iso_hit h;
                size_t px = (size_t)row * (size_t)img->width + (size_t)x;
                float *c = img->rgba + 4 * px;
                int a;
                wvol_error e2;
                wvol_camera_ray(cam, x + 0.5, row + 0.5, o, d);
                memset(&h, 0, sizeof h);
                /* the hint: the previous pixel of the row (this thread traced it, so the image
                 * does not depend on the thread count) */
                if (x == 0) ws.has_hint = 0;
                if (!failed && wvol__trace(&tr, &ws, o, d, tmin, &h, &e2) != WVOL_OK) {
#pragma omp critical(wvol_iso_err)
                    if (!failed) {
                        failed = 1;
                        first_err = e2;
                    }
                }
                ws.has_hint = h.hit;
                ws.hint = h.t;
                functions += h.functions;
                pieces += h.pieces;
                refined += h.refined;
                intervals += h.intervals;
                evals += (size_t)h.evals;
                grazes += (size_t)h.grazes;
                if (depth) depth[px] = h.hit ? (float)h.t : INFINITY;
                if (normals)
                    for (a = 0; a < 3; a++) normals[3 * px + a] = h.hit ? (float)h.normal[a] : 0.0f;
                hits += (size_t)h.hit;
                wvol__iso_shade(c, &h, d, p->light, p->color, p->ambient);
            }
        }
        cells += ws.cells;
        t_cells += ws.cell_seconds;
        wvol__trace_ws_free(&ws);
    }
    if (failed) {
        wvol__trace_cells_free(&tr);
        wvol__iso_boxk_free(&tr.k);
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
        st->cells = cells;
        st->cells_undecided = wvol__trace_cells_undecided(&tr);
        if (hits == 0) empty_message(&tr, iso, st->message, sizeof st->message);
        st->seconds = wvol__now() - t_start;
    }
    wvol__trace_cells_free(&tr);
    wvol__iso_boxk_free(&tr.k);
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
    if (tp && tp->surface == WVOL_ISO_SURFACE_CAST) {
        wvol_iso_cast_params cp;
        wvol_iso_cast_stats cs;
        wvol_render_source src = wvol_render_source_store(s);
        wvol_iso_cast_params_default(&cp);
        cp.threads = tp->threads;
        memcpy(cp.light, tp->light, sizeof cp.light);
        memcpy(cp.color, tp->color, sizeof cp.color);
        cp.ambient = tp->ambient;
        stt = wvol_iso_cast(surf, z, NULL, &src, cam, iso, &cp, &cs, err);
        if (stt == WVOL_OK && tstats) {
            memset(tstats, 0, sizeof *tstats);
            tstats->rays = cs.rays;
            tstats->hits = cs.hits;
            tstats->seconds = cs.seconds;
            tstats->cpu_seconds = cs.cpu_seconds;
            memcpy(tstats->message, cs.message, sizeof tstats->message);
        }
    } else {
        stt = wvol_iso_raytrace(surf, z, NULL, s, cam, iso, tp, tstats, err);
    }
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

