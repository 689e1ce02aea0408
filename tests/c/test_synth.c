/* SPDX-License-Identifier: MIT */
/* datasets-synth: determinism, value ranges, labels, geometry, known values. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "check.h"
#include "wvol/source.h"
#include "wvol_synth.h"

static const char *kinds[] = {"gaussian", "blobs", "skull", "textures", "shepp-logan", "turbulence"};
enum { NKINDS = 6 };

static wvol_volume *make(const char *kind, size_t nx, size_t ny, size_t nz, uint64_t seed, double noise,
                         wvol_volume **labels)
{
    wvol_synth_params p;
    wvol_volume *v = NULL;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[0] = nx, p.dims[1] = ny, p.dims[2] = nz;
    p.seed = seed;
    p.noise = noise;
    CHECK(wvol_synth_make(&v, labels, kind, &p, &err) == WVOL_OK, "%s %zux%zux%zu: %s", kind, nx, ny, nz,
          err.message);
    return v;
}

static int same_bytes(const wvol_volume *a, const wvol_volume *b)
{
    return a && b && a->nx == b->nx && a->ny == b->ny && a->nz == b->nz &&
           memcmp(a->data, b->data, wvol_volume_count(a) * sizeof(float)) == 0;
}

static void rng_matches_reference(void)
{
    wvol_rng r;
    double sum = 0, sum2 = 0, lo = 1, hi = 0;
    int i, n = 200000;
    /* splitmix64's published first output for state 0 */
    CHECK(wvol_hash64(0) == 0xE220A8397B1DCDAFull, "splitmix64(0) = %016llx",
          (unsigned long long)wvol_hash64(0));
    wvol_rng_seed(&r, 42);
    for (i = 0; i < n; i++) {
        double u = wvol_rng_uniform(&r);
        if (u < lo) lo = u;
        if (u > hi) hi = u;
    }
    CHECK(lo >= 0 && hi < 1 && lo < 1e-4 && hi > 1 - 1e-4, "uniform range %g..%g", lo, hi);
    for (i = 0; i < n; i++) {
        double z = wvol_rng_normal(&r);
        sum += z;
        sum2 += z * z;
    }
    CHECK_NEAR(sum / n, 0.0, 0.01, "normal mean");
    CHECK_NEAR(sum2 / n, 1.0, 0.02, "normal variance");
}

static void same_seed_same_bytes_any_threads(void)
{
    int k;
    for (k = 0; k < NKINDS; k++) {
        wvol_volume *a, *b, *c, *la = NULL, *lb = NULL;
        a = make(kinds[k], 19, 13, 11, 7, 3.0, &la);
#ifdef _OPENMP
        omp_set_num_threads(1);
#endif
        b = make(kinds[k], 19, 13, 11, 7, 3.0, &lb);
#ifdef _OPENMP
        omp_set_num_threads(3);
#endif
        c = make(kinds[k], 19, 13, 11, 7, 3.0, NULL);
#ifdef _OPENMP
        omp_set_num_threads(omp_get_num_procs());
#endif
        CHECK(same_bytes(a, b) && same_bytes(a, c), "%s: same params + seed must give the same bytes", kinds[k]);
        CHECK((la == NULL) == (lb == NULL) && (!la || same_bytes(la, lb)), "%s: labels deterministic", kinds[k]);
        wvol_volume_destroy(a);
        wvol_volume_destroy(b);
        wvol_volume_destroy(c);
        wvol_volume_destroy(la);
        wvol_volume_destroy(lb);
    }
}

static void different_seed_differs(void)
{
    int k;
    for (k = 0; k < NKINDS; k++) {
        /* with noise every generator depends on the seed */
        wvol_volume *a = make(kinds[k], 24, 20, 16, 1, 1.0, NULL), *b = make(kinds[k], 24, 20, 16, 2, 1.0, NULL);
        CHECK(a && b && !same_bytes(a, b), "%s: seeds 1 and 2 with noise must differ", kinds[k]);
        wvol_volume_destroy(a);
        wvol_volume_destroy(b);
    }
    /* without noise, the seeded generators still differ (blob layout, regions, bone texture) */
    for (k = 1; k <= 3; k++) {
        wvol_volume *a = make(kinds[k], 48, 48, 48, 1, 0, NULL), *b = make(kinds[k], 48, 48, 48, 99, 0, NULL);
        CHECK(a && b && !same_bytes(a, b), "%s: seeds 1 and 99 must differ without noise", kinds[k]);
        wvol_volume_destroy(a);
        wvol_volume_destroy(b);
    }
}

static void geometry_is_centred(void)
{
    wvol_synth_params p;
    wvol_volume *v = NULL;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[0] = 10, p.dims[1] = 7, p.dims[2] = 1;
    CHECK(wvol_synth_gaussian(&v, &p, &err) == WVOL_OK, "%s", err.message);
    CHECK(v && v->spacing[0] == 1 && v->spacing[1] == 1 && v->spacing[2] == 1, "default spacing 1");
    CHECK(v && v->origin[0] == -4.5 && v->origin[1] == -3 && v->origin[2] == 0, "origin centres the volume");
    wvol_volume_destroy(v);
    p.dims[0] = p.dims[1] = p.dims[2] = 64;
    CHECK(wvol_synth_skull(&v, NULL, &p, &err) == WVOL_OK, "%s", err.message);
    CHECK(v && v->spacing[0] == 3.75 && v->spacing[2] == 3.75, "skull default spacing 240 mm / 64");
    CHECK(v && fabs(v->origin[0] + 118.125) < 1e-12, "skull origin %g", v ? v->origin[0] : 0);
    wvol_volume_destroy(v);
    p.spacing[0] = 2, p.spacing[1] = 2, p.spacing[2] = 4;
    CHECK(wvol_synth_skull(&v, NULL, &p, &err) == WVOL_OK, "%s", err.message);
    CHECK(v && v->spacing[2] == 4 && v->origin[2] == -126, "explicit anisotropic spacing kept");
    wvol_volume_destroy(v);
}

/* ---- gaussian ------------------------------------------------------------ */

static void gaussian_values(void)
{
    wvol_volume *v = make("gaussian", 33, 33, 33, 1, 0, NULL), *b;
    size_t n = 33, i, j, k;
    double maxdiff = 0, u, expect;
    if (!v) return;
    CHECK_NEAR(v->data[16 + n * (16 + n * 16)], 1.0, 1e-7, "peak 1 at the centre voxel");
    for (k = 0; k < n; k++)
        for (j = 0; j < n; j++)
            for (i = 0; i < n; i++) {
                double a = v->data[i + n * (j + n * k)];
                double d1 = fabs(a - v->data[(n - 1 - i) + n * (j + n * k)]);
                double d2 = fabs(a - v->data[j + n * (i + n * k)]);
                double d3 = fabs(a - v->data[k + n * (j + n * i)]);
                if (d1 > maxdiff) maxdiff = d1;
                if (d2 > maxdiff) maxdiff = d2;
                if (d3 > maxdiff) maxdiff = d3;
            }
    CHECK(maxdiff < 1e-6, "gaussian is symmetric (max diff %g)", maxdiff);
    /* f(u) = exp(-u^2 / (2 * 0.25^2)) along x, u = (2i + 1 - n) / n */
    i = 24;
    u = (2.0 * (double)i + 1.0 - 33.0) / 33.0;
    expect = exp(-u * u / (2 * 0.0625));
    CHECK_NEAR(v->data[i + n * (16 + n * 16)], expect, 1e-6, "gaussian value on the x axis");
    wvol_volume_destroy(v);
    /* blobs are not symmetric */
    b = make("blobs", 32, 32, 32, 5, 0, NULL);
    maxdiff = 0;
    for (i = 0; b && i < 32 * 32 * 32; i++) {
        size_t x = i % 32, rest = i / 32;
        double d = fabs(b->data[i] - b->data[(31 - x) + 32 * rest]);
        if (d > maxdiff) maxdiff = d;
    }
    CHECK(maxdiff > 0.05, "blobs not mirror-symmetric (max diff %g)", maxdiff);
    wvol_volume_destroy(b);
}

/* ---- skull ----------------------------------------------------------------- */

static float at_mm(const wvol_volume *v, double x, double y, double z)
{
    size_t i = (size_t)lround((x - v->origin[0]) / v->spacing[0]);
    size_t j = (size_t)lround((y - v->origin[1]) / v->spacing[1]);
    size_t k = (size_t)lround((z - v->origin[2]) / v->spacing[2]);
    return v->data[i + v->nx * (j + v->ny * k)];
}

static void class_fractions(const wvol_volume *lab, double frac[WVOL_SKULL_CLASSES])
{
    size_t n = wvol_volume_count(lab), i;
    int c;
    for (c = 0; c < WVOL_SKULL_CLASSES; c++) frac[c] = 0;
    for (i = 0; i < n; i++) {
        c = (int)lab->data[i];
        if (c >= 0 && c < WVOL_SKULL_CLASSES) frac[c] += 1.0 / (double)n;
    }
}

static void skull_tissue_ranges(void)
{
    static const struct {
        const char *name;
        double lo, hi, min_share;
    } tissue[WVOL_SKULL_CLASSES] = {
        {"air", -1000, -990, 0.99}, {"soft tissue", 0, 80, 0.98}, {"brain", 28, 40, 0.99},
        {"csf", 0, 15, 0.95},       {"bone", 700, 1800, 0.98}};
    wvol_volume *lab = NULL, *v = make("skull", 96, 96, 96, 3, 0, &lab);
    size_t nx = 96, i, j, k, inside[WVOL_SKULL_CLASSES] = {0}, total[WVOL_SKULL_CLASSES] = {0};
    double vmin, vmax, frac[WVOL_SKULL_CLASSES];
    int c, bad_label = 0;
    if (!v || !lab) return;
    wvol_volume_range(v, &vmin, &vmax, NULL);
    CHECK(vmin >= -1000 && vmax <= 1800, "skull values within -1000..1800 HU: %g..%g", vmin, vmax);
    /* interior voxels (6 neighbours of the same class) hold their tissue's values */
    for (k = 1; k + 1 < nx; k++)
        for (j = 1; j + 1 < nx; j++)
            for (i = 1; i + 1 < nx; i++) {
                size_t q = i + nx * (j + nx * k);
                float l = lab->data[q];
                if (l != floorf(l) || l < 0 || l >= WVOL_SKULL_CLASSES) {
                    bad_label++;
                    continue;
                }
                if (lab->data[q - 1] != l || lab->data[q + 1] != l || lab->data[q - nx] != l ||
                    lab->data[q + nx] != l || lab->data[q - nx * nx] != l || lab->data[q + nx * nx] != l)
                    continue;
                c = (int)l;
                total[c]++;
                if (v->data[q] >= tissue[c].lo && v->data[q] <= tissue[c].hi) inside[c]++;
            }
    CHECK(bad_label == 0, "%d labels are not integers 0..4", bad_label);
    for (c = 0; c < WVOL_SKULL_CLASSES; c++) {
        double share = total[c] ? (double)inside[c] / (double)total[c] : 0;
        CHECK(total[c] > 0 && share >= tissue[c].min_share, "%s: %.4f of %zu interior voxels in %g..%g",
              tissue[c].name, share, total[c], tissue[c].lo, tissue[c].hi);
    }
    class_fractions(lab, frac);
    CHECK(frac[WVOL_SKULL_BONE] > 0.02 && frac[WVOL_SKULL_BRAIN] > 0.08 && frac[WVOL_SKULL_AIR] > 0.4,
          "plausible shares: bone %.3f brain %.3f air %.3f", frac[WVOL_SKULL_BONE], frac[WVOL_SKULL_BRAIN],
          frac[WVOL_SKULL_AIR]);
    /* anatomy at known places (mm, LPS: +y posterior, +z superior) */
    CHECK(at_mm(v, -118, -118, -118) == -1000.0f, "air in the corner");
    CHECK(at_mm(v, 0, 30, 60) >= 28 && at_mm(v, 0, 30, 60) <= 40, "brain above the ventricles: %g",
          at_mm(v, 0, 30, 60));
    CHECK(at_mm(v, 0, 89, 30) >= 700, "occipital bone: %g", at_mm(v, 0, 89, 30));
    CHECK(at_mm(v, 0, 5, 100) >= 700, "bone at the vertex: %g", at_mm(v, 0, 5, 100));
    CHECK(at_mm(v, 33, -72, -18) < 30 && at_mm(v, 33, -72, -18) > 0, "eye: %g", at_mm(v, 33, -72, -18));
    CHECK(at_mm(v, 0, 28, -40) < 100, "foramen magnum is open: %g", at_mm(v, 0, 28, -40));
    CHECK(at_mm(v, 0, -16, -100) == -1000.0f, "airway: %g", at_mm(v, 0, -16, -100));
    CHECK(at_mm(v, 25, -52, -88) >= 700, "jaw: %g", at_mm(v, 25, -52, -88));
    wvol_volume_destroy(v);
    wvol_volume_destroy(lab);
}

static void skull_same_anatomy_at_any_resolution(void)
{
    wvol_synth_params p;
    wvol_volume *v = NULL, *lab = NULL;
    wvol_error err;
    double ref[WVOL_SKULL_CLASSES], f[WVOL_SKULL_CLASSES];
    static const size_t sizes[3][3] = {{48, 48, 48}, {80, 80, 80}, {80, 80, 40}};
    int s, c;
    wvol_synth_params_default(&p);
    p.dims[0] = p.dims[1] = p.dims[2] = 128;
    CHECK(wvol_synth_skull(&v, &lab, &p, &err) == WVOL_OK, "skull 128: %s", err.message);
    if (!v || !lab) return;
    class_fractions(lab, ref);
    wvol_volume_destroy(v);
    wvol_volume_destroy(lab);
    for (s = 0; s < 3; s++) {
        memcpy(p.dims, sizes[s], sizeof p.dims);
        /* the 80x80x40 case: voxels twice as tall, same world extent */
        p.spacing[0] = p.spacing[1] = s == 2 ? 3.0 : 0.0;
        p.spacing[2] = s == 2 ? 6.0 : 0.0;
        if (wvol_synth_skull(&v, &lab, &p, &err) != WVOL_OK) {
            CHECK(0, "%s", err.message);
            continue;
        }
        class_fractions(lab, f);
        for (c = 0; c < WVOL_SKULL_CLASSES; c++)
            if (c != WVOL_SKULL_CSF)
                CHECK(fabs(f[c] - ref[c]) <= 0.15 * ref[c] + 0.002, "size %zux%zux%zu class %d: share %.4f vs %.4f",
                      sizes[s][0], sizes[s][1], sizes[s][2], c, f[c], ref[c]);
        wvol_volume_destroy(v);
        wvol_volume_destroy(lab);
    }
}

static void skull_noise_has_the_asked_sigma(void)
{
    wvol_volume *a = make("skull", 40, 40, 40, 4, 0, NULL), *b = make("skull", 40, 40, 40, 4, 25.0, NULL);
    size_t n = 40 * 40 * 40, i;
    double s = 0, s2 = 0;
    if (!a || !b) return;
    for (i = 0; i < n; i++) {
        double d = (double)b->data[i] - (double)a->data[i];
        s += d;
        s2 += d * d;
    }
    s /= (double)n;
    CHECK(fabs(s) < 0.5, "noise mean %g", s);
    CHECK_NEAR(sqrt(s2 / (double)n - s * s), 25.0, 0.5, "noise sigma");
    wvol_volume_destroy(a);
    wvol_volume_destroy(b);
}

/* ---- textures -------------------------------------------------------------- */

static void texture_labels_match_region_count(void)
{
    static const char *variants[] = {"gratings", "frequencies", "dots", "mixed"};
    static const int counts[] = {2, 4, 7};
    static const size_t sizes[2][3] = {{96, 80, 1}, {40, 40, 40}};
    int vi, ci, si;
    for (si = 0; si < 2; si++)
        for (vi = 0; vi < 4; vi++)
            for (ci = 0; ci < 3; ci++) {
                wvol_synth_params p;
                wvol_volume *v = NULL, *lab = NULL;
                wvol_error err;
                size_t n, i, seen[16] = {0};
                int bad = 0, missing = 0, r;
                double vmin, vmax;
                wvol_synth_params_default(&p);
                memcpy(p.dims, sizes[si], sizeof p.dims);
                p.variant = variants[vi];
                p.count = counts[ci];
                p.seed = 11 + (uint64_t)ci;
                if (wvol_synth_textures(&v, &lab, &p, &err) != WVOL_OK) {
                    CHECK(0, "textures %s: %s", variants[vi], err.message);
                    continue;
                }
                n = wvol_volume_count(v);
                for (i = 0; i < n; i++) {
                    float l = lab->data[i];
                    if (l != floorf(l) || l < 0 || l >= counts[ci]) bad++;
                    else seen[(int)l]++;
                }
                for (r = 0; r < counts[ci]; r++)
                    if (seen[r] < n / (size_t)(8 * counts[ci])) missing++;
                wvol_volume_range(v, &vmin, &vmax, NULL);
                CHECK(bad == 0 && missing == 0, "%s count %d size %zu^%d: %d bad labels, %d regions missing or tiny",
                      variants[vi], counts[ci], sizes[si][0], si ? 3 : 2, bad, missing);
                CHECK(vmin >= 0 && vmax <= 1 && vmax - vmin > 0.5, "%s values in [0,1]: %g..%g", variants[vi], vmin,
                      vmax);
                CHECK(v->nz == sizes[si][2] && lab->nz == v->nz, "label map has the volume's size");
                wvol_volume_destroy(v);
                wvol_volume_destroy(lab);
            }
}

/* ---- Shepp-Logan ------------------------------------------------------------ */

static float at_u(const wvol_volume *v, double ux, double uy, double uz)
{
    /* voxel centres sit at u = (2i + 1 - n) / n */
    size_t i = (size_t)lround((ux * (double)v->nx + (double)v->nx - 1) / 2);
    size_t j = (size_t)lround((uy * (double)v->ny + (double)v->ny - 1) / 2);
    size_t k = (size_t)lround((uz * (double)v->nz + (double)v->nz - 1) / 2);
    return v->data[i + v->nx * (j + v->ny * k)];
}

static void shepp_logan_known_values(void)
{
    static const struct {
        double u[3], ks, yyw;
        const char *where;
    } pts[] = {
        {{0, 0, 0}, 1.02, 0.2, "centre (a + b)"},
        {{0, 0, 0.8828125}, 2.0, 1.0, "skull shell above the brain (a only)"},
        {{0, 0.35, -0.25}, 1.04, 0.4, "ellipsoid e"},
        {{-0.22, 0, -0.25}, 1.0, 0.0, "ellipsoid c"},
        {{0, 0.1, 0.625}, 1.0, 0.0, "ellipsoid j"},
        {{0.95, 0.95, 0.95}, 0.0, 0.0, "outside"},
    };
    wvol_synth_params p;
    wvol_volume *ks = NULL, *yyw = NULL;
    wvol_error err;
    size_t i;
    wvol_synth_params_default(&p);
    p.dims[0] = p.dims[1] = p.dims[2] = 128;
    CHECK(wvol_synth_shepp_logan(&ks, &p, &err) == WVOL_OK, "%s", err.message);
    p.variant = "yu-ye-wang";
    CHECK(wvol_synth_shepp_logan(&yyw, &p, &err) == WVOL_OK, "%s", err.message);
    if (!ks || !yyw) return;
    for (i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        CHECK_NEAR(at_u(ks, pts[i].u[0], pts[i].u[1], pts[i].u[2]), pts[i].ks, 1e-6, pts[i].where);
        CHECK_NEAR(at_u(yyw, pts[i].u[0], pts[i].u[1], pts[i].u[2]), pts[i].yyw, 1e-6, pts[i].where);
    }
    wvol_volume_destroy(ks);
    wvol_volume_destroy(yyw);
}

/* ---- sizes and bad parameters ------------------------------------------------ */

static void odd_and_one_voxel_thick_sizes(void)
{
    static const size_t sizes[][3] = {{1, 1, 1}, {1, 7, 1}, {3, 5, 7}, {17, 1, 9}, {31, 31, 1}, {1, 24, 24}, {2, 2, 2}};
    size_t s;
    int k;
    for (s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
        for (k = 0; k < NKINDS; k++) {
            wvol_volume *lab = NULL, *v = make(kinds[k], sizes[s][0], sizes[s][1], sizes[s][2], 1, 0.5, &lab);
            wvol_error err;
            if (!v) continue;
            CHECK(v->nx == sizes[s][0] && v->ny == sizes[s][1] && v->nz == sizes[s][2], "dims kept");
            CHECK(wvol_check_finite(v->data, v->nx, v->ny, v->nz, kinds[k], &err) == WVOL_OK, "%s", err.message);
            CHECK(fabs(v->origin[1] + 0.5 * (double)(v->ny - 1) * v->spacing[1]) < 1e-9, "%s origin centred",
                  kinds[k]);
            wvol_volume_destroy(v);
            wvol_volume_destroy(lab);
        }
}

static void bad_parameters_are_refused(void)
{
    wvol_synth_params p;
    wvol_volume *v = (wvol_volume *)&p, *lab = NULL;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[1] = 0;
    CHECK(wvol_synth_make(&v, NULL, "skull", &p, &err) == WVOL_ERR_DIMS && v == NULL, "zero dim: %s", err.message);
    p.dims[0] = p.dims[1] = p.dims[2] = SIZE_MAX / 2;
    CHECK(wvol_synth_make(&v, NULL, "gaussian", &p, &err) == WVOL_ERR_DIMS && strstr(err.message, "overflow"),
          "overflow: %s", err.message);
    wvol_synth_params_default(&p);
    p.noise = -1;
    CHECK(wvol_synth_make(&v, NULL, "blobs", &p, &err) == WVOL_ERR_ARG && strstr(err.message, "noise"),
          "noise: %s", err.message);
    p.noise = 0;
    p.spacing[0] = 1;
    CHECK(wvol_synth_make(&v, NULL, "blobs", &p, &err) == WVOL_ERR_ARG && strstr(err.message, "spacing"),
          "partial spacing: %s", err.message);
    p.spacing[0] = 0;
    CHECK(wvol_synth_make(&v, NULL, "mandelbulb", &p, &err) == WVOL_ERR_ARG && strstr(err.message, "mandelbulb"),
          "unknown kind: %s", err.message);
    p.variant = "plaid";
    CHECK(wvol_synth_make(&v, &lab, "textures", &p, &err) == WVOL_ERR_ARG && strstr(err.message, "plaid") && !lab,
          "unknown variant: %s", err.message);
    CHECK(wvol_synth_make(&v, NULL, "shepp-logan", &p, &err) == WVOL_ERR_ARG, "unknown variant: %s", err.message);
    p.variant = NULL;
    p.count = 17;
    CHECK(wvol_synth_make(&v, NULL, "textures", &p, &err) == WVOL_ERR_ARG, "count: %s", err.message);
    p.count = 0;
    p.sigma = -2;
    CHECK(wvol_synth_make(&v, NULL, "gaussian", &p, &err) == WVOL_ERR_ARG, "sigma: %s", err.message);
    CHECK(wvol_synth_kind_find("Shepp-Logan") == 4 && wvol_synth_kind_find("nope") < 0, "kind lookup");
    CHECK(wvol_synth_kind_has_labels(wvol_synth_kind_find("skull")) &&
              !wvol_synth_kind_has_labels(wvol_synth_kind_find("gaussian")),
          "label kinds");
    {
        size_t dims[3] = {0, 0, 0};
        wvol_synth_kind_default_dims(0, NULL); /* does nothing */
        wvol_synth_kind_default_dims(0, dims);
        CHECK(dims[0] > 0 && dims[1] > 0 && dims[2] > 0, "default dims");
    }
}

static double last_fraction;
static int progress_calls;
static void on_progress(void *user, double f)
{
    (void)user;
    last_fraction = f;
    progress_calls++;
}

static void progress_is_reported(void)
{
    wvol_synth_params p;
    wvol_volume *v = NULL;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[0] = p.dims[1] = p.dims[2] = 32;
    p.progress = on_progress;
    CHECK(wvol_synth_blobs(&v, &p, &err) == WVOL_OK, "%s", err.message);
    CHECK(progress_calls >= 2 && last_fraction == 1.0, "progress: %d calls, last %g", progress_calls, last_fraction);
    wvol_volume_destroy(v);
}

/* Any slab of a generator holds the same bytes as those slices of the whole volume, labels
 * and noise included, whatever the slab sizes. */
static void slabs_equal_the_whole_volume(void)
{
    for (int k = 0; k < NKINDS; k++) {
        wvol_volume *lab = NULL, *v = make(kinds[k], 23, 17, 29, 5, 2.0, &lab);
        wvol_synth_params p;
        wvol_synth_gen *g = NULL;
        wvol_source *src = NULL;
        wvol_error err;
        size_t slice = 23 * 17, dims[3] = {0, 0, 0}, z0 = 0, step = 1;
        float *buf = malloc(29 * slice * sizeof *buf), *lbuf = malloc(29 * slice * sizeof *lbuf);
        wvol_synth_params_default(&p);
        p.dims[0] = 23, p.dims[1] = 17, p.dims[2] = 29;
        p.seed = 5;
        p.noise = 2.0;
        CHECK(wvol_synth_gen_open(&g, kinds[k], &p, &err) == WVOL_OK, "%s: %s", kinds[k], err.message);
        if (!v || !g || !buf || !lbuf) goto next;
        wvol_synth_gen_geometry(g, dims, NULL, NULL);
        CHECK(dims[0] == 23 && dims[1] == 17 && dims[2] == 29, "%s: dims", kinds[k]);
        CHECK(wvol_synth_gen_has_labels(g) == (lab != NULL), "%s: labels", kinds[k]);
        for (; z0 < 29; z0 += step, step = step * 2 + 1) {
            size_t nz = z0 + step <= 29 ? step : 29 - z0;
            CHECK(wvol_synth_gen_slab(g, buf, lab ? lbuf : NULL, z0, nz, &err) == WVOL_OK, "%s", err.message);
            CHECK(memcmp(buf, v->data + z0 * slice, nz * slice * sizeof *buf) == 0, "%s: slab %zu+%zu differs",
                  kinds[k], z0, nz);
            if (lab)
                CHECK(memcmp(lbuf, lab->data + z0 * slice, nz * slice * sizeof *buf) == 0,
                      "%s: label slab %zu+%zu differs", kinds[k], z0, nz);
        }
        CHECK(wvol_synth_gen_slab(g, buf, NULL, 28, 2, &err) == WVOL_ERR_ARG, "%s: past the end refused", kinds[k]);
        /* and as a volume source, backwards */
        CHECK(wvol_synth_source(&src, kinds[k], &p, &err) == WVOL_OK, "%s", err.message);
        CHECK(src && wvol_source_streams(src) && wvol_source_read(src, buf, 20, 9, &err) == WVOL_OK &&
                  memcmp(buf, v->data + 20 * slice, 9 * slice * sizeof *buf) == 0,
              "%s: source slab differs", kinds[k]);
    next:
        wvol_source_destroy(src);
        wvol_synth_gen_close(g);
        free(buf);
        free(lbuf);
        wvol_volume_destroy(v);
        wvol_volume_destroy(lab);
    }
}

/* The turbulence field: unit variance (the modes' sum; a seed's few box-scale modes move
 * it by up to about 20%, so each seed is held to [0.6, 1.4]), mean near 0, and Kolmogorov's
 * second-order structure function S2(r) ~ r^(2/3) in the inertial range: S2(16) / S2(8) along
 * x at 128^3, averaged over 4 seeds, within 0.3 of 2^(2/3) = 1.587 (seeds scatter by about
 * +-0.2: few modes per shell). A smooth field would give 4, white noise 1. Below the finest
 * mode (a period of 4 voxels) it is smooth: S2(2) / S2(1) > 3. */
static void turbulence_follows_kolmogorov(void)
{
    double ratio = 0;
    for (int seed = 1; seed <= 4; seed++) {
        wvol_volume *v = make("turbulence", 128, 128, 128, (uint64_t)seed, 0, NULL);
        double m = 0, var = 0, S[5] = {0};
        size_t n = (size_t)128 * 128 * 128;
        if (!v) continue;
        for (size_t i = 0; i < n; i++) m += v->data[i];
        m /= (double)n;
        for (size_t i = 0; i < n; i++) var += (v->data[i] - m) * (v->data[i] - m);
        var /= (double)n;
        CHECK(fabs(m) < 0.2 && var > 0.6 && var < 1.4, "seed %d: mean %g, variance %g", seed, m, var);
        for (int q = 0; q < 5; q++) {
            size_t r = (size_t)1 << q, c = 0;
            double a = 0;
            for (size_t row = 0; row < 128 * 128; row += 7)
                for (size_t i = 0; i + r < 128; i++) {
                    double d = v->data[row * 128 + i + r] - v->data[row * 128 + i];
                    a += d * d, c++;
                }
            S[q] = a / (double)c;
        }
        CHECK(S[1] / S[0] > 3, "seed %d: S2(2)/S2(1) = %g: smooth below the finest mode", seed, S[1] / S[0]);
        ratio += S[4] / S[3] / 4;
        wvol_volume_destroy(v);
    }
    CHECK(fabs(ratio - pow(2.0, 2.0 / 3.0)) < 0.3, "S2(16)/S2(8) = %g, Kolmogorov 2^(2/3) = 1.587", ratio);
}

int main(void)
{
    slabs_equal_the_whole_volume();
    turbulence_follows_kolmogorov();
    rng_matches_reference();
    same_seed_same_bytes_any_threads();
    different_seed_differs();
    geometry_is_centred();
    gaussian_values();
    skull_tissue_ranges();
    skull_same_anatomy_at_any_resolution();
    skull_noise_has_the_asked_sigma();
    texture_labels_match_region_count();
    shepp_logan_known_values();
    odd_and_one_voxel_thick_sizes();
    bad_parameters_are_refused();
    progress_is_reported();
    return check_summary("test_synth");
}
