/* SPDX-License-Identifier: MIT
 * Marching cubes from a store against dense marching cubes, in thread CPU seconds, in one
 * process (bench/results/iso_mc_profile.md): the volume (a raw float32 n^3 file, or
 * "sphere" for a distance field) is transformed (3 levels), a fraction of its coefficients
 * kept, a store built; then dense MC and the store's brick path are run alternately, reps
 * times, one thread, each the least thread CPU seconds. The first brick extraction (which
 * builds the store's block view and bounds) is reported apart.
 *
 * Usage: iso_bricks_cpu FILE|sphere N ISO [REPS] [WAVELET] [KEEP] [BRICK]
 * (perf record on this process, with the dense runs left out, gives the brick path's
 * profile.) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "wvol/wvol.h"

static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int fail(const char *what, const wvol_error *e)
{
    fprintf(stderr, "iso_bricks_cpu: %s: %s\n", what, e->message);
    return 1;
}

int main(int argc, char **argv)
{
    wvol_error e;
    wvol_volume *v = NULL;
    wvol_coeffs *c = NULL;
    wvol_selection *sel = NULL;
    wvol_store *st = NULL;
    const wvol_filter *flt = NULL;
    wvol_select_params sp;
    wvol_iso_params p;
    size_t n, tris_dense = 0, tris_bricks = 0, skipped = 0, total = 0;
    double iso, best_dense = INFINITY, best_bricks = INFINITY, first = -1.0;
    int reps, dense = getenv("ISO_BRICKS_NO_DENSE") == NULL;
    if (argc < 4) {
        fprintf(stderr, "usage: iso_bricks_cpu FILE|sphere N ISO [REPS] [WAVELET] [KEEP] [BRICK]\n");
        return 2;
    }
    n = (size_t)atol(argv[2]);
    iso = atof(argv[3]);
    reps = argc > 4 ? atoi(argv[4]) : 5;
    if (n < 2 || reps < 1) {
        fprintf(stderr, "iso_bricks_cpu: N >= 2 and REPS >= 1\n");
        return 2;
    }
    if (wvol_volume_create(&v, n, n, n, &e) != WVOL_OK) return fail("volume", &e);
    if (!strcmp(argv[1], "sphere")) {
        for (size_t k = 0; k < n; k++)
            for (size_t j = 0; j < n; j++)
                for (size_t i = 0; i < n; i++) {
                    double x = (double)i - 0.5 * (double)(n - 1), y = (double)j - 0.5 * (double)(n - 1),
                           z = (double)k - 0.5 * (double)(n - 1);
                    v->data[i + n * (j + n * k)] = (float)sqrt(x * x + y * y + z * z);
                }
    } else {
        FILE *f = fopen(argv[1], "rb");
        size_t got = f ? fread(v->data, sizeof(float), n * n * n, f) : 0;
        if (f) fclose(f);
        if (got != n * n * n) {
            fprintf(stderr, "iso_bricks_cpu: %s does not hold %zu^3 floats\n", argv[1], n);
            return 1;
        }
    }
    if (wvol_filter_get(&flt, argc > 5 ? argv[5] : "db2", &e) != WVOL_OK) return fail("wavelet", &e);
    if (wvol_dwt3(&c, v, flt, 3, &e) != WVOL_OK) return fail("transform", &e);
    wvol_select_params_default(&sp);
    sp.mode = WVOL_SELECT_FRACTION;
    sp.fraction = argc > 6 ? atof(argv[6]) : 0.05;
    if (wvol_select(&sel, c, &sp, NULL, NULL, &e) != WVOL_OK) return fail("select", &e);
    if (wvol_store_build(&st, c, sel, NULL, &e) != WVOL_OK) return fail("store", &e);
    wvol_iso_params_default(&p);
    p.threads = 1;
    if (argc > 7) p.brick = atoi(argv[7]);
    for (int r = 0; r < reps; r++) {
        wvol_mesh *m = NULL;
        wvol_iso_stats is;
        double t0, t1;
        if (dense) {
            t0 = cpu_now();
            if (wvol_iso_extract(&m, v, iso, &p, &is, &e) != WVOL_OK) return fail("dense MC", &e);
            t1 = cpu_now();
            if (t1 - t0 < best_dense) best_dense = t1 - t0;
            tris_dense = m->ntris;
            wvol_mesh_destroy(m);
        }
        t0 = cpu_now();
        if (wvol_iso_extract_store(&m, st, iso, &p, &is, &e) != WVOL_OK) return fail("brick path", &e);
        t1 = cpu_now();
        if (first < 0) first = t1 - t0;
        else if (t1 - t0 < best_bricks) best_bricks = t1 - t0;
        tris_bricks = m->ntris;
        skipped = is.bricks_skipped;
        total = is.bricks_total;
        wvol_mesh_destroy(m);
    }
    /* the triangle counts differ a little: the brick path meshes the kept coefficients' reconstruction */
    printf("dense %.1f ms  bricks %.1f ms  ratio %.2f  first %.1f ms  skipped %zu/%zu  triangles %zu %zu\n",
           best_dense * 1e3, best_bricks * 1e3, best_bricks / best_dense, first * 1e3, skipped, total, tris_dense,
           tris_bricks);
    wvol_store_destroy(st);
    wvol_selection_destroy(sel);
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
    return 0;
}
