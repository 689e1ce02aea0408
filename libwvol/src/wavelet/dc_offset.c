/* SPDX-License-Identifier: MIT */
/* Data on a large offset through the float32 transforms (wavelet_bricks.h, "DC offset").
 *
 * A volume whose values sit far from 0 against their spread (1e4 + a signal of range 1.4)
 * loses its details in float32 arithmetic: every detail coefficient is a difference of
 * terms of the offset's magnitude, rounded to its ulp, and the inverse adds the large
 * low-pass back with the same rounding. The forward transform takes the offset out of the
 * samples first (exact where a sample lies within a factor of 2 of it) and puts it back into
 * the coarsest low-pass band as one constant, so the coefficients mean what they meant; the
 * inverse takes it out of that band again and adds it to the samples last. The offset is a
 * property of the data read first (the first z-slice), so that the in-memory and the
 * streamed transform, which reads slices in order, take the same one: the same bits. */
#include <math.h>

#include "wavelet/wavelet_internal.h"

/* an offset is taken out when it is this many times the data's spread: below it float32
 * resolves the details to within 2^-24 x 64 of the spread, and the bits stay as they were */
#define OFFSET_RATIO 64.0

/* The offset of values in [lo, hi]: their midrange when it is more than OFFSET_RATIO times their
 * spread, else 0. constant_too: a constant set's value counts (a low-pass band of one
 * coefficient); without it a constant set has none (a first slice all air keeps the bits of
 * a CT volume as they were). */
static float offset_of(double lo, double hi, int constant_too)
{
    const double mid = 0.5 * (lo + hi), spread = hi - lo;
    if (!isfinite(mid) || !(fabs(mid) > OFFSET_RATIO * spread)) return 0.0f;
    if (!(spread > 0) && !constant_too) return 0.0f;
    return (float)mid;
}

float wvol__slice_offset(const float *slice, size_t n)
{
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        lo = slice[i] < lo ? slice[i] : lo;
        hi = slice[i] > hi ? slice[i] : hi;
    }
    return n ? offset_of(lo, hi, 0) : 0.0f;
}

double wvol__dc_gain_f32(const wvol_filter *f, int levels, const size_t pad[3])
{
    double sum = 0.0, gain = 1.0;
    for (int t = 0; t < f->length; t++) sum += (double)(float)f->h[t]; /* the kernels' float taps */
    for (int a = 0; a < 3; a++)
        if (pad[a] > 1)
            for (int m = 0; m < levels; m++) gain *= sum;
    return gain;
}

/* The coarsest low-pass block's extent per axis. */
static void low_block(const size_t p[3], int levels, size_t e[3])
{
    for (int a = 0; a < 3; a++) e[a] = p[a] > 1 ? p[a] >> levels : 1;
}

void wvol__lowpass_add(float *data, const size_t p[3], int levels, double a)
{
    size_t e[3];
    low_block(p, levels, e);
    for (size_t k = 0; k < e[2]; k++)
        for (size_t j = 0; j < e[1]; j++) {
            float *row = data + p[0] * (j + p[1] * k);
            for (size_t i = 0; i < e[0]; i++) row[i] = (float)((double)row[i] + a);
        }
}

float wvol__lowpass_offset(const float *data, const size_t p[3], int levels)
{
    size_t e[3];
    double lo = INFINITY, hi = -INFINITY;
    low_block(p, levels, e);
    for (size_t k = 0; k < e[2]; k++)
        for (size_t j = 0; j < e[1]; j++) {
            const float *row = data + p[0] * (j + p[1] * k);
            for (size_t i = 0; i < e[0]; i++) {
                lo = row[i] < lo ? row[i] : lo;
                hi = row[i] > hi ? row[i] : hi;
            }
        }
    return offset_of(lo, hi, 1);
}

float wvol__band_range_offset(double lo, double hi) { return offset_of(lo, hi, 1); }

/* float32's spacing at |x| (its ulp), as a double */
static double f32_spacing(double x)
{
    x = fabs(x);
    return x > 0 ? ldexp(1.0, ilogb(x) - 23) : 0.0;
}

double wvol__f32_floor_sse(double mag, double voxels, const wvol_filter *f, int levels, const size_t pad[3])
{
    const double low = mag * wvol__dc_gain_f32(f, levels, pad);
    double nlow = 1.0;
    for (int a = 0; a < 3; a++)
        if (pad[a] > 1) nlow *= (double)(pad[a] >> levels);
    return voxels * f32_spacing(mag) * f32_spacing(mag) / 12.0 + nlow * 0.25 * f32_spacing(low) * f32_spacing(low);
}
