/* Tests of the implicit-surface ray tracer (libwvol/src/iso/raytrace.c): no missed
 * hit against dense sampling of f^ at 1/8 voxel, the first crossing at the same
 * depth within tolerance, every store bound the tracer relies on checked against
 * dense sampling of f^ and grad f^ on random boxes, empty result for an iso-value
 * outside the range. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "wvol/iso.h"
#include "wvol/store.h"

static uint64_t rs = 0x2545F4914F6CDD1Dull;
static double rnd(void)
{
    rs ^= rs << 13;
    rs ^= rs >> 7;
    rs ^= rs << 17;
    return (double)(rs >> 11) / 9007199254740992.0;
}

/* Two Gaussian blobs (one elongated) and a ripple: several crossings per ray. */
static wvol_volume *phantom(size_t n, int kind)
{
    wvol_volume *v = NULL;
    size_t i, j, k;
    wvol_volume_create(&v, n, n, n, NULL);
    for (k = 0; k < n; k++)
        for (j = 0; j < n; j++)
            for (i = 0; i < n; i++) {
                double x = (double)i / (n - 1) - 0.5, y = (double)j / (n - 1) - 0.5, z = (double)k / (n - 1) - 0.5, f;
                if (kind == 0) {
                    f = exp(-(x * x + y * y + z * z) / (2 * 0.15 * 0.15));
                } else {
                    double a = x - 0.15, b = y + 0.1, c = z;
                    f = exp(-(a * a / 0.01 + b * b / 0.004 + c * c / 0.02)) +
                        0.8 * exp(-((x + 0.2) * (x + 0.2) + (y - 0.15) * (y - 0.15) + (z - 0.1) * (z - 0.1)) / 0.006) +
                        0.05 * sin(17 * x) * cos(13 * y);
                }
                v->data[i + n * (j + n * k)] = (float)f;
            }
    return v;
}

static wvol_store *make_store(const wvol_volume *v, const char *filter, int levels, double keep)
{
    const wvol_filter *f = NULL;
    wvol_coeffs *c = NULL;
    wvol_selection *sel = NULL;
    wvol_store *s = NULL;
    wvol_select_params sp = wvol_select_params_default();
    wvol_error err;
    if (wvol_filter_get(&f, filter, &err) != WVOL_OK || wvol_dwt3(&c, v, f, levels, &err) != WVOL_OK) return NULL;
    if (keep < 1.0) {
        sp.mode = WVOL_SELECT_FRACTION;
        sp.fraction = keep;
        wvol_select(&sel, c, &sp, NULL, NULL, &err);
    }
    if (wvol_store_build(&s, c, sel, NULL, &err) != WVOL_OK) fprintf(stderr, "store: %s\n", err.message);
    wvol_selection_destroy(sel);
    wvol_coeffs_destroy(c);
    return s;
}

static double f_at(const wvol_store *s, const double o[3], const double d[3], double t)
{
    double w[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]}, x[3];
    wvol_store_world_to_voxel(s, w, x);
    return wvol_store_eval(s, x, NULL);
}

/* Random rays from outside towards random interior points; returns failures. */
static void no_missed_hit(const wvol_store *s, const wvol_volume *v, double iso, int nrays, const char *what)
{
    wvol_store_info info;
    wvol_iso_trace_params p;
    int r, found = 0, agreed = 0, slivers = 0;
    double tol;
    wvol_store_get_info(s, &info);
    wvol_iso_trace_params_default(&p);
    tol = p.tolerance = 1e-3;
    for (r = 0; r < nrays; r++) {
        double target[3] = {0, 0, 0}, o[3], d[3], len = 0, tmax, h, tprev, fprev, tcross = INFINITY;
        wvol_iso_hit hit;
        int a;
        /* aim at a sample inside the surface (or, one ray in four, anywhere) */
        for (int tries = 0; tries < 1000; tries++) {
            size_t q = (size_t)(rnd() * (double)(v->nx * v->ny * v->nz));
            if (q >= v->nx * v->ny * v->nz) continue;
            target[0] = info.origin[0] + info.spacing[0] * (double)(q % v->nx);
            target[1] = info.origin[1] + info.spacing[1] * (double)((q / v->nx) % v->ny);
            target[2] = info.origin[2] + info.spacing[2] * (double)(q / (v->nx * v->ny));
            if (r % 4 == 3 || v->data[q] >= iso) break;
        }
        for (a = 0; a < 3; a++) {
            d[a] = rnd() - 0.5;
            len += d[a] * d[a];
        }
        len = sqrt(len);
        for (a = 0; a < 3; a++) {
            d[a] /= len;
            o[a] = target[a] - 2.0 * (double)info.nx * d[a];
        }
        CHECK(wvol_iso_trace_ray(s, iso, o, d, &p, &hit, NULL) == WVOL_OK, "%s: trace", what);
        /* dense sampling at 1/8 voxel inside the extent [0, n-1] */
        {
            double t0 = 0, t1 = INFINITY, ov[3], dv[3];
            size_t n[3] = {info.nx, info.ny, info.nz};
            wvol_store_world_to_voxel(s, o, ov);
            wvol_store_dir_to_voxel(s, d, dv);
            for (a = 0; a < 3; a++) {
                double ta = (0 - ov[a]) / dv[a], tb = ((double)n[a] - 1 - ov[a]) / dv[a];
                if (ta > tb) { double x = ta; ta = tb; tb = x; }
                if (ta > t0) t0 = ta;
                if (tb < t1) t1 = tb;
            }
            if (t0 > t1) {
                CHECK(!hit.hit, "%s: hit outside the extent", what);
                continue;
            }
            h = 0.125 / sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
            tmax = t1;
            tprev = t0;
            fprev = f_at(s, o, d, t0);
            for (double t = t0 + h;; t += h) {
                double tt = t < tmax ? t : tmax, ft = f_at(s, o, d, tt);
                if ((ft >= iso) != (fprev >= iso)) {
                    tcross = tprev; /* crossing in [tprev, tt] */
                    break;
                }
                if (tt >= tmax) break;
                tprev = tt;
                fprev = ft;
            }
            if (isfinite(tcross)) {
                found++;
                CHECK(hit.hit, "%s: ray %d: dense sampling crosses at t=%.6f, the tracer missed", what, r, tcross);
                if (hit.hit) {
                    if (hit.t >= tcross - tol && hit.t <= tcross + h + tol) {
                        agreed++;
                    } else if (hit.t < tcross) {
                        /* an earlier crossing dense sampling stepped over: must be genuine */
                        int gen = (f_at(s, o, d, hit.t - tol) >= iso) != (f_at(s, o, d, hit.t + tol) >= iso);
                        CHECK(gen, "%s: ray %d: spurious hit at %.6f before %.6f", what, r, hit.t, tcross);
                        slivers += gen;
                    } else {
                        CHECK(0, "%s: ray %d: hit at %.6f after the first crossing [%.6f, %.6f]", what, r, hit.t, tcross,
                              tcross + h);
                    }
                }
            } else if (hit.hit) {
                int gen = (f_at(s, o, d, hit.t - tol) >= iso) != (f_at(s, o, d, hit.t + tol) >= iso);
                CHECK(gen, "%s: ray %d: hit at %.6f where dense sampling finds none and f^ does not cross", what, r,
                      hit.t);
                slivers += gen;
            }
        }
    }
    printf("  %s: %d rays, %d cross, %d at the same depth, %d thin crossings between samples\n", what, nrays, found,
           agreed, slivers);
    CHECK(found > nrays / 2, "%s: too few crossing rays (%d) to test anything", what, found);
}

/* wvol_store_box_bounds against dense sampling of f^ and grad f^ on random boxes. */
static void bounds_hold(const wvol_store *s, const char *what)
{
    wvol_store_info info;
    int b, smooth;
    double worst_v = -INFINITY, worst_g = -INFINITY;
    wvol_store_get_info(s, &info);
    smooth = info.filter->length > 2;
    for (b = 0; b < 30; b++) {
        double lo[3], hi[3];
        wvol_store_bounds bd;
        int a, i, j, k, q = 7;
        for (a = 0; a < 3; a++) {
            double w = rnd() * 6.0;
            lo[a] = rnd() * ((double)info.nx - 1 - w);
            hi[a] = lo[a] + w;
        }
        CHECK(wvol_store_box_bounds(s, lo, hi, &bd, NULL) == WVOL_OK, "%s: bounds", what);
        for (k = 0; k < q; k++)
            for (j = 0; j < q; j++)
                for (i = 0; i < q; i++) {
                    double x[3] = {lo[0] + (hi[0] - lo[0]) * (i + 0.37 * rnd()) / (q - 0.63),
                                   lo[1] + (hi[1] - lo[1]) * (j + 0.37 * rnd()) / (q - 0.63),
                                   lo[2] + (hi[2] - lo[2]) * (k + 0.37 * rnd()) / (q - 0.63)};
                    double g[3], f = wvol_store_eval(s, x, g);
                    if (f - bd.vmax > worst_v) worst_v = f - bd.vmax;
                    if (bd.vmin - f > worst_v) worst_v = bd.vmin - f;
                    if (smooth)
                        for (a = 0; a < 3; a++)
                            if (fabs(g[a]) - bd.grad[a] > worst_g) worst_g = fabs(g[a]) - bd.grad[a];
                }
    }
    CHECK(worst_v <= 0, "%s: f^ exceeds its box bound by %g", what, worst_v);
    if (smooth) CHECK(worst_g <= 0, "%s: grad f^ exceeds its box bound by %g", what, worst_g);
}

typedef struct ortho {
    double c[3], u[3], v[3], d[3], half;
    int w, h;
} ortho;

static void ortho_ray(void *user, double px, double py, double o[3], double d[3])
{
    const ortho *cam = user;
    double sx = (2 * px / cam->w - 1) * cam->half, sy = (1 - 2 * py / cam->h) * cam->half;
    for (int a = 0; a < 3; a++) {
        o[a] = cam->c[a] - 3 * cam->half * cam->d[a] + sx * cam->u[a] + sy * cam->v[a];
        d[a] = cam->d[a];
    }
}

static void image_and_empty(const wvol_store *s, const char *what)
{
    ortho cam = {{15.5, 15.5, 15.5}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}, 16.0, 48, 48};
    float *rgb = malloc(48 * 48 * 3 * sizeof(float)), *depth = malloc(48 * 48 * sizeof(float));
    wvol_iso_trace_stats st;
    CHECK(wvol_iso_raytrace(rgb, depth, NULL, 48, 48, ortho_ray, &cam, s, 0.5, NULL, &st, NULL) == WVOL_OK, "%s: image",
          what);
    CHECK(st.hits > 100 && st.hits < 48 * 48, "%s: %zu hits", what, st.hits);
    CHECK(isinf(depth[0]) && isfinite(depth[24 * 48 + 24]), "%s: depth buffer", what);
    printf("  %s: 48x48 image, %zu hits, %.1f evals and %.1f bounds per ray, %.3f s\n", what, st.hits,
           (double)st.evals / st.rays, (double)st.bounds / st.rays, st.seconds);
    CHECK(wvol_iso_raytrace(rgb, depth, NULL, 48, 48, ortho_ray, &cam, s, 5.0, NULL, &st, NULL) == WVOL_OK, "%s: empty",
          what);
    CHECK(st.hits == 0 && st.message[0], "%s: message '%s'", what, st.message);
    free(rgb);
    free(depth);
}

int main(void)
{
    setvbuf(stdout, NULL, _IONBF, 0);
    static const struct { const char *f; int levels; double keep; int kind; double iso; } cases[] = {
        {"db2", 2, 1.0, 0, 0.5}, {"db2", 2, 0.05, 1, 0.3}, {"coif1", 2, 0.2, 1, 0.3}, {"haar", 2, 1.0, 1, 0.3},
    };
    size_t i;
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        wvol_volume *v = phantom(32, cases[i].kind);
        wvol_store *s = make_store(v, cases[i].f, cases[i].levels, cases[i].keep);
        char what[64];
        snprintf(what, sizeof what, "%s L%d keep %g phantom %d iso %g", cases[i].f, cases[i].levels, cases[i].keep,
                 cases[i].kind, cases[i].iso);
        CHECK(s != NULL, "%s: store", what);
        if (s) {
            bounds_hold(s, what);
            no_missed_hit(s, v, cases[i].iso, 40, what);
            if (cases[i].kind == 0) image_and_empty(s, what);
        }
        wvol_store_destroy(s);
        wvol_volume_destroy(v);
    }
    return check_summary("test_iso_trace");
}
