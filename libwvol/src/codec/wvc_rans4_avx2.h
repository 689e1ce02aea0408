/* SPDX-License-Identifier: MIT
 * Chunk mode 4's eight-lane helpers (AVX2), shared by its encoder (wvc_rans4_enc.c) and its
 * decoder's engine (wvc_rans4_dec.c). Defines R4_HAVE_AVX2 where the compiler can target
 * AVX2; the functions are compiled for it whatever the build's own -march, and run only after
 * r4_cpu_avx2() said yes. Not installed. */
#ifndef WVOL_CODEC_WVC_RANS4_AVX2_H
#define WVOL_CODEC_WVC_RANS4_AVX2_H

#include <stdint.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define R4_HAVE_AVX2 1
#define R4_AVX2 __attribute__((target("avx2,bmi,bmi2,popcnt")))
#define R4_AVX2_INLINE static inline __attribute__((always_inline, target("avx2,bmi,bmi2,popcnt")))

/* The CPU's features, as libgcc's (or compiler-rt's) constructor found them: read only. */
static inline int r4_cpu_avx2(void)
{
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("popcnt");
}

/* |v| capped at 65535 (the neighbour sums' term) */
R4_AVX2_INLINE __m256i r4v_abs16(__m256i v) { return _mm256_min_epu32(_mm256_abs_epi32(v), _mm256_set1_epi32(65535)); }
/* lanes i -> i - 1 (lane 0 from p's lane 7) and i -> i + 1 (lane 7 from n's lane 0) */
R4_AVX2_INLINE __m256i r4v_left(__m256i v, __m256i p)
{
    return _mm256_permutevar8x32_epi32(_mm256_blend_epi32(v, p, 0x80), _mm256_setr_epi32(7, 0, 1, 2, 3, 4, 5, 6));
}
R4_AVX2_INLINE __m256i r4v_right(__m256i v, __m256i n)
{
    return _mm256_permutevar8x32_epi32(_mm256_blend_epi32(v, n, 0x01), _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 0));
}
/* (v > 0) + 2 (v < 0) */
R4_AVX2_INLINE __m256i r4v_sgn3(__m256i v)
{
    const __m256i z = _mm256_setzero_si256();
    return _mm256_sub_epi32(_mm256_sub_epi32(z, _mm256_cmpgt_epi32(v, z)),
                            _mm256_add_epi32(_mm256_cmpgt_epi32(z, v), _mm256_cmpgt_epi32(z, v)));
}
/* the low bytes of the eight lanes to d[0..7] */
R4_AVX2_INLINE void r4v_bytes(uint8_t *d, __m256i v)
{
    const __m256i sh = _mm256_setr_epi8(0, 4, 8, 12, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0, 4, 8, 12, -1,
                                        -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1);
    v = _mm256_permutevar8x32_epi32(_mm256_shuffle_epi8(v, sh), _mm256_setr_epi32(0, 4, 1, 1, 1, 1, 1, 1));
    _mm_storel_epi64((__m128i *)d, _mm256_castsi256_si128(v));
}
/* the parent classes (0, 1, 2-3, >= 4 of |parent|) of eight lanes whose parents are the four
 * values at pr, each serving two lanes */
R4_AVX2_INLINE __m256i r4v_parent_class(const int32_t *pr)
{
    const __m256i zero = _mm256_setzero_si256(), one = _mm256_set1_epi32(1);
    const __m256i a = _mm256_abs_epi32(_mm256_permutevar8x32_epi32(
        _mm256_castsi128_si256(_mm_loadu_si128((const __m128i *)pr)), _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3)));
    return _mm256_sub_epi32(_mm256_sub_epi32(zero, _mm256_cmpgt_epi32(a, zero)),
                            _mm256_add_epi32(_mm256_cmpgt_epi32(a, one), _mm256_cmpgt_epi32(a, _mm256_set1_epi32(3))));
}
/* lane 0 replaced by s0 */
R4_AVX2_INLINE __m256i r4v_set0(__m256i X, uint32_t s0)
{
    return _mm256_blend_epi32(X, _mm256_castsi128_si256(_mm_cvtsi32_si128((int)s0)), 1);
}
#endif

#endif
