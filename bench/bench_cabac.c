/* SPDX-License-Identifier: MIT
 * The CABAC band coder (chunk mode 2's engine and context model) by itself, in process:
 * the quantised coefficients of a .wvc file (its decoded values divided by the step and
 * truncated, which gives back |q| for reconstruction offsets below one step) coded level
 * by level, each level's seven detail bands as one stream with block flags, as a chunk
 * of chunk mode 2 is coded, then decoded into a zeroed pyramid. Prints one JSON line:
 * coefficients, bytes, a checksum of the coded bytes (equal across builds that code
 * identically), the best encode and decode seconds over the repetitions and whether
 * every decoded detail coefficient equals the coded one. No file I/O or page faults in
 * the timed part (the decode target is zeroed before each repetition, outside the timer).
 *   bench_cabac FILE.wvc [REPS]
 * Uses the codec's internal interface (codec/wvc_internal.h): a benchmark of the coder,
 * not of the library's API. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "codec/wvc_internal.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    wvol_coeffs *c = NULL;
    wvol_wvc_info I;
    wvol_error err;
    wvol_wvc_read_options o;
    wvc_layout L;
    int reps = argc > 2 ? atoi(argv[2]) : 5, bad = 0;
    double te = INFINITY, td = INFINITY;
    size_t bytes = 0, n;
    uint64_t coefs = 0, nonzero = 0, sum = 0;
    int32_t *Q, *D;
    if (argc < 2 || reps < 1) {
        fprintf(stderr, "usage: bench_cabac FILE.wvc [REPS]\n");
        return 2;
    }
    wvol_wvc_read_options_default(&o);
    if (wvol_wvc_read(&c, argv[1], &o, &I, &err) != WVOL_OK || I.step <= 0) {
        fprintf(stderr, "bench_cabac: %s\n", I.step <= 0 ? "no quantiser step" : err.message);
        return 1;
    }
    n = c->px * c->py * c->pz;
    Q = malloc(n * sizeof *Q);
    D = malloc(n * sizeof *D);
    if (!Q || !D) return 1;
    for (size_t i = 0; i < n; i++) {
        double a = floor(fabs((double)c->data[i]) / I.step);
        int32_t q = a > WVC_QMAX ? WVC_QMAX : (int32_t)a;
        Q[i] = c->data[i] < 0 ? -q : q;
    }
    wvol__wvc_layout(&L, c->px, c->py, c->pz, c->levels);
    for (int r = 0; r < reps; r++) {
        double e = 0, d = 0;
        memset(D, 0, n * sizeof *D);
        bytes = 0, coefs = 0, nonzero = 0, sum = 0;
        for (int s0 = 1; s0 + 7 <= L.nsec; s0 += 7) { /* levels coarse to fine: parents first */
            int32_t *Qs[7], *Ds[7];
            const size_t *Ps[7];
            const wvc_band *Bs[7];
            uint8_t *buf;
            size_t sz;
            uint64_t nz;
            const char *why = NULL;
            double t0;
            for (int k = 0; k < 7; k++) Qs[k] = Q, Ds[k] = D, Ps[k] = L.p, Bs[k] = &L.sec[s0 + k], coefs += L.sec[s0 + k].count;
            t0 = now();
            if (wvol__wvc_cabac_encode_multi(&buf, &sz, 7, Qs, Ps, Bs, 1)) return 1;
            e += now() - t0;
            bytes += sz;
            for (size_t i = 0; i < sz; i++) sum = sum * 131 + buf[i];
            t0 = now();
            if (wvol__wvc_cabac_decode_multi(7, Ds, Ps, Bs, buf, sz, 1, &nz, &why)) {
                fprintf(stderr, "bench_cabac: decode: %s\n", why);
                return 1;
            }
            d += now() - t0;
            nonzero += nz;
            free(buf);
        }
        te = e < te ? e : te;
        td = d < td ? d : td;
    }
    for (int s = 1; s < L.nsec; s++) {
        const wvc_band *b = &L.sec[s];
        for (size_t z = 0; z < b->ext[2]; z++)
            for (size_t y = 0; y < b->ext[1]; y++) {
                size_t at = wvc_index(L.p, b, 0, y, z);
                bad |= memcmp(Q + at, D + at, b->ext[0] * sizeof *Q) != 0;
            }
    }
    printf("{\"file\":\"%s\",\"coefficients\":%llu,\"nonzero\":%llu,\"bytes\":%zu,\"checksum\":\"%016llx\","
           "\"encode_s\":%.5f,\"decode_s\":%.5f,\"encode_mcoef_s\":%.1f,\"decode_mcoef_s\":%.1f,\"roundtrip\":%s}\n",
           argv[1], (unsigned long long)coefs, (unsigned long long)nonzero, bytes, (unsigned long long)sum, te, td,
           (double)coefs / te / 1e6, (double)coefs / td / 1e6, bad ? "false" : "true");
    free(Q);
    free(D);
    wvol_coeffs_destroy(c);
    return bad;
}
