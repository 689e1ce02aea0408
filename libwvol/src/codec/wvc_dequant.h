/* SPDX-License-Identifier: MIT
 * The .wvc dequantiser's arithmetic, shared by the whole-file decoder (wvc_decode.c) and
 * the chunk readers (wvc2_file.c, wvc2_piece.c), so that every path gives the same bits
 * (not installed).
 *
 * A quantised value q becomes sign(q) (|q| + d2) step for |q| >= 2, sign(q) o1 for |q| = 1
 * (o1 = (1 + delta1) step) and +0 for 0: computed in double and rounded once to float, so the
 * only error beyond the quantiser's is half an ulp. Eight values at a time in explicit
 * vectors (|q| widened to double in two halves, the selects done on the float bits); the same
 * operations as the scalar form wvc_dequant1, hence the same bits wherever d2 >= -1 (which a
 * version-2 band table enforces). Neither checks a value: the whole-file decoder uses them
 * only for a section whose constants pass wvc_dequant_fits (no |q| < 2^31 then gives a value
 * beyond float32), and keeps its checked form, which refuses such a value, for the others (a
 * crafted file's constants); the chunk readers take them as they are (a value beyond float32
 * becomes inf). */
#ifndef WVOL_CODEC_WVC_DEQUANT_H
#define WVOL_CODEC_WVC_DEQUANT_H

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef int32_t wvc_dq_i8 __attribute__((vector_size(32)));
typedef int32_t wvc_dq_i4 __attribute__((vector_size(16)));
typedef float wvc_dq_f8 __attribute__((vector_size(32)));
typedef float wvc_dq_f4 __attribute__((vector_size(16)));
typedef double wvc_dq_d4 __attribute__((vector_size(32)));

/* Whether a section's constants allow the unchecked form: finite, step > 0, o1 >= 0 and
 * within float32, d2 >= -1 (|q| + d2 > 0 for |q| >= 2), and (2^31 + d2) step <= FLT_MAX. */
static inline int wvc_dequant_fits(double o1, double d2, double step)
{
    return isfinite(o1) && isfinite(d2) && isfinite(step) && step > 0 && o1 >= 0 && o1 <= FLT_MAX && d2 >= -1.0 &&
           (2147483648.0 + d2) * step <= FLT_MAX;
}

/* One value (the tails of the vector loops). */
static inline __attribute__((always_inline)) float wvc_dequant1(int32_t v, float f1, double d2, double step)
{
    const float big = (float)((fabs((double)v) + d2) * step);
    const float a = v == 0 ? 0.0f : (v == 1 || v == -1) ? f1 : big;
    return v < 0 ? -a : a;
}

/* Eight values from src (int32) into dst (may be src: all are read first); each lane of *nz
 * counts its non-zero values. |q| never INT32_MIN (the coders bound it far below). Vectors
 * pass through memory, not by value (no vector ABI in the baseline clone). */
static inline __attribute__((always_inline)) void wvc_dequant8(float *dst, const void *src, float f1, double d2,
                                                                double step, wvc_dq_i8 *nz)
{
    wvc_dq_i8 q, m, a, one, zero, bits;
    wvc_dq_i4 alo, ahi;
    wvc_dq_d4 dlo, dhi;
    wvc_dq_f4 flo, fhi;
    const wvc_dq_f8 f1v = {f1, f1, f1, f1, f1, f1, f1, f1};
    memcpy(&q, src, sizeof q);
    m = q >> 31, a = (q ^ m) - m;
    alo = __builtin_shufflevector(a, a, 0, 1, 2, 3), ahi = __builtin_shufflevector(a, a, 4, 5, 6, 7);
    dlo = (__builtin_convertvector(alo, wvc_dq_d4) + d2) * step;
    dhi = (__builtin_convertvector(ahi, wvc_dq_d4) + d2) * step;
    flo = __builtin_convertvector(dlo, wvc_dq_f4), fhi = __builtin_convertvector(dhi, wvc_dq_f4);
    one = a == 1, zero = a == 0;
    bits = (wvc_dq_i8)__builtin_shufflevector(flo, fhi, 0, 1, 2, 3, 4, 5, 6, 7);
    bits = (bits & ~one) | ((wvc_dq_i8)f1v & one);
    bits = (bits & ~zero) | (q & (int32_t)0x80000000); /* magnitude >= 0: q's sign */
    *nz -= ~zero;                                      /* a mask lane is -1 where set */
    memcpy(dst, &bits, sizeof bits);
}

#endif
