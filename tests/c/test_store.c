/* SPDX-License-Identifier: MIT */
/* The coefficient store (libwvol/src/store/store.c, query.c, ranges.c): lookup
 * and iteration give exactly the kept set, box and ray queries give exactly the
 * brute-force set of function images, value and gradient bounds are never
 * exceeded by dense samples of f^ and its gradient, point evaluation agrees with
 * an independent sum, densify round-trips, bad input is refused. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;
static double urand(void) { return fixture_urand(&rng_state); }

static double blob_at(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    size_t nx = v->nx, ny = v->ny, nz = v->nz;
    double x = (i - 0.4 * nx) / (0.25 * nx), y = (j - 0.5 * ny) / (0.3 * ny), z = (k - 0.5 * nz) / (0.3 * nz + 1);
    (void)ctx;
    return (float)(50.0 * exp(-(x * x + y * y + z * z)) + 4.0 * (urand() - 0.5) + (i > nx / 2 ? 10.0 : 0.0));
}

/* Coefficients of a smooth blob plus noise, and a selection keeping `fraction`. */
static wvol_coeffs *make_coeffs(const char *fname, int levels, size_t nx, size_t ny, size_t nz)
{
    wvol_volume *v = fixture_volume(nx, ny, nz, blob_at, NULL);
    wvol_coeffs *c = NULL;
    wvol_dwt3_ex(&c, v, fixture_filter(fname), levels, WVOL_PAD_EDGE, 1, NULL);
    wvol_volume_destroy(v);
    return c;
}

static wvol_selection *keep_fraction(const wvol_coeffs *c, double fraction)
{
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    wvol_selection *s = NULL;
    prm.mode = WVOL_SELECT_FRACTION, prm.fraction = fraction;
    wvol_select(&s, c, &prm, NULL, NULL, NULL);
    return s;
}

/* ---- brute force over the kept set ------------------------------------------------------ */

typedef struct fn {
    int m, band;
    size_t pos[3];
    float value;
} fn;

static fn *kept_list(const wvol_coeffs *c, const wvol_selection *s, size_t *n)
{
    size_t N = c->px * c->py * c->pz, k = 0;
    fn *out = malloc(N * sizeof *out);
    for (size_t i = 0; i < N; i++) {
        if (s && !wvol_selection_is_kept(s, i)) continue;
        wvol_coeffs_locate(c, i, &out[k].m, &out[k].band, out[k].pos, out[k].pos + 1, out[k].pos + 2);
        out[k].value = c->data[i];
        k++;
    }
    *n = k;
    return out;
}

typedef struct img {
    int m, band;
    uint32_t p, q, r;
    int64_t n[3];  /* periodic image: lo = 2^m p - s + n P */
    double t0, t1;
} img;

static int img_cmp(const void *a, const void *b)
{
    const img *x = a, *y = b;
#define CMPF(f)                                \
    if (x->f != y->f) return x->f < y->f ? -1 : 1
    CMPF(m);
    CMPF(band);
    CMPF(p);
    CMPF(q);
    CMPF(r);
    CMPF(n[0]);
    CMPF(n[1]);
    CMPF(n[2]);
    return 0;
}

/* Ray vs box, written out independently of the library (closed slabs). */
static int ray_box(const double o[3], const double d[3], double tmin, double tmax, const double lo[3],
                   const double hi[3], double *t0, double *t1)
{
    for (int a = 0; a < 3; a++) {
        if (isinf(lo[a])) continue;
        if (d[a] == 0.0) {
            if (o[a] < lo[a] || o[a] > hi[a]) return 0;
            continue;
        }
        double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
        if (ta > tb) {
            double t = ta;
            ta = tb, tb = t;
        }
        tmin = fmax(tmin, ta), tmax = fmin(tmax, tb);
        if (tmin > tmax) return 0;
    }
    *t0 = tmin, *t1 = tmax;
    return 1;
}

/* Every image of every kept function meeting the box [a, b] (ray == NULL) or the
 * segment o + t d, t in [tmin, tmax] (bounding box [a, b]). */
static img *brute_images(const wvol_coeffs *c, const fn *f, size_t nf, const double a[3], const double b[3],
                         const double *o, const double *d, double tmin, double tmax, size_t *count)
{
    size_t cap = 1024, k = 0, P[3] = {c->px, c->py, c->pz};
    img *out = malloc(cap * sizeof *out);
    double s = c->filter->center, S = c->filter->length - 1;
    for (size_t i = 0; i < nf; i++) {
        int64_t n0[3], n1[3];
        double lo0[3];
        for (int x = 0; x < 3; x++) {
            if (P[x] == 1) {
                n0[x] = n1[x] = 0;
                continue;
            }
            lo0[x] = ldexp((double)f[i].pos[x], f[i].m) - s;
            double hi0 = lo0[x] + ldexp(S, f[i].m);
            n0[x] = (int64_t)ceil((a[x] - hi0) / (double)P[x]);
            n1[x] = (int64_t)floor((b[x] - lo0[x]) / (double)P[x]);
        }
        int64_t n[3];
        for (n[2] = n0[2]; n[2] <= n1[2]; n[2]++)
            for (n[1] = n0[1]; n[1] <= n1[1]; n[1]++)
                for (n[0] = n0[0]; n[0] <= n1[0]; n[0]++) {
                    img e = {f[i].m, f[i].band, (uint32_t)f[i].pos[0], (uint32_t)f[i].pos[1], (uint32_t)f[i].pos[2],
                             {n[0], n[1], n[2]}, 0, 0};
                    if (o) {
                        double lo[3], hi[3];
                        for (int x = 0; x < 3; x++) {
                            if (P[x] == 1) {
                                lo[x] = -INFINITY, hi[x] = INFINITY;
                                continue;
                            }
                            lo[x] = lo0[x] + (double)n[x] * (double)P[x];
                            hi[x] = lo[x] + ldexp(S, f[i].m);
                        }
                        if (!ray_box(o, d, tmin, tmax, lo, hi, &e.t0, &e.t1)) continue;
                    }
                    if (k == cap) out = realloc(out, (cap *= 2) * sizeof *out);
                    out[k++] = e;
                }
    }
    *count = k;
    qsort(out, k, sizeof *out, img_cmp);
    return out;
}

static img *hits_to_images(const wvol_coeffs *c, const wvol_store_hits *h)
{
    img *out = malloc((h->count ? h->count : 1) * sizeof *out);
    size_t P[3] = {c->px, c->py, c->pz};
    double s = c->filter->center;
    for (size_t i = 0; i < h->count; i++) {
        const wvol_store_hit *e = h->hits + i;
        size_t pos[3] = {e->p, e->q, e->r};
        out[i].m = e->level, out[i].band = e->band;
        out[i].p = e->p, out[i].q = e->q, out[i].r = e->r;
        for (int x = 0; x < 3; x++)
            out[i].n[x] = P[x] == 1 ? 0 : (int64_t)llround((e->lo[x] + s - ldexp((double)pos[x], e->level)) / (double)P[x]);
        out[i].t0 = e->t0, out[i].t1 = e->t1;
    }
    qsort(out, h->count, sizeof *out, img_cmp);
    return out;
}

/* ---- tests ---------------------------------------------------------------------------------- */

typedef struct setup {
    const char *family;
    int levels;
    size_t n[3];
    double fraction;
} setup;

static const setup setups[] = {
    {"haar", 3, {16, 16, 16}, 0.1},  {"db2", 3, {24, 20, 16}, 0.08}, {"db2", 2, {15, 13, 9}, 0.2},
    {"coif1", 2, {16, 16, 8}, 0.15}, {"db4", 3, {16, 16, 16}, 0.1},  {"db2", 3, {32, 24, 1}, 0.2},
};
/* bl3 (128 taps, support 127 << m) is left to the single-function test: at test
   sizes each function has thousands of periodic images. */
#define NSETUPS (sizeof setups / sizeof setups[0])

static void lookup_and_iteration_give_the_kept_set(void)
{
    for (size_t si = 0; si < NSETUPS; si++) {
        const setup *su = setups + si;
        wvol_coeffs *c = make_coeffs(su->family, su->levels, su->n[0], su->n[1], su->n[2]);
        wvol_selection *sel = keep_fraction(c, su->fraction);
        wvol_store *st = NULL;
        wvol_error err;
        CHECK(wvol_store_build(&st, c, sel, NULL, &err) == WVOL_OK, "%s: %s", su->family, err.message);
        if (!st) continue;
        size_t N = c->px * c->py * c->pz, wrong = 0, seen_count = 0, dup = 0, extra = 0;
        for (size_t i = 0; i < N; i++) {
            int m, b;
            size_t p, q, r;
            float v = -1;
            wvol_coeffs_locate(c, i, &m, &b, &p, &q, &r);
            int k = wvol_store_lookup(st, m, b, p, q, r, &v);
            if (k != wvol_selection_is_kept(sel, i) || (k && v != c->data[i])) wrong++;
        }
        CHECK(wrong == 0, "%s: %zu lookups wrong", su->family, wrong);
        unsigned char *seen = calloc(N, 1);
        wvol_store_iter it = {0, 0};
        wvol_store_coeff e;
        while (wvol_store_next(st, &it, &e)) {
            size_t i = wvol_coeffs_index(c, e.level, e.band, e.p, e.q, e.r);
            if (i >= N || !wvol_selection_is_kept(sel, i) || e.value != c->data[i]) extra++;
            else if (seen[i]++) dup++;
            seen_count++;
        }
        CHECK(extra == 0 && dup == 0 && seen_count == wvol_selection_kept(sel), "%s: iteration %zu (kept %zu), %zu extra, %zu dup",
              su->family, seen_count, wvol_selection_kept(sel), extra, dup);
        wvol_store_info info;
        wvol_store_get_info(st, &info);
        CHECK(info.kept == wvol_selection_kept(sel), "info kept");
        printf("store %-5s %zux%zux%zu: kept %zu, nodes %zu, %.1f bytes per kept coefficient\n", su->family, su->n[0],
               su->n[1], su->n[2], info.kept, info.nodes, info.bytes_per_coeff);
        /* out-of-range lookups */
        CHECK(!wvol_store_lookup(st, 0, 1, 0, 0, 0, NULL) && !wvol_store_lookup(st, su->levels + 1, 1, 0, 0, 0, NULL) &&
                  !wvol_store_lookup(st, 1, 0, 0, 0, 0, NULL) && !wvol_store_lookup(st, 1, 8, 0, 0, 0, NULL) &&
                  !wvol_store_lookup(st, 1, 1, c->px, 0, 0, NULL),
              "bad lookups");
        /* densify gives the selection applied to c */
        wvol_coeffs *d = NULL, *ref = NULL;
        CHECK(wvol_store_densify(st, &d, &err) == WVOL_OK, "densify: %s", err.message);
        wvol_coeffs_clone(&ref, c, NULL);
        wvol_selection_apply(sel, ref, NULL);
        CHECK(d && memcmp(d->data, ref->data, N * sizeof(float)) == 0, "%s: densify differs", su->family);
        /* the nonzero store of the applied coefficients holds the same set (where nonzero) */
        wvol_store *st2 = NULL;
        CHECK(wvol_store_build(&st2, ref, NULL, NULL, &err) == WVOL_OK, "build without selection");
        wvol_store_info i2;
        wvol_store_get_info(st2, &i2);
        size_t nzk = 0;
        for (size_t i = 0; i < N; i++) {
            int m, b;
            size_t p, q, r;
            wvol_coeffs_locate(c, i, &m, &b, &p, &q, &r);
            nzk += b == 0 || ref->data[i] != 0.0f;
        }
        CHECK(i2.kept == nzk, "nonzero store: %zu vs %zu", i2.kept, nzk);
        wvol_store_destroy(st2);
        wvol_coeffs_destroy(d), wvol_coeffs_destroy(ref);
        free(seen);
        wvol_store_destroy(st);
        wvol_selection_destroy(sel);
        wvol_coeffs_destroy(c);
    }
}

static void random_box(const wvol_coeffs *c, double a[3], double b[3], double maxw)
{
    size_t P[3] = {c->px, c->py, c->pz};
    for (int x = 0; x < 3; x++) {
        double w = maxw * pow(urand(), 2.0);
        /* mostly inside the volume, sometimes across the periodic seam or outside it */
        a[x] = (urand() * 1.4 - 0.2) * (double)P[x];
        b[x] = a[x] + w;
    }
}

static void queries_match_brute_force(void)
{
    for (size_t si = 0; si < NSETUPS; si++) {
        const setup *su = setups + si;
        wvol_coeffs *c = make_coeffs(su->family, su->levels, su->n[0], su->n[1], su->n[2]);
        wvol_selection *sel = keep_fraction(c, su->fraction);
        wvol_store *st = NULL;
        wvol_store_hits hits = {0};
        size_t nf, boxes_bad = 0, rays_bad = 0, tbad = 0, total_hits = 0;
        fn *f = kept_list(c, sel, &nf);
        wvol_store_build(&st, c, sel, NULL, NULL);
        for (int t = 0; t < 100; t++) {
            double a[3], b[3];
            size_t ne;
            random_box(c, a, b, t < 40 ? 2.0 : 20.0);
            if (t == 0) memcpy(b, a, sizeof b); /* a point */
            CHECK(wvol_store_query_box(st, a, b, &hits, NULL) == WVOL_OK, "box query");
            img *exp_ = brute_images(c, f, nf, a, b, NULL, NULL, 0, 0, &ne), *got = hits_to_images(c, &hits);
            if (ne != hits.count) boxes_bad++;
            else
                for (size_t i = 0; i < ne; i++)
                    if (img_cmp(exp_ + i, got + i)) {
                        boxes_bad++;
                        break;
                    }
            total_hits += hits.count;
            free(exp_), free(got);
        }
        for (int t = 0; t < 100; t++) {
            double o[3], d[3], a[3], b[3], tmin = urand() * 2 - 1, tmax = tmin + 0.1 + 3 * urand();
            size_t P[3] = {c->px, c->py, c->pz}, ne;
            for (int x = 0; x < 3; x++) {
                o[x] = (urand() * 1.2 - 0.1) * (double)P[x];
                d[x] = (urand() - 0.5) * (double)P[x] * 0.5;
                if (t % 10 == 3 && x == 1) d[x] = 0.0; /* parallel to a face */
                if (t % 10 == 7 && x != 2) d[x] = 0.0; /* along an axis */
            }
            double p0, p1;
            for (int x = 0; x < 3; x++)
                p0 = o[x] + tmin * d[x], p1 = o[x] + tmax * d[x], a[x] = fmin(p0, p1), b[x] = fmax(p0, p1);
            CHECK(wvol_store_query_ray(st, o, d, tmin, tmax, &hits, NULL) == WVOL_OK, "ray query");
            img *exp_ = brute_images(c, f, nf, a, b, o, d, tmin, tmax, &ne), *got = hits_to_images(c, &hits);
            if (ne != hits.count) rays_bad++;
            else
                for (size_t i = 0; i < ne; i++) {
                    if (img_cmp(exp_ + i, got + i)) {
                        rays_bad++;
                        break;
                    }
                    if (fabs(exp_[i].t0 - got[i].t0) > 1e-12 || fabs(exp_[i].t1 - got[i].t1) > 1e-12) tbad++;
                }
            total_hits += hits.count;
            free(exp_), free(got);
        }
        CHECK(boxes_bad == 0, "%s: %zu of 100 boxes differ from brute force", su->family, boxes_bad);
        CHECK(rays_bad == 0 && tbad == 0, "%s: %zu of 100 rays differ (%zu t intervals)", su->family, rays_bad, tbad);
        CHECK(total_hits > 1000, "%s: the queries found something (%zu)", su->family, total_hits);
        wvol_store_hits_free(&hits);
        free(f);
        wvol_store_destroy(st);
        wvol_selection_destroy(sel);
        wvol_coeffs_destroy(c);
    }
}

/* Point evaluation against an independent sum over the kept set with the
 * basis module's own evaluation (wvol_basis_value / _deriv), periodic images
 * included, and against wvol_fhat_eval on the densified coefficients. */
static void eval_matches_independent_sum(void)
{
    for (size_t si = 0; si < NSETUPS; si++) {
        const setup *su = setups + si;
        wvol_coeffs *c = make_coeffs(su->family, su->levels, su->n[0], su->n[1], su->n[2]);
        wvol_selection *sel = keep_fraction(c, su->fraction);
        wvol_store *st = NULL;
        wvol_coeffs *d = NULL;
        size_t nf, P[3] = {c->px, c->py, c->pz};
        fn *f = kept_list(c, sel, &nf);
        wvol_store_build(&st, c, sel, NULL, NULL);
        wvol_store_densify(st, &d, NULL);
        const wvol_basis *b = wvol_store_basis(st);
        double s = c->filter->center, S = c->filter->length - 1, worst = 0, worst2 = 0, scale = 0;
        for (size_t i = 0; i < nf; i++) scale += fabs(f[i].value);
        for (int t = 0; t < 40; t++) {
            double x[3], g[3], g2[3], fe = 0, ge[3] = {0, 0, 0};
            for (int a = 0; a < 3; a++) x[a] = P[a] == 1 ? 0.0 : (urand() * 1.2 - 0.1) * (double)P[a];
            double v = wvol_store_eval(st, x, g);
            for (size_t i = 0; i < nf; i++) {
                int m = f[i].m;
                double B[3], D[3], nm = 1.0;
                for (int a = 0; a < 3; a++) {
                    int which = (f[i].band >> a) & 1;
                    B[a] = D[a] = 0.0;
                    if (P[a] == 1) {
                        B[a] = 1.0;
                        continue;
                    }
                    nm *= sqrt(ldexp(1.0, -m));
                    double y = x[a] + s, lo = ldexp((double)f[i].pos[a], m);
                    int64_t n0 = (int64_t)ceil((lo - y) / (double)P[a]), n1 = (int64_t)floor((lo + ldexp(S, m) - y) / (double)P[a]);
                    for (int64_t n = n0; n <= n1; n++) {
                        double u = (y + (double)n * (double)P[a]) / ldexp(1.0, m) - (double)f[i].pos[a];
                        if (u < 0 || u >= S) continue;
                        B[a] += wvol_basis_value(b, which, u);
                        D[a] += wvol_basis_deriv(b, which, u) / ldexp(1.0, m);
                    }
                }
                fe += f[i].value * nm * B[0] * B[1] * B[2];
                ge[0] += f[i].value * nm * D[0] * B[1] * B[2];
                ge[1] += f[i].value * nm * B[0] * D[1] * B[2];
                ge[2] += f[i].value * nm * B[0] * B[1] * D[2];
            }
            worst = fmax(worst, fabs(v - fe));
            for (int a = 0; a < 3; a++) worst = fmax(worst, fabs(g[a] - ge[a]));
            double v2 = wvol_fhat_eval(d, b, x, g2);
            worst2 = fmax(worst2, fabs(v - v2));
            for (int a = 0; a < 3; a++) worst2 = fmax(worst2, fabs(g[a] - g2[a]));
        }
        CHECK(worst <= 1e-11 * scale, "%s: eval vs independent sum %g (scale %g)", su->family, worst, scale);
        CHECK(worst2 <= 1e-9 * scale, "%s: eval vs wvol_fhat_eval %g (scale %g)", su->family, worst2, scale);
        /* Haar: f^ at a sample is the reconstructed sample */
        if (!strcmp(su->family, "haar")) {
            wvol_volume *r = NULL;
            double w = 0;
            wvol_idwt3_ex(&r, d, 1, NULL);
            for (size_t k = 0; k < c->nz; k += 3)
                for (size_t j = 0; j < c->ny; j += 2)
                    for (size_t i = 0; i < c->nx; i++) {
                        double x[3] = {(double)i, (double)j, (double)k};
                        w = fmax(w, fabs(wvol_store_eval(st, x, NULL) - r->data[i + c->nx * (j + c->ny * k)]));
                    }
            CHECK(w < 1e-4, "haar f^ at samples vs reconstruction: %g", w);
            wvol_volume_destroy(r);
        }
        free(f);
        wvol_coeffs_destroy(d);
        wvol_store_destroy(st);
        wvol_selection_destroy(sel);
        wvol_coeffs_destroy(c);
    }
}

/* The bounds the iso tracer relies on: sampled f^ and grad f^ on random boxes
 * never leave them. Reports the tightness (sampled extent / bound). */
static void bounds_are_never_exceeded(void)
{
    for (size_t si = 0; si < NSETUPS; si++) {
        const setup *su = setups + si;
        wvol_coeffs *c = make_coeffs(su->family, su->levels, su->n[0], su->n[1], su->n[2]);
        wvol_selection *sel = keep_fraction(c, su->fraction);
        wvol_store *st = NULL;
        size_t P[3] = {c->px, c->py, c->pz}, violations = 0, samples = 0;
        double tight_v = 0, tight_g = 0, sum_v = 0, sum_g = 0;
        wvol_store_build(&st, c, sel, NULL, NULL);
        for (int t = 0; t < 60; t++) {
            double a[3], b[3];
            wvol_store_bounds bd;
            random_box(c, a, b, t < 20 ? 0.5 : t < 40 ? 3.0 : 10.0);
            for (int x = 0; x < 3; x++)
                if (P[x] == 1) a[x] = b[x] = 0.0;
            CHECK(wvol_store_box_bounds(st, a, b, &bd, NULL) == WVOL_OK, "bounds");
            double fmin_ = INFINITY, fmax_ = -INFINITY, gmax[3] = {0, 0, 0}, gn = 0;
            for (int k = 0; k < 200; k++) {
                double x[3], g[3];
                for (int ax = 0; ax < 3; ax++) {
                    /* grid corners and edges first, then random points */
                    double u = k < 27 ? (double)((k / (int)pow(3, ax)) % 3) / 2.0 : urand();
                    x[ax] = a[ax] + u * (b[ax] - a[ax]);
                }
                double v = wvol_store_eval(st, x, g);
                samples++;
                if (v < bd.vmin || v > bd.vmax || fabs(v) > bd.vabs) violations++;
                double n2 = 0;
                for (int ax = 0; ax < 3; ax++) {
                    if (fabs(g[ax]) > bd.grad[ax]) violations++;
                    gmax[ax] = fmax(gmax[ax], fabs(g[ax]));
                    n2 += g[ax] * g[ax];
                }
                if (sqrt(n2) > bd.grad_norm) violations++;
                gn = fmax(gn, sqrt(n2));
                fmin_ = fmin(fmin_, v), fmax_ = fmax(fmax_, v);
            }
            double tv = (fmax_ - fmin_) / fmax(bd.vmax - bd.vmin, 1e-300), tg = gn / fmax(bd.grad_norm, 1e-300);
            tight_v = fmax(tight_v, tv), tight_g = fmax(tight_g, tg);
            sum_v += tv, sum_g += tg;
        }
        CHECK(violations == 0, "%s: %zu of %zu samples outside the bounds", su->family, violations, samples);
        printf("bounds %-5s: value range tightness mean %.3f max %.3f; gradient mean %.3f max %.3f\n", su->family,
               sum_v / 60, tight_v, sum_g / 60, tight_g);
        wvol_store_destroy(st);
        wvol_selection_destroy(sel);
        wvol_coeffs_destroy(c);
    }
}

/* Per-function maxima (periodic copies included) and subtree sums: a store
 * holding one coefficient 1 is sampled densely over a whole period. */
static void function_and_node_bounds_hold(void)
{
    const char *fams[] = {"haar", "db2", "db4", "coif1", "bl3"};
    for (int fi = 0; fi < 5; fi++) {
        /* bl3: a point meets 128^3 root images at level 1, so only a few samples of two bands */
        int bl = !strcmp(fams[fi], "bl3"), levels = bl ? 1 : 3, samples = bl ? 3 : 600;
        size_t n = 16; /* level 3: period 16 holds less than one db4 support (56): copies overlap */
        wvol_coeffs *c = NULL;
        wvol_coeffs_create(&c, fixture_filter(fams[fi]), levels, n, n, n, NULL);
        size_t worst_v = 0;
        double tv = 0, tg = 0;
        for (int m = 1; m <= levels; m++)
            for (int band = (m == levels ? 0 : 1); band < 8; band += bl ? 7 : 1) {
                wvol_store *st = NULL;
                memset(c->data, 0, n * n * n * sizeof(float));
                size_t e = n >> m, idx = wvol_coeffs_index(c, m, band, e / 2, e - 1, 0);
                c->data[idx] = 1.0f;
                wvol_store_build(&st, c, NULL, NULL, NULL);
                double vmax, gmax[3], fm = 0, gm[3] = {0, 0, 0};
                wvol_store_function_bounds(st, m, band, &vmax, gmax);
                for (int k = 0; k < samples; k++) {
                    double x[3] = {urand() * n, urand() * n, urand() * n}, g[3];
                    fm = fmax(fm, fabs(wvol_store_eval(st, x, g)));
                    for (int a = 0; a < 3; a++) gm[a] = fmax(gm[a], fabs(g[a]));
                }
                if (fm > vmax) worst_v++;
                for (int a = 0; a < 3; a++)
                    if (gm[a] > gmax[a]) worst_v++;
                tv = fmax(tv, fm / vmax), tg = fmax(tg, gm[0] / fmax(gmax[0], 1e-300));
                /* the root's subtree bound covers the function (detail bands) */
                if (band) {
                    wvol_store_node nd;
                    double sv = 0, sg[3] = {0, 0, 0};
                    for (size_t i = 0; i < wvol_store_node_count(st); i++) {
                        wvol_store_node_get(st, i, &nd);
                        if (nd.level == levels) {
                            sv += nd.vbound;
                            for (int a = 0; a < 3; a++) sg[a] += nd.gbound[a];
                        }
                    }
                    CHECK(sv >= vmax && sg[0] >= gmax[0] && sg[1] >= gmax[1] && sg[2] >= gmax[2],
                          "%s m %d band %d: root bounds %g < %g", fams[fi], m, band, sv, vmax);
                }
                wvol_store_destroy(st);
            }
        CHECK(worst_v == 0, "%s: %zu single-function maxima exceeded", fams[fi], worst_v);
        printf("function bounds %-5s: sampled/bound value %.3f, gradient %.3f\n", fams[fi], tv, tg);
        wvol_coeffs_destroy(c);
    }
}

/* Subtree bounds add up: each node's bound >= own |c| max|w| + children's. */
static void subtree_bounds_are_consistent(void)
{
    wvol_coeffs *c = make_coeffs("db2", 3, 32, 32, 32);
    wvol_selection *sel = keep_fraction(c, 0.05);
    wvol_store *st = NULL;
    wvol_store_info info;
    size_t bad = 0, childbad = 0;
    wvol_store_build(&st, c, sel, NULL, NULL);
    wvol_store_get_info(st, &info);
    for (size_t i = 0; i < info.nodes; i++) {
        wvol_store_node nd, ch;
        wvol_store_node_get(st, i, &nd);
        double v = 0, g[3] = {0, 0, 0};
        int k = 0;
        for (int l = 1; l < 8; l++) {
            if (!((nd.band_mask >> (l - 1)) & 1)) continue;
            double fv, fg[3];
            wvol_store_function_bounds(st, nd.level, l, &fv, fg);
            v += fabs(nd.values[k]) * fv;
            for (int a = 0; a < 3; a++) g[a] += fabs(nd.values[k]) * fg[a];
            k++;
        }
        for (int ci = 0, j = 0; ci < 8; ci++) {
            if (!((nd.child_mask >> ci) & 1)) continue;
            wvol_store_node_get(st, nd.child_first + (size_t)j++, &ch);
            if (ch.level != nd.level - 1 || ch.p != 2 * nd.p + (ci & 1) || ch.q != 2 * nd.q + ((ci >> 1) & 1) ||
                ch.r != 2 * nd.r + ((ci >> 2) & 1))
                childbad++;
            for (int a = 0; a < 3; a++)
                if (ch.lo[a] < nd.lo[a] || ch.hi[a] > nd.hi[a]) childbad++;
            v += ch.vbound;
            for (int a = 0; a < 3; a++) g[a] += ch.gbound[a];
        }
        if (nd.vbound < v * (1 - 1e-12) || nd.gbound[0] < g[0] * (1 - 1e-12)) bad++;
        if (!nd.band_mask && !nd.child_mask) bad++; /* an empty node is never made */
    }
    CHECK(bad == 0, "%zu nodes with bounds below their parts", bad);
    CHECK(childbad == 0, "%zu child links wrong", childbad);
    CHECK(info.roots <= info.lowpass[0] * info.lowpass[1] * info.lowpass[2], "roots");
    wvol_store_destroy(st);
    wvol_selection_destroy(sel);
    wvol_coeffs_destroy(c);
}

static void empty_selection_and_bad_input(void)
{
    wvol_coeffs *c = make_coeffs("db2", 2, 16, 16, 16);
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    wvol_selection *sel = NULL;
    wvol_store *st = NULL;
    wvol_store_hits hits = {0};
    wvol_store_bounds bd;
    wvol_error err;
    prm.mode = WVOL_SELECT_COUNT, prm.count = 0;
    wvol_select(&sel, c, &prm, NULL, NULL, NULL);
    CHECK(wvol_store_build(&st, c, sel, NULL, &err) == WVOL_OK, "low-pass-only store: %s", err.message);
    wvol_store_info info;
    wvol_store_get_info(st, &info);
    CHECK(info.nodes == 0 && info.kept == 64, "only the low-pass cube: %zu nodes, %zu kept", info.nodes, info.kept);
    double a[3] = {3, 4, 5}, b[3] = {4, 5, 6};
    CHECK(wvol_store_query_box(st, a, b, &hits, NULL) == WVOL_OK && hits.count > 0, "low-pass hits");
    for (size_t i = 0; i < hits.count; i++) CHECK(hits.hits[i].band == 0 && hits.hits[i].level == 2, "low-pass only");
    CHECK(wvol_store_box_bounds(st, a, b, &bd, NULL) == WVOL_OK && bd.vmax >= bd.vmin, "bounds");
    /* bad input */
    double bad_lo[3] = {5, 0, 0}, bad_hi[3] = {4, 1, 1}, nan3[3] = {NAN, 0, 0}, huge[3] = {1e9, 1, 1}, z[3] = {0, 0, 0};
    CHECK(wvol_store_query_box(st, bad_lo, bad_hi, &hits, &err) == WVOL_ERR_ARG, "lo > hi refused");
    CHECK(wvol_store_query_box(st, nan3, b, &hits, &err) == WVOL_ERR_ARG, "NaN box refused");
    CHECK(wvol_store_query_box(st, z, huge, &hits, &err) == WVOL_ERR_ARG && strstr(err.message, "periods"),
          "a box of 1e9 voxels refused: %s", err.message);
    CHECK(wvol_store_query_ray(st, z, b, 1.0, 0.0, &hits, &err) == WVOL_ERR_ARG, "tmin > tmax refused");
    CHECK(wvol_store_query_ray(st, z, nan3, 0.0, 1.0, &hits, &err) == WVOL_ERR_ARG, "NaN direction refused");
    CHECK(wvol_store_box_bounds(st, bad_lo, bad_hi, &bd, &err) == WVOL_ERR_ARG, "bounds lo > hi refused");
    CHECK(isnan(wvol_store_eval(st, nan3, NULL)), "eval at NaN is NaN");
    CHECK(wvol_store_query_box(NULL, a, b, &hits, &err) == WVOL_ERR_ARG, "NULL store");
    wvol_store *st2 = (wvol_store *)&st2;
    CHECK(wvol_store_build(&st2, NULL, NULL, NULL, &err) == WVOL_ERR_ARG && st2 == NULL, "NULL coefficients");
    wvol_coeffs *other = make_coeffs("db2", 2, 16, 16, 8);
    CHECK(wvol_store_build(&st2, other, sel, NULL, &err) == WVOL_ERR_DIMS, "selection of another layout refused");
    wvol_store_params sp;
    wvol_store_params_default(&sp);
    sp.spline_J = 40;
    CHECK(wvol_store_build(&st2, c, sel, &sp, &err) == WVOL_ERR_ARG && st2 == NULL && strstr(err.message, "J = 40"),
          "spline J 40 refused: %s", err.message);
    /* NaN or Inf coefficients and a bad geometry are refused, naming the problem */
    {
        float keep = c->data[9];
        c->data[9] = NAN;
        CHECK(wvol_store_build(&st2, c, NULL, NULL, &err) == WVOL_ERR_NONFINITE && !st2 && strstr(err.message, "NaN"),
              "NaN coefficient: %s", err.message);
        c->data[9] = -INFINITY;
        CHECK(wvol_store_build(&st2, c, sel, NULL, &err) == WVOL_ERR_NONFINITE && !st2 && strstr(err.message, "Inf"),
              "Inf coefficient: %s", err.message);
        c->data[9] = keep;
        c->spacing[0] = NAN;
        CHECK(wvol_store_build(&st2, c, NULL, NULL, &err) == WVOL_ERR_ARG && !st2 && strstr(err.message, "spacing"),
              "NaN spacing: %s", err.message);
        c->spacing[0] = -2;
        CHECK(wvol_store_build(&st2, c, NULL, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "spacing"),
              "negative spacing: %s", err.message);
        c->spacing[0] = 1;
        c->origin[1] = INFINITY;
        CHECK(wvol_store_build(&st2, c, NULL, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "origin"),
              "infinite origin: %s", err.message);
        c->origin[1] = 0;
    }
    wvol_store_destroy(NULL);
    wvol_store_hits_free(&hits);
    wvol_coeffs_destroy(other);
    wvol_store_destroy(st);
    wvol_selection_destroy(sel);
    wvol_coeffs_destroy(c);
}

int main(void)
{
    lookup_and_iteration_give_the_kept_set();
    queries_match_brute_force();
    eval_matches_independent_sum();
    bounds_are_never_exceeded();
    function_and_node_bounds_hold();
    subtree_bounds_are_consistent();
    empty_selection_and_bad_input();
    return check_summary("test_store");
}
