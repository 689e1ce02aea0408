/* SPDX-License-Identifier: MIT */
/* 1D periodic single-level analysis and synthesis in double: the reference form of
 * DESIGN.md section 4 (a[k] = sum_n h[n] x[(2k+n) mod N]; synthesis is the transpose). */
#include <string.h>

#include "wavelet/wavelet_internal.h"

void wvol_dwt1(double *out, const double *x, size_t n, const wvol_filter *f)
{
    size_t half = n / 2;
    if (!out || !x || !f || n < 2 || (n & 1)) return;
    for (size_t k = 0; k < half; k++) {
        double a = 0.0, d = 0.0;
        for (int m = 0; m < f->length; m++) {
            double v = x[(2 * k + (size_t)m) % n];
            a += f->h[m] * v;
            d += f->g[m] * v;
        }
        out[k] = a;
        out[half + k] = d;
    }
}

void wvol_idwt1(double *out, const double *ad, size_t n, const wvol_filter *f)
{
    size_t half = n / 2;
    if (!out || !ad || !f || n < 2 || (n & 1)) return;
    memset(out, 0, n * sizeof *out);
    for (size_t k = 0; k < half; k++)
        for (int m = 0; m < f->length; m++)
            out[(2 * k + (size_t)m) % n] += f->h[m] * ad[k] + f->g[m] * ad[half + k];
}
