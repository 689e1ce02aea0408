/* SPDX-License-Identifier: MIT */
/* Store benchmark: selection and octree build times on an n^3 volume (default
 * 256), ray and box query and point evaluation rates, bytes per kept coefficient.
 * Usage: bench_store [n] [family] [levels]. Prints one JSON object. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "wvol/store.h"
#include "wvol/wavelet.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static uint64_t rng = 0x853c49e6748fea9bull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? (size_t)atol(argv[1]) : 256;
    const char *fam = argc > 2 ? argv[2] : "db2";
    int levels = argc > 3 ? atoi(argv[3]) : 3;
    const wvol_filter *f = NULL;
    wvol_volume *v = NULL;
    wvol_coeffs *c = NULL;
    wvol_error err;
    if (wvol_filter_get(&f, fam, &err) || wvol_volume_create(&v, n, n, n, &err)) {
        fprintf(stderr, "bench_store: %s\n", err.message);
        return 1;
    }
    /* a Gaussian blob, a few spheres' shells and mild noise */
    for (size_t k = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++) {
                double x = (double)i / n - 0.5, y = (double)j / n - 0.45, z = (double)k / n - 0.55;
                double r = sqrt(x * x + y * y + z * z), val = 1000.0 * exp(-r * r / 0.02);
                val += r > 0.3 && r < 0.33 ? 400.0 : 0.0;
                v->data[i + n * (j + n * k)] = (float)(val + 2.0 * (urand() - 0.5));
            }
    double t0 = now();
    if (wvol_dwt3(&c, v, f, levels, &err)) {
        fprintf(stderr, "bench_store: %s\n", err.message);
        return 1;
    }
    double t_dwt = now() - t0;
    printf("{\"n\": %zu, \"family\": \"%s\", \"levels\": %d, \"coefficients\": %zu, \"dwt_s\": %.4f,\n", n, fam, levels,
           c->px * c->py * c->pz, t_dwt);

    const char *names[] = {"fraction 0.05", "count 100000", "energy 0.999", "psnr 50", "threshold 1.0",
                           "fraction 0.05 + ellipsoid"};
    wvol_selection *keep5 = NULL;
    printf(" \"select\": [\n");
    for (int mode = 0; mode < 6; mode++) {
        wvol_select_params prm;
        wvol_select_params_default(&prm);
        wvol_select_report rep;
        wvol_selection *sel = NULL;
        switch (mode) {
        case 0: prm.mode = WVOL_SELECT_FRACTION, prm.fraction = 0.05; break;
        case 1: prm.mode = WVOL_SELECT_COUNT, prm.count = 100000; break;
        case 2: prm.mode = WVOL_SELECT_ENERGY, prm.energy = 0.999; break;
        case 3: prm.mode = WVOL_SELECT_PSNR, prm.psnr = 50, prm.peak = 1400.0; break;
        case 4: prm.mode = WVOL_SELECT_THRESHOLD, prm.threshold = 1.0; break;
        default:
            prm.mode = WVOL_SELECT_FRACTION, prm.fraction = 0.05, prm.n_ellipsoids = 1, prm.lod_floor = 0.05;
            prm.ellipsoids[0] = (wvol_lod_ellipsoid){{n * 0.5, n * 0.45, n * 0.55}, {n * 0.1, n * 0.1, n * 0.1}, 2};
        }
        t0 = now();
        if (wvol_select(&sel, c, &prm, NULL, &rep, &err)) {
            fprintf(stderr, "bench_store: %s\n", err.message);
            return 1;
        }
        double t = now() - t0;
        printf("  {\"mode\": \"%s\", \"seconds\": %.4f, \"kept\": %zu, \"predicted_l2\": %.6g, \"predicted_psnr\": %.3f}%s\n",
               names[mode], t, rep.kept, rep.predicted_l2, rep.predicted_psnr, mode < 5 ? "," : "");
        if (mode == 0) keep5 = sel;
        else wvol_selection_destroy(sel);
    }
    printf(" ],\n");

    wvol_store *st = NULL;
    wvol_store_info info;
    t0 = now();
    if (wvol_store_build(&st, c, keep5, NULL, &err)) {
        fprintf(stderr, "bench_store: %s\n", err.message);
        return 1;
    }
    double t_build = now() - t0;
    wvol_store_get_info(st, &info);
    printf(" \"store_5pct\": {\"build_s\": %.4f, \"kept\": %zu, \"nodes\": %zu, \"bytes\": %zu, \"bytes_per_coeff\": %.2f,"
           " \"basis_bytes\": %zu},\n",
           t_build, info.kept, info.nodes, info.bytes, info.bytes_per_coeff, info.basis_bytes);

    /* rays through the volume along random directions, box queries of 8^3 bricks, point evaluations */
    wvol_store_hits hits = {0};
    size_t small = n < 128, nrays = small ? 100 : 2000, total = 0;
    t0 = now();
    for (size_t r = 0; r < nrays; r++) {
        double o[3], d[3], len = 0;
        for (int a = 0; a < 3; a++) o[a] = n * (0.25 + 0.5 * urand()), d[a] = urand() - 0.5, len += d[a] * d[a];
        for (int a = 0; a < 3; a++) d[a] /= sqrt(len);
        wvol_store_query_ray(st, o, d, -0.5 * n, 0.5 * n, &hits, NULL);
        total += hits.count;
    }
    double t_ray = now() - t0;
    size_t nbox = small ? 100 : 2000, btotal = 0;
    t0 = now();
    for (size_t b = 0; b < nbox; b++) {
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) lo[a] = floor(urand() * (n - 8)), hi[a] = lo[a] + 8;
        wvol_store_query_box(st, lo, hi, &hits, NULL);
        btotal += hits.count;
    }
    double t_box = now() - t0;
    wvol_store_bounds bd;
    t0 = now();
    for (size_t b = 0; b < nbox; b++) {
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) lo[a] = floor(urand() * (n - 8)), hi[a] = lo[a] + 8;
        wvol_store_box_bounds(st, lo, hi, &bd, NULL);
    }
    double t_bounds = now() - t0;
    size_t npts = small ? 2000 : 100000;
    double acc = 0;
    t0 = now();
    for (size_t i = 0; i < npts; i++) {
        double x[3] = {urand() * n, urand() * n, urand() * n}, g[3];
        acc += wvol_store_eval(st, x, g);
    }
    double t_eval = now() - t0;
    printf(" \"queries\": {\"ray_us\": %.2f, \"hits_per_ray\": %.1f, \"box8_us\": %.2f, \"hits_per_box8\": %.1f,"
           " \"bounds8_us\": %.2f, \"eval_us\": %.3f, \"checksum\": %.6g}\n}\n",
           1e6 * t_ray / nrays, (double)total / nrays, 1e6 * t_box / nbox, (double)btotal / nbox, 1e6 * t_bounds / nbox,
           1e6 * t_eval / npts, acc);
    wvol_store_hits_free(&hits);
    wvol_store_destroy(st);
    wvol_selection_destroy(keep5);
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
    return 0;
}
