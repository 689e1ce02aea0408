/* SPDX-License-Identifier: MIT
 * Tests of the bricked iso caster (libwvol/src/iso/cast.c, cast_cell.c) and of the surface
 * cut by a face of the box (both the caster and the exact f^ tracer):
 *  - no missed first crossing: on random, grazing, tangent, corner/edge and plateau rays,
 *    wherever sampling the trilinear interpolant at 1/8 voxel finds a change of class the
 *    caster hits at or before it, and its hit is a real crossing: the interpolant's class
 *    differs from the entry class at the hit and not at the hit minus the tolerance;
 *  - a store's cast equals the cast of its reconstruction (same bricks of samples);
 *  - an image equals single rays, for 1 and 2 threads;
 *  - the face cut: a bone block cut by the bottom face, air cut by the top face: the caster
 *    and the tracer see no false surface at the bottom face. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "iso/iso_internal.h"
#include "wvol/iso.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol_synth.h"

/* Under AddressSanitizer (unoptimised, instrumented) a quarter of the rays: the sanitizer run
 * checks memory, the release run the numbers. */
#if defined(WVOL_TEST_ASAN)
#define RAYS(n) ((n) / 4 > 0 ? (n) / 4 : 1)
#else
#define RAYS(n) (n)
#endif

static uint64_t rs = 0x9E3779B97F4A7C15ull;
static double rnd(void)
{
    return fixture_urand(&rs);
}

/* The trilinear interpolant of v at voxel coordinates x (inside [0, n-1]). */
static double interp(const wvol_volume *v, const double x[3])
{
    size_t n[3] = {v->nx, v->ny, v->nz};
    long i[3];
    double f[3], c8[8];
    int a, k;
    for (a = 0; a < 3; a++) {
        double xc = x[a] < 0 ? 0 : x[a] > (double)n[a] - 1 ? (double)n[a] - 1 : x[a];
        i[a] = (long)floor(xc);
        if (i[a] > (long)n[a] - 2) i[a] = (long)n[a] - 2;
        if (i[a] < 0) i[a] = 0;
        f[a] = xc - (double)i[a];
    }
    for (k = 0; k < 8; k++) {
        size_t ii = (size_t)(i[0] + (k & 1)), jj = (size_t)(i[1] + ((k >> 1) & 1)), kk = (size_t)(i[2] + ((k >> 2) & 1));
        c8[k] = v->data[ii + n[0] * (jj + n[1] * kk)];
    }
    return wvol__cell_eval(c8, f, NULL);
}

static double interp_t(const wvol_volume *v, const double o[3], const double d[3], double t)
{
    double x[3];
    int a;
    for (a = 0; a < 3; a++) x[a] = (o[a] + t * d[a] - v->origin[a]) / v->spacing[a];
    return interp(v, x);
}

/* The ray's part inside [0, n-1], t >= tmin. */
static int extent(const wvol_volume *v, const double o[3], const double d[3], double tmin, double *t0, double *t1)
{
    size_t n[3] = {v->nx, v->ny, v->nz};
    double a0 = tmin, a1 = INFINITY;
    int a;
    for (a = 0; a < 3; a++) {
        double ov = (o[a] - v->origin[a]) / v->spacing[a], dv = d[a] / v->spacing[a], ta, tb;
        if (dv == 0) {
            if (ov < 0 || ov > (double)n[a] - 1) return 0;
            continue;
        }
        ta = -ov / dv;
        tb = ((double)n[a] - 1 - ov) / dv;
        if (ta > tb) {
            double x = ta;
            ta = tb, tb = x;
        }
        if (ta > a0) a0 = ta;
        if (tb < a1) a1 = tb;
    }
    *t0 = a0;
    *t1 = a1;
    return a0 < a1;
}

typedef struct tally {
    int rays, crossings, hits, extra;
    double worst_depth;
} tally;

/* One ray against 1/8-voxel sampling (plus the exact entry point) of the interpolant. */
static void check_ray(wvol__caster *c, wvol__cast_ws *w, const wvol_volume *v, double iso, double eps,
                      const double o[3], const double d[3], double tol_vox, tally *ty, const char *what)
{
    wvol_iso_hit h;
    double t0, t1, step, t, tk = INFINITY, smin = fmin(v->spacing[0], fmin(v->spacing[1], v->spacing[2]));
    int cls0, in;
    CHECK(wvol__cast(c, w, o, d, 0.0, &h, NULL) == WVOL_OK, "%s: cast", what);
    ty->rays++;
    in = extent(v, o, d, 0.0, &t0, &t1);
    if (!in) {
        CHECK(!h.hit, "%s: a hit outside the extent", what);
        return;
    }
    cls0 = interp_t(v, o, d, t0) >= iso;
    if (fabs(interp_t(v, o, d, t0) - iso) <= eps && h.hit) {
        /* entering on the surface within rounding (e.g. exactly at a sample equal to iso): the
         * entry class is the caster's, the one its hit leaves */
        double fh = interp_t(v, o, d, h.t);
        if (fabs(fh - iso) > eps) cls0 = !(fh >= iso);
    }
    step = 0.125 * smin;
    for (t = t0; t <= t1; t += step) {
        double f = interp_t(v, o, d, t);
        if ((f >= iso) != cls0) {
            if (fabs(f - iso) > eps) tk = t;
            else if (!isfinite(tk)) tk = t; /* a touch: the caster may take it or not; handled below */
            break;
        }
    }
    if (isfinite(tk)) {
        double ftk = interp_t(v, o, d, tk);
        ty->crossings++;
        if (fabs(ftk - iso) > eps)
            CHECK(h.hit && h.t <= tk + tol_vox * smin, "%s: missed crossing at t=%.9g (f=%.9g, iso %g): hit %d t %.9g; ray o %.17g %.17g %.17g d %.17g %.17g %.17g, entry t %.17g f %.17g",
                  what, tk, ftk, iso, h.hit, h.t, o[0], o[1], o[2], d[0], d[1], d[2], t0, interp_t(v, o, d, t0));
    }
    if (h.hit) {
        double fa = interp_t(v, o, d, h.t), fb = interp_t(v, o, d, h.t - tol_vox * smin * 1.01);
        ty->hits++;
        if (!isfinite(tk)) ty->extra++;
        CHECK(h.t >= t0 - 1e-9 && h.t <= t1 + 1e-9, "%s: hit t %g outside [%g, %g]", what, h.t, t0, t1);
        /* a crossing: the other class at the hit (up to rounding), the entry class just before */
        CHECK((fa >= iso) != cls0 || fabs(fa - iso) <= eps, "%s: hit at t=%.9g is no crossing (f=%.9g, iso %g)", what,
              h.t, fa, iso);
        CHECK(h.t - tol_vox * smin * 1.01 < t0 || (fb >= iso) == cls0 || fabs(fb - iso) <= eps,
              "%s: hit at t=%.9g is late: f(t - tol) = %.9g", what, h.t, fb);
        CHECK(isfinite(h.normal[0]) && isfinite(h.normal[1]) && isfinite(h.normal[2]), "%s: normal", what);
    }
}

static double f_sphere(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double c = 0.5 * ((double)v->nx - 1), dx = (double)i - c, dy = (double)j - c, dz = (double)k - c;
    (void)ctx;
    return sqrt(dx * dx + dy * dy + dz * dz);
}

static double f_noise(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)v, (void)i, (void)j, (void)k, (void)ctx;
    return rnd();
}

/* a smooth field in HU-like units: a broad Gaussian bump (sigma 8 voxels) of 1000 over -500 */
static double f_smooth(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double x = (double)i - 0.5 * ((double)v->nx - 1), y = (double)j - 0.5 * ((double)v->ny - 1),
           z = (double)k - 0.5 * ((double)v->nz - 1);
    (void)ctx;
    return -500.0 + 1000.0 * exp(-(x * x + y * y + z * z) / (2.0 * 8.0 * 8.0));
}

/* integers 0..3, with wide plateaus of exactly the iso-value 2 */
static double f_plateau(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)v, (void)ctx;
    if ((i / 4 + j / 4 + k / 4) % 3 == 0) return 2.0;
    return (double)((i * 7 + j * 3 + k * 5) % 4);
}

/* Random rays of each kind through v. */
static void guarantee(const wvol_volume *v, const wvol_store *s, double iso, int nrays, const char *what)
{
    wvol_render_source src = s ? wvol_render_source_store(s) : wvol_render_source_volume(v);
    wvol_iso_cast_params p;
    wvol__caster *c = NULL;
    wvol__cast_ws w;
    wvol_volume *ref = NULL;
    tally ty = {0, 0, 0, 0, 0};
    double n = (double)v->nx, cen = 0.5 * (n - 1), vmin, vmax, eps;
    int r, kind;
    wvol_iso_cast_params_default(&p);
    p.brick = 8; /* small bricks: many brick and group boundaries on every ray */
    wvol_volume_range(v, &vmin, &vmax, NULL);
    /* |interp - iso| below eps is a touch either side may classify differently: float64
     * rounding of the cubic against the direct lerp (~1e-15 of the values) for a volume; for a
     * store also the float32 rounding of the brick reconstruction against the whole inverse
     * transform the test compares with (~1e-7 of the values per synthesis step) */
    eps = (s ? 1e-5 : 1e-12) * (fmax(fabs(vmin), fabs(vmax)) + fabs(iso));
    if (s) { /* the samples the caster sees: the store's reconstruction */
        wvol_coeffs *cf = NULL;
        CHECK(wvol_store_densify(s, &cf, NULL) == WVOL_OK && wvol_idwt3(&ref, cf, NULL) == WVOL_OK, "%s: reconstruct",
              what);
        wvol_coeffs_destroy(cf);
        if (!ref) return;
    }
    CHECK(wvol__caster_create(&c, &src, iso, &p, NULL) == WVOL_OK, "%s: caster", what);
    if (!c) {
        wvol_volume_destroy(ref);
        return;
    }
    memset(&w, 0, sizeof w);
    for (kind = 0; kind < 5; kind++)
        for (r = 0; r < nrays; r++) {
            double o[3], d[3], tgt[3], len = 0;
            int a;
            for (a = 0; a < 3; a++) tgt[a] = rnd() * (n - 1), d[a] = rnd() - 0.5;
            if (kind == 1) { /* grazing: nearly in a grid plane, often exactly in one */
                int ax = r % 3;
                d[ax] = (r % 2) ? 0.0 : 1e-7 * (rnd() - 0.5);
                tgt[ax] = floor(tgt[ax]) + ((r / 3) % 2 ? 0.0 : 0.5);
            } else if (kind == 2) { /* through grid vertices and edges exactly */
                for (a = 0; a < 3; a++) tgt[a] = floor(tgt[a]);
                if (r % 2) d[r % 3] = 0.0;
                if (r % 5 == 0) d[0] = d[1] = d[2] = 1.0;
            } else if (kind == 3) { /* tangent to the sphere r = iso (for the sphere field) */
                double u[3] = {rnd() - 0.5, rnd() - 0.5, rnd() - 0.5}, ul = 0, dd = 0;
                for (a = 0; a < 3; a++) ul += u[a] * u[a];
                ul = sqrt(ul);
                for (a = 0; a < 3; a++) u[a] /= ul, dd += d[a] * u[a];
                for (a = 0; a < 3; a++) d[a] -= dd * u[a]; /* d perpendicular to u */
                for (a = 0; a < 3; a++) tgt[a] = cen + u[a] * (iso + 1e-3 * (rnd() - 0.5));
            } else if (kind == 4) { /* axis-parallel */
                d[0] = d[1] = d[2] = 0;
                d[r % 3] = r % 2 ? 1.0 : -1.0;
            }
            for (a = 0; a < 3; a++) len += d[a] * d[a];
            len = sqrt(len);
            if (!(len > 0)) continue;
            for (a = 0; a < 3; a++) {
                d[a] /= len;
                o[a] = v->origin[a] + v->spacing[a] * tgt[a] - 2.0 * n * v->spacing[a] * d[a];
            }
            check_ray(c, &w, ref ? ref : v, iso, eps, o, d, p.tolerance, &ty, what);
        }
    printf("%s: %d rays, %d sampled crossings, %d hits (%d between samples)\n", what, ty.rays, ty.crossings, ty.hits,
           ty.extra);
    CHECK(ty.crossings > ty.rays / 10, "%s: the rays meet the surface (%d crossings)", what, ty.crossings);
    wvol__cast_ws_free(&w);
    wvol__caster_destroy(c);
    wvol_volume_destroy(ref);
}

/* An image equals single rays, pixel for pixel, for 1 and 2 threads; from a store it equals
 * the image of the store's reconstruction. */
static void images(const wvol_volume *v, const wvol_store *s, double iso, const char *what)
{
    wvol_render_source src = wvol_render_source_store(s), vs;
    wvol_camera cam;
    wvol_geometry g;
    wvol_image *im1 = NULL, *im2 = NULL, *im3 = NULL;
    wvol_iso_cast_params p;
    wvol_iso_cast_stats st;
    wvol_coeffs *cf = NULL;
    wvol_volume *rec = NULL;
    int W = 40, H = 32, proj, x, y, mism = 0, differ = 0;
    float *z1 = malloc(W * H * sizeof *z1), *z2 = malloc(W * H * sizeof *z2), *z3 = malloc(W * H * sizeof *z3);
    (void)v;
    wvol_iso_cast_params_default(&p);
    p.brick = 8;
    CHECK(wvol_store_densify(s, &cf, NULL) == WVOL_OK && wvol_idwt3(&rec, cf, NULL) == WVOL_OK, "%s: rec", what);
    vs = wvol_render_source_volume(rec);
    wvol_geometry_of_volume(&g, rec);
    for (proj = 0; proj < 2; proj++) {
        CHECK(wvol_camera_parse(&cam, proj ? "persp dir=1,0.6,-0.3" : "ortho dir=-0.3,1,0.5", &g, W, H, NULL) == WVOL_OK,
              "camera");
        wvol_image_create(&im1, W, H, NULL);
        wvol_image_create(&im2, W, H, NULL);
        wvol_image_create(&im3, W, H, NULL);
        p.threads = 1;
        CHECK(wvol_iso_cast(im1, z1, NULL, &src, &cam, iso, &p, &st, NULL) == WVOL_OK, "%s: cast", what);
        CHECK(st.hits > 0 && st.bricks_built > 0 && st.bricks_built + st.bricks_bound <= st.bricks_total,
              "%s: stats hits %zu built %zu bound %zu total %zu", what, st.hits, st.bricks_built, st.bricks_bound,
              st.bricks_total);
        p.threads = 2;
        CHECK(wvol_iso_cast(im2, z2, NULL, &src, &cam, iso, &p, NULL, NULL) == WVOL_OK, "%s: cast 2", what);
        CHECK(wvol_iso_cast(im3, z3, NULL, &vs, &cam, iso, &p, NULL, NULL) == WVOL_OK, "%s: cast rec", what);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                double o[3], d[3];
                wvol_iso_hit h;
                int px = x + W * y;
                mism += memcmp(&z1[px], &z2[px], sizeof(float)) != 0 ||
                        memcmp(im1->rgba + 4 * px, im2->rgba + 4 * px, 4 * sizeof(float)) != 0;
                /* the store's bricks and the whole inverse transform round differently (float32) */
                differ += isfinite(z1[px]) != isfinite(z3[px]) ||
                          (isfinite(z1[px]) && fabs(z1[px] - z3[px]) > 1e-2 * g.spacing[0]);
                if ((x * 7 + y * 3) % 11) continue; /* a sample of the pixels as single rays */
                wvol_camera_ray(&cam, x + 0.5, y + 0.5, o, d);
                if (proj == 1) {
                    CHECK(wvol_iso_cast_ray(&src, iso, o, d, &p, &h, NULL) == WVOL_OK, "ray");
                    CHECK(h.hit == isfinite(z1[px]) && (!h.hit || (float)h.t == z1[px]), "%s: pixel %d,%d: ray %d %.9g vs image %.9g",
                          what, x, y, h.hit, h.t, z1[px]);
                }
            }
        CHECK(mism == 0, "%s: 1 and 2 threads differ on %d pixels", what, mism);
        CHECK(differ <= 2, "%s: store and reconstruction differ on %d pixels", what, differ);
        wvol_image_destroy(im1);
        wvol_image_destroy(im2);
        wvol_image_destroy(im3);
    }
    /* outside the range: empty image, a message */
    wvol_image_create(&im1, W, H, NULL);
    CHECK(wvol_iso_cast(im1, z1, NULL, &src, &cam, 1e9, &p, &st, NULL) == WVOL_OK && st.hits == 0 && st.message[0],
          "%s: empty image and message", what);
    CHECK(wvol_iso_cast(im1, z1, NULL, &src, &cam, NAN, &p, &st, NULL) == WVOL_ERR_ARG, "%s: NaN iso refused", what);
    {
        wvol_iso_cast_params q = p;
        wvol_error err;
        q.model_bound = 9;
        CHECK(wvol_iso_cast(im1, z1, NULL, &src, &cam, 0.5, &q, &st, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "model_bound 9"),
              "%s: model_bound 9: %s", what, err.message);
        q = p;
        q.ambient = NAN;
        CHECK(wvol_iso_cast(im1, z1, NULL, &src, &cam, 0.5, &q, &st, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "ambient"),
              "%s: NaN ambient: %s", what, err.message);
        q = p;
        q.light[0] = INFINITY;
        CHECK(wvol_iso_cast(im1, z1, NULL, &src, &cam, 0.5, &q, &st, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "light[0]"),
              "%s: infinite light: %s", what, err.message);
    }
    wvol_image_destroy(im1);
    wvol_volume_destroy(rec);
    wvol_coeffs_destroy(cf);
    free(z1), free(z2), free(z3);
}

/* ---- the model bound: |f^ - interp| <= E per brick, and the exact tracer's hits ---- */

static void model_bound(const wvol_volume *v, const char *filter, int J, double keep, double iso, double min_ratio,
                        int nrays, const char *what)
{
    wvol_store *s = fixture_store(v, filter, 2, keep, J);
    wvol_render_source src;
    wvol_iso_cast_params p;
    wvol__caster *c = NULL;
    wvol__cast_ws w;
    wvol_coeffs *cf = NULL;
    wvol_volume *rec = NULL;
    double worst = 0.0, emin = INFINITY, emax = 0.0;
    int i, inner = 0, hits = 0, r;
    CHECK(s != NULL, "%s: store", what);
    if (!s) return;
    src = wvol_render_source_store(s);
    wvol_iso_cast_params_default(&p);
    p.brick = 8;
    p.model_bound = 1;
    CHECK(wvol_store_densify(s, &cf, NULL) == WVOL_OK && wvol_idwt3(&rec, cf, NULL) == WVOL_OK, "%s: rec", what);
    CHECK(rec && wvol__caster_create(&c, &src, iso, &p, NULL) == WVOL_OK, "%s: caster", what);
    if (!c || !rec) goto done;
    memset(&w, 0, sizeof w);
    /* random points: f^ (the store's spline model) against the interpolant of the reconstruction */
    for (i = 0; i < RAYS(3000); i++) {
        double x[3], e, f, g;
        int a;
        for (a = 0; a < 3; a++) x[a] = rnd() * ((double)v->nx - 1);
        e = wvol__caster_fhat_bound(c, &w, x, NULL);
        CHECK(!isnan(e) && e >= 0, "%s: bound at (%g, %g, %g): %g", what, x[0], x[1], x[2], e);
        if (!isfinite(e)) continue; /* a brick whose sample window a face clips: no bound */
        inner++;
        f = wvol_store_eval(s, x, NULL);
        g = interp(rec, x);
        CHECK(fabs(f - g) <= e, "%s: |f^ - interp| = %.9g > bound %.9g at (%g, %g, %g)", what, fabs(f - g), e, x[0],
              x[1], x[2]);
        if (fabs(f - g) / e > worst) worst = fabs(f - g) / e;
        emin = fmin(emin, e), emax = fmax(emax, e);
    }
    CHECK(inner > RAYS(300), "%s: interior points %d", what, inner);
    /* the exact tracer's hits: f^ = iso there, so the interpolant is within the bound of iso */
    for (r = 0; r < nrays; r++) {
        double o[3], d[3], x[3], e, len = 0;
        wvol_iso_hit h;
        int a;
        for (a = 0; a < 3; a++) d[a] = rnd() - 0.5, len += d[a] * d[a];
        len = sqrt(len);
        /* from inside the interior bricks, so that the first hit is usually in a brick whose window
         * no face clips */
        for (a = 0; a < 3; a++) {
            d[a] /= len;
            o[a] = v->origin[a] + v->spacing[a] * (0.5 * ((double)v->nx - 1) + (0.3 * rnd() - 0.15) * (double)v->nx);
        }
        CHECK(wvol_iso_trace_ray(s, iso, o, d, NULL, &h, NULL) == WVOL_OK, "%s: trace", what);
        if (!h.hit) continue;
        wvol_store_world_to_voxel(s, h.pos, x);
        e = wvol__caster_fhat_bound(c, &w, x, NULL);
        if (!isfinite(e)) continue;
        hits++;
        CHECK(fabs(interp(rec, x) - iso) <= e, "%s: tracer hit at (%g, %g, %g): |interp - iso| = %.9g > %.9g", what, x[0],
              x[1], x[2], fabs(interp(rec, x) - iso), e);
    }
    CHECK(hits >= nrays / 10, "%s: tracer hits %d of %d rays", what, hits, nrays);
    printf("%s: bound %.4g .. %.4g over %d interior points, largest |f^ - interp| / bound %.4f; %d tracer hits "
           "within it\n",
           what, emin, emax, inner, worst, hits);
    CHECK(worst >= min_ratio, "%s: the bound is looser than expected: largest |f^ - interp| / bound %.4g < %.4g", what,
          worst, min_ratio);
    wvol__cast_ws_free(&w);
done:
    wvol__caster_destroy(c);
    wvol_volume_destroy(rec);
    wvol_coeffs_destroy(cf);
    wvol_store_destroy(s);
}

/* ---- the surface cut by a face ---- */

static double f_cut(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)ctx;
    if (k >= v->nz - 4 && i >= 4 && i < 28 && j >= 4 && j < 28) return -1000.0; /* air cut by the top face */
    if (k < 6 && i >= 10 && i < 22 && j >= 12 && j < 20) return 1200.0;           /* bone cut by the bottom face */
    if (k >= 20 && k < 26 && i >= 4 && i < 28 && j >= 4 && j < 28) return 1200.0; /* a bone slab inside */
    return 39.0;                                                                   /* soft tissue */
}

static void face_cut(void)
{
    wvol_volume *v = fixture_volume(32, 32, 48, f_cut, NULL);
    wvol_store *s = v ? fixture_store(v, "db2", 3, 1.0, 4) : NULL;
    wvol_render_source vs = wvol_render_source_volume(v);
    double iso = 226.0, lo[3], hi[3];
    int i, j, checked = 0, traced = 0;
    CHECK(s != NULL, "face cut: store");
    if (!s) return;
    wvol__iso_model_extent(s, lo, hi);
    CHECK(lo[2] > 0.5 && lo[2] < 2.0 && hi[2] == 47.0, "face cut: db2's traced extent along z [%g, %g]", lo[2], hi[2]);
    for (j = 5; j < 28; j += 2)
        for (i = 5; i < 28; i += 2) {
            /* on sample columns: the interpolant along z is the lerp of the column's samples */
            double o[3] = {i, j, -10.0}, d[3] = {0, 0, 1};
            int jaw = i >= 10 && i < 22 && j >= 12 && j < 20;
            wvol_iso_hit hc, ht;
            CHECK(wvol_iso_cast_ray(&vs, iso, o, d, NULL, &hc, NULL) == WVOL_OK, "face cut: cast");
            CHECK(wvol_iso_trace_ray(s, iso, o, d, NULL, &ht, NULL) == WVOL_OK, "face cut: trace");
            /* the interpolant crosses 226 between samples 39 and 1200 at 0.16 voxel: below the
             * slab at z = 19 + 0.16; in the jaw (entered inside) where it leaves it, z = 5 + 0.84 */
            CHECK(hc.hit && fabs(hc.pos[2] - (jaw ? 5.0 + (1200 - 226) / 1161.0 : 19.0 + (226 - 39) / 1161.0)) < 1e-4,
                  "face cut: cast at (%g, %g): hit %d z %.6g", o[0], o[1], hc.hit, hc.pos[2]);
            /* f^ (db2, not interpolating) puts the crossings within a voxel of the interpolant's,
             * away from the jaw's and the slab's sides, where db2's ringing is f^'s own; before the
             * wrap bands were excluded it hit at z ~ 0.1 everywhere */
            if (i >= 7 && i <= 25 && j >= 7 && j <= 25 && !(i >= 6 && i < 26 && j >= 8 && j < 24) && ++traced)
                CHECK(ht.hit && fabs(ht.pos[2] - hc.pos[2]) < 1.0, "face cut: trace at (%g, %g): hit %d z %.6g (cast %.6g)",
                      o[0], o[1], ht.hit, ht.pos[2], hc.pos[2]);
            CHECK(!ht.hit || ht.pos[2] >= lo[2], "face cut: trace hit z %g in the wrap band", ht.pos[2]);
            checked++;
        }
    CHECK(checked == 144 && traced >= 16, "face cut: rays %d, traced %d", checked, traced);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

int main(void)
{
    setvbuf(stdout, NULL, _IONBF, 0);
    {
        wvol_volume *v = fixture_volume(24, 24, 24, f_sphere, NULL);
        guarantee(v, NULL, 7.3, RAYS(200), "sphere distance 24^3");
        wvol_volume_destroy(v);
    }
    {
        wvol_volume *v = fixture_volume(20, 18, 22, f_noise, NULL);
        guarantee(v, NULL, 0.5, RAYS(200), "white noise 20x18x22");
        wvol_volume_destroy(v);
    }
    {
        wvol_volume *v = fixture_volume(24, 24, 24, f_plateau, NULL);
        guarantee(v, NULL, 2.0, RAYS(200), "plateaus at iso 24^3");
        wvol_volume_destroy(v);
    }
    {
        wvol_synth_params sp;
        wvol_volume *v = NULL;
        wvol_store *s;
        wvol_synth_params_default(&sp);
        sp.dims[0] = sp.dims[1] = sp.dims[2] = 40;
        sp.seed = 3;
        CHECK(wvol_synth_make(&v, NULL, "skull", &sp, NULL) == WVOL_OK, "skull");
        s = v ? fixture_store(v, "db2", 3, 0.05, 4) : NULL;
        CHECK(s != NULL, "skull store");
        if (s) {
            guarantee(v, s, 400.0, RAYS(150), "skull 40^3 db2 5% store");
            images(v, s, 400.0, "skull 40^3 db2 5% store");
        }
        wvol_store_destroy(s);
        wvol_volume_destroy(v);
    }
    {
        wvol_synth_params sp;
        wvol_volume *v = NULL;
        wvol_synth_params_default(&sp);
        sp.dims[0] = sp.dims[1] = sp.dims[2] = 32;
        CHECK(wvol_synth_make(&v, NULL, "gaussian", &sp, NULL) == WVOL_OK, "gaussian");
        if (v) {
            /* the smallest ratio of the largest sampled |f^ - interp| to the bound allowed, about a
             * third of the one measured with 3000 points (fewer points under ASan): the bound may
             * not drift looser than this; measured 0.0058, 0.0027, 0.17 */
            model_bound(v, "db4", 6, 1.0, 0.5, 0.0019, RAYS(200), "gaussian 32^3 db4 J6 100%");
            model_bound(v, "db2", 4, 0.2, 0.5, 0.0009, RAYS(200), "gaussian 32^3 db2 J4 20%");
            model_bound(v, "haar", 0, 1.0, 0.5, 0.057, RAYS(200), "gaussian 32^3 haar 100%");
        }
        wvol_volume_destroy(v);
        v = fixture_volume(32, 32, 32, f_smooth, NULL);
        if (v) {
            /* a smooth field (a broad bump, HU-like values): the bound against the largest
             * |f^ - interp| found on 3000 random points; measured 0.0047, 0.0037, 0.0087, 0.0048.
             * What keeps it loose is the residual of the samples' quadric over the window phi reaches
             * (L + 4 samples) times D (A^2 + A + 1), cast_bound.c; docs/iso.md */
            model_bound(v, "db4", 6, 1.0, 0.0, 0.0015, RAYS(100), "smooth 32^3 db4 J6 100%");
            model_bound(v, "db2", 4, 1.0, 0.0, 0.0012, RAYS(100), "smooth 32^3 db2 J4 100%");
            model_bound(v, "db2", 4, 0.05, 0.0, 0.0029, RAYS(100), "smooth 32^3 db2 J4 5%");
            model_bound(v, "coif2", 6, 1.0, 0.0, 0.0016, RAYS(100), "smooth 32^3 coif2 J6 100%");
        }
        wvol_volume_destroy(v);
        v = fixture_volume(32, 32, 32, f_noise, NULL);
        if (v) {
            /* on noise the plane residual is the data itself; measured 0.062, 0.0069, 0.28 */
            /* the exact tracer builds every function on noise (no cell is decided): few rays */
            model_bound(v, "db4", 6, 1.0, 0.5, 0.02, RAYS(20), "white noise 32^3 db4 J6 100%");
            model_bound(v, "db2", 4, 1.0, 0.5, 0.0023, RAYS(20), "white noise 32^3 db2 J4 100%");
            model_bound(v, "haar", 0, 1.0, 0.5, 0.09, RAYS(20), "white noise 32^3 haar 100%");
        }
        wvol_volume_destroy(v);
    }
    face_cut();
    return check_summary("test_iso_cast");
}
