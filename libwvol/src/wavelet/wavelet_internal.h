/* Internal declarations shared by the wavelet sources (not installed). */
#ifndef WVOL_WAVELET_INTERNAL_H
#define WVOL_WAVELET_INTERNAL_H

#include <stddef.h>
#include "wvol/wavelet.h"

/* Longest filter the engine handles (bl3 truncated at 1e-10 is well under this). */
#define WVOL__MAX_TAPS 256

/* Battle-Lemarie filter of spline order `order` (3 = cubic) from its Fourier form,
 * centred (h[K] is the centre tap), truncated where |h| < tol and renormalised to
 * sum sqrt(2). Writes *len <= cap taps; returns 0 on success, -1 if unsupported or
 * longer than cap. */
int wvol__bl_compute(int order, double tol, double *h, int cap, int *len);

/* Defect max_k |sum_n h[n] h[n+2k] - delta_k| of a low-pass filter. */
double wvol__filter_defect(const double *h, int length);

#endif
