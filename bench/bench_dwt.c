/* SPDX-License-Identifier: MIT */
/* DWT benchmark driver: forward + inverse multi-level float32 transforms of one volume
 * with several wavelets and thread counts, and a plain copy of the same array for the
 * memory-bandwidth bound. Prints one JSON object; bench/bench_dwt.py runs it beside
 * PyWavelets and writes bench/results/dwt.json. */
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/wavelet.h"

static double now(void) { return omp_get_wtime(); }

/* Copy src -> dst with `threads` threads (each a contiguous chunk), as a transform pass
 * streams its data: the peer for bytes-moved bandwidth. */
static void copy_array(float *dst, const float *src, size_t n, int threads)
{
#pragma omp parallel num_threads(threads)
    {
        int t = omp_get_thread_num(), nt = omp_get_num_threads();
        size_t lo = n * (size_t)t / (size_t)nt, hi = n * (size_t)(t + 1) / (size_t)nt;
        memcpy(dst + lo, src + lo, (hi - lo) * sizeof *dst);
    }
}

int main(int argc, char **argv)
{
    size_t n = 256, count;
    int levels = 3, reps = 3, nthr = 0, thr[8];
    const char *input = NULL, *wavelets = "haar,db2,coif1", *threads = "1,2";
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--n")) n = (size_t)atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--levels")) levels = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--reps")) reps = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--input")) input = argv[i + 1];
        else if (!strcmp(argv[i], "--wavelets")) wavelets = argv[i + 1];
        else if (!strcmp(argv[i], "--threads")) threads = argv[i + 1];
        else {
            fprintf(stderr, "bench_dwt: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    for (const char *p = threads; *p && nthr < 8; p = strchr(p, ',') ? strchr(p, ',') + 1 : p + strlen(p))
        thr[nthr++] = atoi(p);
    count = n * n * n;
    float *orig = malloc(count * sizeof *orig), *work = malloc(count * sizeof *work);
    if (!orig || !work) return 1;
    if (input) {
        FILE *fp = fopen(input, "rb");
        if (!fp || fread(orig, sizeof *orig, count, fp) != count) {
            fprintf(stderr, "bench_dwt: cannot read %zu floats from %s\n", count, input);
            return 1;
        }
        fclose(fp);
    } else {
        unsigned s = 12345;
        for (size_t i = 0; i < count; i++) s = s * 1103515245u + 12345u, orig[i] = (float)(s >> 8) / 16777216.0f;
    }
    printf("{\"n\": %zu, \"levels\": %d, \"reps\": %d, \"max_threads\": %d, \"runs\": [", n, levels, reps,
           omp_get_max_threads());
    int first = 1;
    for (int ti = 0; ti < nthr; ti++) {
        double tc = 1e30;
        copy_array(work, orig, count, thr[ti]); /* touch pages */
        for (int r = 0; r < reps + 2; r++) {
            double t0 = now();
            copy_array(work, orig, count, thr[ti]);
            double t = now() - t0;
            if (t < tc) tc = t;
        }
        printf("%s\n  {\"what\": \"copy\", \"threads\": %d, \"seconds\": %.6g, \"bytes\": %zu}", first ? "" : ",",
               thr[ti], tc, 2 * count * sizeof(float));
        first = 0;
        char list[256];
        snprintf(list, sizeof list, "%s", wavelets);
        for (char *name = strtok(list, ","); name; name = strtok(NULL, ",")) {
            const wvol_filter *f;
            wvol_error err;
            double tf = 1e30, ti_ = 1e30, maxerr = 0;
            if (wvol_filter_get(&f, name, &err) != WVOL_OK) {
                fprintf(stderr, "bench_dwt: %s\n", err.message);
                return 1;
            }
            omp_set_num_threads(thr[ti]);
            for (int r = 0; r < reps; r++) {
                memcpy(work, orig, count * sizeof *work);
                double t0 = now();
                if (wvol_dwt3_inplace_f32(work, n, n, n, f, levels, &err) != WVOL_OK) return 1;
                double t1 = now();
                if (wvol_idwt3_inplace_f32(work, n, n, n, f, levels, &err) != WVOL_OK) return 1;
                double t2 = now();
                if (t1 - t0 < tf) tf = t1 - t0;
                if (t2 - t1 < ti_) ti_ = t2 - t1;
            }
            for (size_t i = 0; i < count; i++) {
                double d = (double)work[i] - orig[i];
                if (d < 0) d = -d;
                if (d > maxerr) maxerr = d;
            }
            printf(",\n  {\"what\": \"wvol\", \"wavelet\": \"%s\", \"threads\": %d, \"forward\": %.6g, \"inverse\": %.6g, "
                   "\"max_error\": %.3g}",
                   name, thr[ti], tf, ti_, maxerr);
            fflush(stdout);
        }
    }
    printf("\n]}\n");
    free(orig);
    free(work);
    return 0;
}
