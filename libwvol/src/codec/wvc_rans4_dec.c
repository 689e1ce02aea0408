/* SPDX-License-Identifier: MIT
 * Chunk mode 4's decoder (docs/wvc-format.md, "Chunk mode 4"). A scalar decoder, every state
 * in a register, and where the CPU has AVX2 (and the band's rows are whole vectors of 8) an
 * engine over the same stream: eight magnitude steps per vector (the table entries by a
 * gather, the renormalisation's words by a permutation indexed by the mask of the lanes that
 * take one, as in Giesen's SIMD rANS; the raw bits by a gather at their prefix-summed
 * offsets), a group's modelled signs eight per vector, a row's contexts in one vector pass.
 * The payload is read in place. A row reads up to a row's worth past the stream positions
 * without a test (a word per renormalisation, a 16-byte load of words, 8 bytes of raw bits
 * per step, the engine's gathers up to 36 bytes on); a row starts only while that much of the
 * buffer remains after both positions. When a position comes that close to the payload's end,
 * its stream is read from then on from a copy of the payload's last bytes followed by as many
 * zeros (a few hundred bytes), so every row has room. Each row ends with the checks of the
 * positions and of the magnitudes' range, so a damaged stream stops within a row. */
#include <stdlib.h>
#include <string.h>

#include "core/clones.h"
#include "rans_common.h"
#include "wvc_rans4.h"
#include "wvc_rans4_avx2.h"

#define FORCE_INLINE static inline __attribute__((always_inline))
/* a table entry: symbol | frequency << 6 | (slot - cumulative frequency) << 17 */
#define R4_FSHIFT 6
#define R4_OSHIFT (7 + R4_PBITS)

/* A magnitude symbol's base value and raw-bit mask (mask << 32), and its raw-bit count.
 * Symbol 63 is what an unused context's table gives: a magnitude out of range, which the
 * row's range check refuses (no test in the step). */
#define R4_SK(s) ((s) >= R4_NS ? 0u : (uint32_t)((s) >> 1) - ((s) > 1 ? 1u : 0u))
#define R4_SB(s) ((s) == 63 ? 0x7FFFFFFFu : (s) >= R4_NS ? 0u : (s) < 2 ? (uint32_t)(s) : (2u | ((s)&1u)) << R4_SK(s))
#define R4_ST(s) (R4_SB(s) | (uint64_t)((1u << R4_SK(s)) - 1) << 32)
#define R4_X4(F, s) F(s), F(s + 1), F(s + 2), F(s + 3)
#define R4_X16(F, s) R4_X4(F, s), R4_X4(F, s + 4), R4_X4(F, s + 8), R4_X4(F, s + 12)
#define R4_X64(F, s) R4_X16(F, s), R4_X16(F, s + 16), R4_X16(F, s + 32), R4_X16(F, s + 48)
#define R4_X256(F, s) R4_X64(F, s), R4_X64(F, s + 64), R4_X64(F, s + 128), R4_X64(F, s + 192)
static const uint64_t r4_symtab[64] = {R4_X64(R4_ST, 0)};
static const uint8_t r4_symraw[64] = {R4_X64(R4_SK, 0)};
/* an unused context's table: symbol 63 by an identity step at every slot */
#define R4_ID(k) (63u | R4_M << R4_FSHIFT | (uint32_t)(k) << R4_OSHIFT)
static const uint32_t r4_unused[R4_M] = {R4_X256(R4_ID, 0), R4_X256(R4_ID, 256), R4_X256(R4_ID, 512),
                                         R4_X256(R4_ID, 768)};

typedef struct r4_dec {
    const uint32_t *flat; /* R4_NC tables of R4_M entries */
    uint32_t GF[R4_NG], SF[R4_NSGW + 1], RF[R4_NR];
    uint8_t *rnz;       /* the band's row flags */
    const uint8_t *w;   /* the 16-bit words (little-endian, any alignment): in the payload or its tail's copy */
    const uint8_t *raw; /* the raw bits, after the words, to the payload's end; or in the copy */
    size_t nw, nraw;
    size_t wrow, rrow;   /* bytes a row may read past the word and raw positions */
    size_t wspan, rspan; /* bytes readable from w and raw */
} r4_dec;

/* Where a band's decoding stands: the next row (y fastest), the word and raw-bit positions,
 * the non-zeros so far, the last parent row's flag. */
typedef struct r4_pos {
    size_t row, ps;
    uint64_t bits, nzc;
    uint32_t plast;
} r4_pos;

/* Whether a row may start here (ps <= nw and bits <= 8 nraw: each row ends checked). */
static inline int r4_room(const r4_dec *D, size_t ps, uint64_t bits)
{
    return 2 * ps + D->wrow <= D->wspan && (size_t)(bits >> 3) + D->rrow <= D->rspan;
}

FORCE_INLINE uint32_t r4_word(const r4_dec *D, size_t pos)
{
    uint16_t v;
    memcpy(&v, D->w + 2 * pos, 2);
    return v;
}

/* the 64 raw bits from bit bp on */
FORCE_INLINE uint64_t r4_raw64(const r4_dec *D, uint64_t bp)
{
    uint64_t v;
    memcpy(&v, D->raw + (bp >> 3), 8);
    return v >> (bp & 7);
}

/* A binary step: bit out, state updated (renormalised by the caller). */
FORCE_INLINE uint32_t r4_bin(uint32_t *x, uint32_t f0)
{
    const uint32_t slot = *x & (R4_M - 1), bit = slot >= f0, m = 0u - bit;
    *x = (f0 ^ ((f0 ^ (R4_M - f0)) & m)) * (*x >> R4_PBITS) + slot - (f0 & m);
    return bit;
}

FORCE_INLINE uint32_t r4_renorm(uint32_t x, const r4_dec *D, size_t *pos)
{
    const uint32_t r = x < R4_L;
    const uint32_t v = r4_word(D, *pos);
    *pos += r;
    return (x << (r << 4)) | (v & (0u - r));
}

/* One coefficient on state *x: magnitude, raw bits, raw sign; with modelled signs bit i of *m
 * marks a non-zero (its sign follows the group's magnitudes). */
FORCE_INLINE void r4_coef(const r4_dec *D, uint32_t *x, size_t *pos, uint64_t *bp, int32_t *c, uint32_t cx,
                          int raw_signs, uint64_t *nzc, uint32_t *over, uint32_t *m, int i)
{
    const uint32_t e = D->flat[cx * R4_M + (*x & (R4_M - 1))];
    const uint32_t s = e & 63, nz = s != 0, k = r4_symraw[s];
    const uint64_t st = r4_symtab[s], word = r4_raw64(D, *bp);
    uint32_t a, neg = 0;
    *x = (e >> R4_FSHIFT & (2 * R4_M - 1)) * (*x >> R4_PBITS) + (e >> R4_OSHIFT);
    *x = r4_renorm(*x, D, pos);
    a = (uint32_t)st | ((uint32_t)word & (uint32_t)(st >> 32));
    if (raw_signs) {
        neg = (uint32_t)(word >> k) & nz;
        *bp += k + nz;
    } else {
        *bp += k;
        *m |= nz << i;
    }
    *c = (int32_t)((a ^ (0u - neg)) + neg);
    *nzc += nz;
    *over |= a > WVC_QMAX;
}

/* Row (y, z)'s flag on state *s0, recorded for the rows after it. */
FORCE_INLINE uint32_t r4_row_flag(const r4_dec *D, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                                  size_t z, uint32_t *plast, uint32_t *s0, size_t *ps)
{
    const uint32_t rowz = r4_bin(s0, D->RF[r4_row_ctx(D->rnz, Q, p, b, y, z, plast)]);
    *s0 = r4_renorm(*s0, D, ps);
    D->rnz[z * b->ext[1] + y] = (uint8_t)rowz;
    return rowz;
}

/* The row's end checks: magnitudes in range (an unused context's symbol is not), positions
 * within the streams. */
static int r4_row_bad(const r4_dec *D, int over, size_t ps, uint64_t bits, const char **why)
{
    if (!over && ps <= D->nw && bits <= 8 * (uint64_t)D->nraw) return 0;
    *why = over ? "mode-4 magnitude out of range or a context without a table" : "mode-4 coded data ends early";
    return 1;
}

#define R4_COEF(SP, X) \
    r4_coef(D, SP, &S.ps, &S.bits, c + (X), w->CX[X], raw_signs, &S.nzc, &over, &m, (int)((X)-g0))
/* the sign of the next non-zero of mask m (coefficients g0 ..) on state TV */
#define R4_SIGN(TV)                                                                            \
    do {                                                                                       \
        const int i_ = __builtin_ctz(m);                                                       \
        const uint32_t neg_ = r4_bin(&TV, D->SF[w->SG[g0 + (size_t)i_]]);                      \
        TV = r4_renorm(TV, D, &S.ps);                                                            \
        m &= m - 1;                                                                            \
        c[g0 + (size_t)i_] = (int32_t)(((uint32_t)c[g0 + (size_t)i_] ^ (0u - neg_)) + neg_);   \
    } while (0)
#define R4_SIGNS4(A, B, C, D_) \
    R4_SIGN(A);                \
    if (!m) break;             \
    R4_SIGN(B);                \
    if (!m) break;             \
    R4_SIGN(C);                \
    if (!m) break;             \
    R4_SIGN(D_)

/* The scalar decoder of one band from row P->row on; it stops before a row without room for
 * its reads (P->row says where). States stay in registers: every access names its variable.
 * Returns 0, or -1 with *why. */
FORCE_INLINE int r4_band(const r4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const r4_row *w,
                         const int32_t *zrow, int raw_signs, uint32_t xs[R4_NX], r4_pos *P, const char **why)
{
    const size_t ex = b->ext[0], ey = b->ext[1], rows = ey * b->ext[2], ng = (ex + R4_GROUP - 1) / R4_GROUP;
    uint32_t s0 = xs[0], s1 = xs[1], s2 = xs[2], s3 = xs[3], s4 = xs[4], s5 = xs[5], s6 = xs[6], s7 = xs[7];
    uint32_t s8 = xs[8], s9 = xs[9], s10 = xs[10], s11 = xs[11], s12 = xs[12], s13 = xs[13], s14 = xs[14], s15 = xs[15];
    uint32_t t0 = xs[R4_TS], t1 = xs[R4_TS + 1], t2 = xs[R4_TS + 2], t3 = xs[R4_TS + 3];
    uint32_t t4 = xs[R4_TS + 4], t5 = xs[R4_TS + 5], t6 = xs[R4_TS + 6], t7 = xs[R4_TS + 7];
    r4_pos S = *P; /* a local copy, in registers */
    int r = 0;
    for (; S.row < rows; S.row++) {
        const size_t y = S.row % ey, z = S.row / ey;
        int32_t *c = Q + wvc_index(p, b, 0, y, z);
        uint32_t over = 0, any = 0, m;
        if (!r4_room(D, S.ps, S.bits)) break;
        if (!r4_row_flag(D, Q, p, b, y, z, &S.plast, &s0, &S.ps)) {
            if (r4_row_bad(D, 0, S.ps, S.bits, why)) {
                r = -1;
                break;
            }
            continue;
        }
        wvol__wvc_rans4_row_prep(w, Q, p, b, y, z, zrow, !raw_signs);
        for (size_t g = 0, g0 = 0; g0 < ex; g++, g0 += R4_GROUP) {
            const size_t g1 = g0 + R4_GROUP < ex ? g0 + R4_GROUP : ex;
            uint32_t nz = 1;
            if (ng > 1 && (g + 1 < ng || any)) {
                nz = r4_bin(&s0, D->GF[w->GX[g]]);
                s0 = r4_renorm(s0, D, &S.ps);
            }
            any |= nz;
            if (!nz) continue;
            m = 0;
            if (g1 - g0 == R4_GROUP) {
                const size_t x = g0;
                R4_COEF(&s0, x), R4_COEF(&s1, x + 1), R4_COEF(&s2, x + 2), R4_COEF(&s3, x + 3);
                R4_COEF(&s4, x + 4), R4_COEF(&s5, x + 5), R4_COEF(&s6, x + 6), R4_COEF(&s7, x + 7);
                R4_COEF(&s8, x + 8), R4_COEF(&s9, x + 9), R4_COEF(&s10, x + 10), R4_COEF(&s11, x + 11);
                R4_COEF(&s12, x + 12), R4_COEF(&s13, x + 13), R4_COEF(&s14, x + 14), R4_COEF(&s15, x + 15);
            } else {
                for (size_t x = g0; x < g1; x++) switch (x & (R4_STATES - 1)) {
                    case 0: R4_COEF(&s0, x); break;
                    case 1: R4_COEF(&s1, x); break;
                    case 2: R4_COEF(&s2, x); break;
                    case 3: R4_COEF(&s3, x); break;
                    case 4: R4_COEF(&s4, x); break;
                    case 5: R4_COEF(&s5, x); break;
                    case 6: R4_COEF(&s6, x); break;
                    case 7: R4_COEF(&s7, x); break;
                    case 8: R4_COEF(&s8, x); break;
                    case 9: R4_COEF(&s9, x); break;
                    case 10: R4_COEF(&s10, x); break;
                    case 11: R4_COEF(&s11, x); break;
                    case 12: R4_COEF(&s12, x); break;
                    case 13: R4_COEF(&s13, x); break;
                    case 14: R4_COEF(&s14, x); break;
                    default: R4_COEF(&s15, x); break;
                    }
            }
            if (!raw_signs)
                while (m) {
                    R4_SIGNS4(t0, t1, t2, t3);
                    if (!m) break;
                    R4_SIGNS4(t4, t5, t6, t7);
                }
        }
        if (r4_row_bad(D, over != 0, S.ps, S.bits, why)) {
            r = -1;
            break;
        }
    }
    xs[0] = s0, xs[1] = s1, xs[2] = s2, xs[3] = s3, xs[4] = s4, xs[5] = s5, xs[6] = s6, xs[7] = s7;
    xs[8] = s8, xs[9] = s9, xs[10] = s10, xs[11] = s11, xs[12] = s12, xs[13] = s13, xs[14] = s14, xs[15] = s15;
    xs[R4_TS] = t0, xs[R4_TS + 1] = t1, xs[R4_TS + 2] = t2, xs[R4_TS + 3] = t3;
    xs[R4_TS + 4] = t4, xs[R4_TS + 5] = t5, xs[R4_TS + 6] = t6, xs[R4_TS + 7] = t7;
    *P = S;
    return r;
}

typedef int (*r4_band_fn)(const r4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const r4_row *w,
                          const int32_t *zrow, uint32_t xs[R4_NX], r4_pos *P, const char **why);

#define R4_BAND_SCALAR(NAME, RAW)                                                                            \
    WVOL__CLONES static int NAME(const r4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b,          \
                                 const r4_row *w, const int32_t *zrow, uint32_t xs[R4_NX], r4_pos *P,        \
                                 const char **why)                                                           \
    {                                                                                                        \
        return r4_band(D, Q, p, b, w, zrow, RAW, xs, P, why);                                                \
    }
R4_BAND_SCALAR(r4_band_raw, 1)
R4_BAND_SCALAR(r4_band_sgn, 0)

#ifdef R4_HAVE_AVX2

/* For a renormalisation mask (bit i: lane i takes a word): lane i's word is the
 * popcount(mask below i)-th of the words read in lane order. */
#define R4_PC3(v) (((v)&1) + ((v) >> 1 & 1) + ((v) >> 2 & 1))
#define R4_PC7(v) (R4_PC3(v) + R4_PC3((v) >> 3) + ((v) >> 6 & 1))
#define R4_PERM(mk)                                                                                             \
    {                                                                                                           \
        0, R4_PC7((mk)&1), R4_PC7((mk)&3), R4_PC7((mk)&7), R4_PC7((mk)&15), R4_PC7((mk)&31), R4_PC7((mk)&63), \
            R4_PC7((mk)&127)                                                                                    \
    }
static const uint32_t r4_perm[256][8] __attribute__((aligned(32))) = {R4_X64(R4_PERM, 0), R4_X64(R4_PERM, 64),
                                                                       R4_X64(R4_PERM, 128), R4_X64(R4_PERM, 192)};

/* The low 32 bits at bit offsets OFF (lanes) from base, for counts up to 57 - 7 bits. */
R4_AVX2_INLINE __m256i r4v_bits64(const uint8_t *base, __m256i OFF)
{
    const __m256i by = _mm256_srli_epi32(OFF, 3), sh = _mm256_and_si256(OFF, _mm256_set1_epi32(7));
    const __m256i pick = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
    __m256i q0 = _mm256_i32gather_epi64((const long long *)base, _mm256_castsi256_si128(by), 1);
    __m256i q1 = _mm256_i32gather_epi64((const long long *)base, _mm256_extracti128_si256(by, 1), 1);
    q0 = _mm256_srlv_epi64(q0, _mm256_cvtepu32_epi64(_mm256_castsi256_si128(sh)));
    q1 = _mm256_srlv_epi64(q1, _mm256_cvtepu32_epi64(_mm256_extracti128_si256(sh, 1)));
    return _mm256_blend_epi32(_mm256_permutevar8x32_epi32(q0, pick), _mm256_permutevar8x32_epi32(q1, pick), 0xF0);
}

/* Eight coefficients c[0..7] on the states of *X, contexts cx[0..7]: magnitudes (and raw signs)
 * stored; returns the mask of the non-zeros. *amax: the largest magnitude so far. The lanes
 * renormalise in lane order, the scalar decoder's. */
R4_AVX2_INLINE uint32_t r4v_eight(const r4_dec *D, __m256i *X, const uint8_t *cx, size_t *pos, uint64_t *bits,
                                  int32_t *c, int raw_signs, __m256i *amax)
{
    const __m256i one = _mm256_set1_epi32(1), zero = _mm256_setzero_si256();
    const __m256i C = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)cx));
    __m256i x = *X, E, S, F, R, Wd, NZ, K, Bs, L, P, OFF, Wr, A;
    const uint8_t *base;
    uint32_t rm;
    E = _mm256_i32gather_epi32(
        (const int *)D->flat,
        _mm256_or_si256(_mm256_slli_epi32(C, R4_PBITS), _mm256_and_si256(x, _mm256_set1_epi32(R4_M - 1))), 4);
    S = _mm256_and_si256(E, _mm256_set1_epi32(63));
    F = _mm256_and_si256(_mm256_srli_epi32(E, R4_FSHIFT), _mm256_set1_epi32(2 * R4_M - 1));
    x = _mm256_add_epi32(_mm256_mullo_epi32(F, _mm256_srli_epi32(x, R4_PBITS)), _mm256_srli_epi32(E, R4_OSHIFT));
    R = _mm256_cmpeq_epi32(_mm256_srli_epi32(x, 16), zero); /* x < 2^16 */
    rm = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(R));
    Wd = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(D->w + 2 * *pos)));
    Wd = _mm256_permutevar8x32_epi32(Wd, _mm256_load_si256((const __m256i *)r4_perm[rm]));
    *X = _mm256_blendv_epi8(x, _mm256_or_si256(_mm256_slli_epi32(x, 16), Wd), R);
    *pos += (size_t)_mm_popcnt_u32(rm);
    /* symbol s: 0, 1, or 2n + b: raw bits k = s / 2 - 1, base (2 + b) << k (symbol 63 gives
     * 3 << 30, out of range) */
    NZ = _mm256_cmpgt_epi32(S, zero);
    K = _mm256_max_epi32(_mm256_sub_epi32(_mm256_srli_epi32(S, 1), one), zero);
    Bs = _mm256_sllv_epi32(
        _mm256_or_si256(_mm256_and_si256(S, one), _mm256_and_si256(_mm256_cmpgt_epi32(S, one), _mm256_set1_epi32(2))),
        K);
    L = raw_signs ? _mm256_sub_epi32(K, NZ) : K; /* the sign bit after a non-zero's raw bits */
    P = _mm256_add_epi32(L, _mm256_slli_si256(L, 4));
    P = _mm256_add_epi32(P, _mm256_slli_si256(P, 8));
    P = _mm256_add_epi32(P, _mm256_blend_epi32(zero, _mm256_permutevar8x32_epi32(P, _mm256_set1_epi32(3)), 0xF0));
    OFF = _mm256_add_epi32(_mm256_sub_epi32(P, L), _mm256_set1_epi32((int)(*bits & 7)));
    base = D->raw + (*bits >> 3);
    if (__builtin_expect(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(L, _mm256_set1_epi32(25)))) == 0, 1))
        Wr = _mm256_srlv_epi32(_mm256_i32gather_epi32((const int *)base, _mm256_srli_epi32(OFF, 3), 1),
                               _mm256_and_si256(OFF, _mm256_set1_epi32(7)));
    else /* more than 32 - 7 bits in a lane */
        Wr = r4v_bits64(base, OFF);
    A = _mm256_or_si256(Bs, _mm256_and_si256(Wr, _mm256_sub_epi32(_mm256_sllv_epi32(one, K), one)));
    *amax = _mm256_max_epu32(*amax, A);
    if (raw_signs) {
        const __m256i ng =
            _mm256_sub_epi32(zero, _mm256_and_si256(_mm256_srlv_epi32(Wr, K), _mm256_and_si256(NZ, one)));
        A = _mm256_sub_epi32(_mm256_xor_si256(A, ng), ng);
    }
    _mm256_storeu_si256((__m256i *)c, A);
    *bits += (uint32_t)_mm256_extract_epi32(P, 7);
    return (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(NZ));
}

/* The modelled signs of a group's non-zeros (mask m over c[0 .. glen), glen 8 or 16) on the
 * sign states T8 (t0 .. t7), eight per step in the scalar order: the k-th non-zero on
 * t(k mod 8), renormalised in lane order. The contexts of the non-zeros packed by pext, the
 * sign bits put back on their coefficients by pdep. */
R4_AVX2_INLINE void r4v_signs8(const r4_dec *D, __m256i *T8, const uint8_t *sg, uint32_t m, int32_t *c, size_t glen,
                               size_t *pos)
{
    const uint64_t ones = 0x0101010101010101ull;
    const uint32_t mlo = m & 255, mhi = m >> 8 & 255, nlo = (uint32_t)_mm_popcnt_u32(mlo);
    const uint32_t n = nlo + (uint32_t)_mm_popcnt_u32(mhi);
    const __m256i sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    uint64_t lo, hi = 0;
    unsigned __int128 ctx;
    uint32_t sb = 0;
    __m256i x = *T8;
    memcpy(&lo, sg, 8);
    if (glen > 8) memcpy(&hi, sg + 8, 8);
    lo = _pext_u64(lo, _pdep_u64(mlo, ones) * 255);
    hi = glen > 8 ? _pext_u64(hi, _pdep_u64(mhi, ones) * 255) : 0;
    ctx = (unsigned __int128)lo | (nlo < 8 ? (unsigned __int128)hi << (8 * nlo) : (unsigned __int128)hi << 64);
    for (uint32_t k = 0; k < n; k += 8) {
        const __m256i act =
            _mm256_cmpgt_epi32(_mm256_set1_epi32((int)(n - k)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        const __m256i f0 = _mm256_i32gather_epi32(
            (const int *)D->SF, _mm256_cvtepu8_epi32(_mm_cvtsi64_si128((long long)(uint64_t)(ctx >> (8 * k)))), 4);
        const __m256i slot = _mm256_and_si256(x, _mm256_set1_epi32(R4_M - 1));
        const __m256i B = _mm256_cmpgt_epi32(slot, _mm256_sub_epi32(f0, _mm256_set1_epi32(1))); /* 1: negative */
        const __m256i fr = _mm256_blendv_epi8(f0, _mm256_sub_epi32(_mm256_set1_epi32(R4_M), f0), B);
        __m256i y = _mm256_add_epi32(_mm256_mullo_epi32(fr, _mm256_srli_epi32(x, R4_PBITS)),
                                     _mm256_sub_epi32(slot, _mm256_and_si256(f0, B)));
        const __m256i R = _mm256_and_si256(_mm256_cmpeq_epi32(_mm256_srli_epi32(y, 16), _mm256_setzero_si256()), act);
        const uint32_t rm = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(R));
        __m256i W = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(D->w + 2 * *pos)));
        W = _mm256_permutevar8x32_epi32(W, _mm256_load_si256((const __m256i *)r4_perm[rm]));
        y = _mm256_blendv_epi8(y, _mm256_or_si256(_mm256_slli_epi32(y, 16), W), R);
        x = _mm256_blendv_epi8(x, y, act);
        *pos += (size_t)_mm_popcnt_u32(rm);
        sb |= ((uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(B)) & 255u) << k;
    }
    *T8 = x;
    sb = _pdep_u32(sb & ((1u << n) - 1), m); /* n <= 16 */
    for (size_t i = 0; i < glen; i += 8) {
        const __m256i N = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32((int)(sb >> i)), sel), sel);
        const __m256i v = _mm256_loadu_si256((const __m256i *)(c + i));
        _mm256_storeu_si256((__m256i *)(c + i), _mm256_sub_epi32(_mm256_xor_si256(v, N), N));
    }
}

/* wvol__wvc_rans4_row_prep in one pass of eight-lane vectors (the same numbers, the x
 * neighbours shifted in across lanes), for extents that are multiples of 8 up to 64 whose
 * parent row is at least half as long; returns 0 (nothing done) otherwise. */
R4_AVX2_INLINE int r4v_row_prep(const r4_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                                size_t z, const int32_t *zrow, int signs)
{
    const size_t sy = p[0], sz = p[0] * p[1], ex = b->ext[0], nv = ex / 8;
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const int32_t *N = y > 0 ? c - sy : zrow, *U = z > 0 ? c - sz : zrow;
    const int32_t *UN = z > 0 && y > 0 ? c - sz - sy : zrow, *US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    const int32_t *pr = NULL;
    const __m256i zero = _mm256_setzero_si256();
    __m256i S[8], Nv[8];
    if (ex % 8 || ex > 64 || (b->has_parent && b->pext[0] < ex / 2)) return 0;
    if (z > 0 && y + 4 < b->ext[1]) /* the plane above is far back (a plane of the pyramid): fetch ahead */
        for (size_t x = 0; x < ex; x += 16) __builtin_prefetch(c - sz + 4 * sy + x);
    if (b->has_parent) pr = wvc_rans_parent_row(Q, sy, sz, b, y, z);
    for (size_t v = 0; v < nv; v++) {
        Nv[v] = _mm256_loadu_si256((const __m256i *)(N + 8 * v));
        S[v] = _mm256_add_epi32(r4v_abs16(Nv[v]), r4v_abs16(_mm256_loadu_si256((const __m256i *)(U + 8 * v))));
    }
    for (size_t v = 0; v < nv; v++) {
        const size_t x = 8 * v;
        const __m256i l = r4v_left(S[v], v ? S[v - 1] : zero), r = r4v_right(S[v], v + 1 < nv ? S[v + 1] : zero);
        __m256i A = _mm256_add_epi32(_mm256_add_epi32(_mm256_add_epi32(S[v], S[v]), _mm256_add_epi32(l, r)),
                                     _mm256_add_epi32(r4v_abs16(_mm256_loadu_si256((const __m256i *)(UN + x))),
                                                      r4v_abs16(_mm256_loadu_si256((const __m256i *)(US + x)))));
        __m256i PC = zero, n;
        _mm256_storeu_si256((__m256i *)(w->A + x), A);
        if (pr) PC = r4v_parent_class(pr + x / 2);
        r4v_bytes(w->PC + x, PC);
        /* bit length through float's exponent (A < 2^24), capped at R4_NA - 1 */
        n = _mm256_sub_epi32(_mm256_srli_epi32(_mm256_castps_si256(_mm256_cvtepi32_ps(A)), 23), _mm256_set1_epi32(126));
        n = _mm256_andnot_si256(_mm256_cmpeq_epi32(A, zero), n);
        n = _mm256_min_epi32(n, _mm256_set1_epi32(R4_NA - 1));
        r4v_bytes(w->CX + x, _mm256_add_epi32(_mm256_slli_epi32(n, 2), PC));
        if (signs) {
            const __m256i U8 = _mm256_loadu_si256((const __m256i *)(U + x));
            __m256i sg = _mm256_add_epi32(
                _mm256_set1_epi32(9 * (b->band - 1)),
                _mm256_add_epi32(_mm256_mullo_epi32(r4v_sgn3(U8), _mm256_set1_epi32(3)), r4v_sgn3(Nv[v])));
            sg = _mm256_add_epi32(sg, _mm256_mullo_epi32(r4v_sgn3(r4v_left(Nv[v], v ? Nv[v - 1] : zero)),
                                                         _mm256_set1_epi32(R4_NSG)));
            r4v_bytes(w->SG + x, sg);
        }
    }
    for (size_t g = 0; g < (ex + R4_GROUP - 1) / R4_GROUP; g++) { /* the group flags' contexts */
        const size_t x0 = R4_GROUP * g, x1 = x0 + R4_GROUP < ex ? x0 + R4_GROUP : ex;
        uint32_t s = 0, pm = 0, nb;
        for (size_t x = x0; x < x1; x++) s += w->A[x], pm |= w->PC[x];
        nb = 31 - (uint32_t)__builtin_clz(2 * s + 1);
        pm = pm > 3 ? 3 : pm;
        w->GX[g] = (uint8_t)((nb < R4_NGA - 1 ? nb : R4_NGA - 1) * R4_NP + pm);
    }
    return 1;
}

R4_AVX2_INLINE uint32_t r4v_get0(__m256i X) { return (uint32_t)_mm256_cvtsi256_si32(X); }

/* r4_band for extents that are multiples of 8: the magnitude states in
 * two registers (s0 .. s7, s8 .. s15: the halves of a group of 16), the sign states in one,
 * the flags on lane 0 (s0) taken out of the register and put back. */
R4_AVX2_INLINE int r4_band_v(const r4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const r4_row *w,
                             const int32_t *zrow, int raw_signs, uint32_t xs[R4_NX], r4_pos *P, const char **why)
{
    const size_t ex = b->ext[0], ey = b->ext[1], rows = ey * b->ext[2], ng = (ex + R4_GROUP - 1) / R4_GROUP;
    const __m256i qmax = _mm256_set1_epi32(WVC_QMAX);
    __m256i X = _mm256_loadu_si256((const __m256i *)xs), X1 = _mm256_loadu_si256((const __m256i *)(xs + 8));
    __m256i T8 = _mm256_loadu_si256((const __m256i *)(xs + R4_TS)), amax = _mm256_setzero_si256();
    r4_pos S = *P; /* a local copy, in registers */
    int r = 0;
    for (; S.row < rows; S.row++) {
        const size_t y = S.row % ey, z = S.row / ey;
        int32_t *c = Q + wvc_index(p, b, 0, y, z);
        uint32_t any = 0, m, s0 = r4v_get0(X), ok;
        if (!r4_room(D, S.ps, S.bits)) break;
        m = r4_row_flag(D, Q, p, b, y, z, &S.plast, &s0, &S.ps);
        X = r4v_set0(X, s0);
        if (!m) {
            if (r4_row_bad(D, 0, S.ps, S.bits, why)) {
                r = -1;
                break;
            }
            continue;
        }
        if (!r4v_row_prep(w, Q, p, b, y, z, zrow, !raw_signs))
            wvol__wvc_rans4_row_prep(w, Q, p, b, y, z, zrow, !raw_signs);
        for (size_t g = 0, g0 = 0; g0 < ex; g++, g0 += R4_GROUP) {
            const size_t g1 = g0 + R4_GROUP < ex ? g0 + R4_GROUP : ex;
            uint32_t nz = 1;
            if (ng > 1 && (g + 1 < ng || any)) {
                s0 = r4v_get0(X);
                nz = r4_bin(&s0, D->GF[w->GX[g]]);
                s0 = r4_renorm(s0, D, &S.ps);
                X = r4v_set0(X, s0);
            }
            any |= nz;
            if (!nz) continue;
            m = r4v_eight(D, &X, w->CX + g0, &S.ps, &S.bits, c + g0, raw_signs, &amax);
            if (g1 - g0 > 8) m |= r4v_eight(D, &X1, w->CX + g0 + 8, &S.ps, &S.bits, c + g0 + 8, raw_signs, &amax) << 8;
            S.nzc += (uint64_t)_mm_popcnt_u32(m);
            if (!raw_signs && m) r4v_signs8(D, &T8, w->SG + g0, m, c + g0, g1 - g0, &S.ps);
        }
        ok = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_max_epu32(amax, qmax), qmax)));
        if (r4_row_bad(D, ok != 0xFF, S.ps, S.bits, why)) {
            r = -1;
            break;
        }
    }
    _mm256_storeu_si256((__m256i *)xs, X);
    _mm256_storeu_si256((__m256i *)(xs + 8), X1);
    _mm256_storeu_si256((__m256i *)(xs + R4_TS), T8);
    *P = S;
    return r;
}

#define R4_BAND_AVX2(NAME, RAW)                                                                                  \
    R4_AVX2 static int NAME(const r4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const r4_row *w, \
                            const int32_t *zrow, uint32_t xs[R4_NX], r4_pos *P, const char **why)               \
    {                                                                                                            \
        return r4_band_v(D, Q, p, b, w, zrow, RAW, xs, P, why);                                                  \
    }
R4_BAND_AVX2(r4_band_avx2_raw, 1)
R4_BAND_AVX2(r4_band_avx2_sgn, 0)

#endif

/* One binary context's frequency f0 from the payload (f0 + 1; 0 for unused: f0 = 2^10, the
 * step's identity). */
static int r4_get_binary(const uint8_t *buf, size_t size, size_t *pos, uint32_t *f0)
{
    uint32_t v;
    if (wvol__wvc_rans_get_varint(buf, size, pos, &v) || v > R4_M + 1) return -1;
    *f0 = v ? v - 1 : R4_M;
    return 0;
}

/* One magnitude table into t (R4_M entries): symbol | frequency << 6 | (slot - cumulative) << 17;
 * an unused context's (ns 0) entries give symbol 63 by an identity step. The frequencies sum to
 * R4_M (checked by the callers). */
static void r4_fill_table(uint32_t *t, const uint32_t *freq, uint32_t ns)
{
    uint32_t cum = 0;
    if (!ns) {
        memcpy(t, r4_unused, sizeof r4_unused);
        return;
    }
    for (uint32_t s = 0; s < ns; s++) {
        for (uint32_t k = 0; k < freq[s]; k++) t[cum + k] = s | freq[s] << R4_FSHIFT | k << R4_OSHIFT;
        cum += freq[s];
    }
}

/* The LEB128 magnitude tables into flat (R4_NC tables). */
static int r4_get_tables(const uint8_t *buf, size_t size, size_t *pos, uint32_t *flat)
{
    uint32_t freq[R4_NS];
    for (int c = 0; c < R4_NC; c++) {
        uint32_t v, sum = 0, ns;
        if (wvol__wvc_rans_get_varint(buf, size, pos, &ns) || ns > R4_NS) return -1;
        for (uint32_t s = 0; s < ns; s++) {
            if (wvol__wvc_rans_get_varint(buf, size, pos, &v) || v > R4_M) return -1;
            freq[s] = v;
            sum += v;
        }
        if (ns && (sum != R4_M || !freq[ns - 1])) return -1;
        r4_fill_table(flat + (size_t)c * R4_M, freq, ns);
    }
    return 0;
}

/* Packed tables (wvc_rans4.h): a bit reader, most significant bit first, that refuses to read
 * past the payload. */
typedef struct r4_bitr {
    const uint8_t *p;
    size_t n, end; /* bits read, bits there are */
} r4_bitr;

static int r4_bits_get(r4_bitr *r, uint32_t len, uint32_t *v)
{
    uint32_t x = 0;
    if (len > r->end - r->n) return -1;
    for (uint32_t i = 0; i < len; i++, r->n++) x = x << 1 | (uint32_t)(r->p[r->n >> 3] >> (7 - (r->n & 7)) & 1);
    *v = x;
    return 0;
}

static int r4_eg_get(r4_bitr *r, uint32_t *v)
{
    uint32_t z = 0, b = 0, rest;
    for (;;) {
        if (r4_bits_get(r, 1, &b)) return -1;
        if (b) break;
        if (++z > R4_EG_MAXZ) return -1;
    }
    if (r4_bits_get(r, z, &rest)) return -1;
    *v = 1u << z | rest;
    return 0;
}

static int r4_get_tables_packed(r4_bitr *r, uint32_t *flat)
{
    uint32_t freq[R4_NS];
    for (int c = 0; c < R4_NC; c++) {
        uint32_t v, ns, P, sum = 0;
        if (r4_eg_get(r, &v) || v - 1 > R4_NS) return -1;
        ns = v - 1;
        if (ns) {
            if (r4_bits_get(r, R4_PFIELD, &P)) return -1;
            P += R4_PMIN;
            if (P > R4_PBITS) return -1;
            for (uint32_t s = 0; s + 1 < ns; s++) {
                if (r4_eg_get(r, &v)) return -1;
                sum += v - 1;
                if (sum >= 1u << P) return -1; /* the last frequency is at least 1 */
                freq[s] = (v - 1) << (R4_PBITS - P);
            }
            freq[ns - 1] = ((1u << P) - sum) << (R4_PBITS - P);
        }
        r4_fill_table(flat + (size_t)c * R4_M, freq, ns);
    }
    return 0;
}

static int r4_get_binary_packed(r4_bitr *r, uint32_t *f0)
{
    static const uint32_t fixed[3] = {R4_M, 0, R4_M / 2}; /* R4_BIN_ZEROS, _ONES, _HALF */
    uint32_t kind, P, f;
    if (r4_bits_get(r, R4_BKIND, &kind)) return -1;
    if (kind != R4_BIN_EXPLICIT) {
        *f0 = fixed[kind];
        return 0;
    }
    if (r4_bits_get(r, R4_BPFIELD, &P) || P < R4_BPMIN || P > R4_PBITS || r4_bits_get(r, P, &f) || !f)
        return -1; /* f0 in 1 .. 2^P - 1: P bits and not 0 */
    *f0 = f << (R4_PBITS - P);
    return 0;
}

/* One binary entry in the form the flags say: from the bit reader r (packed) or LEB128 at *pos. */
static int r4_get_entry(int packed, r4_bitr *r, const uint8_t *buf, size_t size, size_t *pos, uint32_t *f0)
{
    return packed ? r4_get_binary_packed(r, f0) : r4_get_binary(buf, size, pos, f0);
}

/* Every table and binary entry, packed or LEB128 as the flags say; *pos past them. */
static int r4_get_all_tables(r4_dec *D, uint32_t *flat, const uint8_t *buf, size_t size, size_t *pos, int packed,
                             int raw_signs)
{
    r4_bitr r = {buf + *pos, 0, 8 * (size - *pos)};
    if (packed ? r4_get_tables_packed(&r, flat) : r4_get_tables(buf, size, pos, flat)) return -1;
    for (int c = 0; c < R4_NG; c++)
        if (r4_get_entry(packed, &r, buf, size, pos, &D->GF[c])) return -1;
    for (int c = 0; c < R4_NSGW; c++)
        if (!raw_signs && r4_get_entry(packed, &r, buf, size, pos, &D->SF[c])) return -1;
    for (int c = 0; c < R4_NR; c++)
        if (r4_get_entry(packed, &r, buf, size, pos, &D->RF[c])) return -1;
    if (packed) *pos += (r.n + 7) / 8;
    return 0;
}

/* The payload's last bytes (from ts to end, at most T) and T zeros, for the rows that would
 * read past the payload's end; which streams read from it. */
typedef struct r4_tail {
    uint8_t *buf;
    const uint8_t *ts, *end;
    size_t T;
    int w, raw;
} r4_tail;

/* base's stream, read at the same positions from the copy: its address of byte ts is buf's */
static const uint8_t *r4_in_tail(const r4_tail *t, const uint8_t *base)
{
    return (const uint8_t *)((uintptr_t)t->buf - (uintptr_t)(t->ts - base));
}

/* Moves each stream without room for a row at P to the tail's copy (its position is then
 * within the payload's last T bytes, which the copy holds, and T bytes of room follow).
 * Returns -1 when none moves (a row without room after the move: not expected). */
static int r4_to_tail(r4_dec *D, const r4_pos *P, r4_tail *t)
{
    int moved = 0;
    if (!t->w && 2 * P->ps + D->wrow > D->wspan) {
        D->w = r4_in_tail(t, D->w);
        D->wspan += t->T;
        t->w = moved = 1;
    }
    if (!t->raw && (size_t)(P->bits >> 3) + D->rrow > D->rspan) {
        D->raw = r4_in_tail(t, D->raw);
        D->rspan += t->T;
        t->raw = moved = 1;
    }
    return moved ? 0 : -1;
}

int wvol__wvc_rans4_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                           const uint8_t *buf, size_t size, int engine, uint64_t *nonzero, const char **why)
{
    const size_t ex = b[0]->ext[0], ng = (ex + R4_GROUP - 1) / R4_GROUP;
    uint32_t xs[R4_NX] __attribute__((aligned(32))), nw, nraw;
    uint32_t *flat = NULL;
    r4_dec D;
    r4_row row = {0};
    int32_t *zrow = NULL;
    r4_pos P;
    size_t pos = 1 + R4_HEAD;
    int r = -1, raw_signs, vec = 0;
    r4_tail tail = {0};
    r4_band_fn band;
    *nonzero = 0;
    memset(&D, 0, sizeof D);
    memset(&P, 0, sizeof P);
    if (size < pos) {
        *why = "mode-4 payload truncated";
        return -1;
    }
    if (buf[0] & ~(R4_SIGNS_MODELLED | R4_TABLES_PACKED)) {
        *why = "mode-4 flags not known";
        return -1;
    }
    raw_signs = !(buf[0] & R4_SIGNS_MODELLED);
    memcpy(xs, buf + 1, R4_HEAD); /* little-endian hosts only, as the rest of the codec */
    for (int l = 0; l < R4_NX; l++)
        if (xs[l] < R4_L) {
            *why = "mode-4 rANS state out of range";
            return -1;
        }
    flat = malloc((size_t)R4_NC * R4_M * sizeof *flat);
    if (!flat) goto nomem;
    D.flat = flat;
    if (r4_get_all_tables(&D, flat, buf, size, &pos, buf[0] & R4_TABLES_PACKED, raw_signs)) goto bad_table;
    D.SF[R4_NSGW] = R4_M;
    if (wvol__wvc_rans_get_varint(buf, size, &pos, &nw) || wvol__wvc_rans_get_varint(buf, size, &pos, &nraw) ||
        2 * (size_t)nw > size - pos || nraw != size - pos - 2 * (size_t)nw) {
        *why = "mode-4 stream lengths do not match the payload";
        goto done;
    }
    D.w = buf + pos;
    D.raw = D.w + 2 * (size_t)nw;
    D.nw = nw;
    D.nraw = nraw;
    /* a row's reads past the positions: a word per step (a row flag, its group flags, a
     * magnitude and a sign per coefficient) and a 16-byte load; up to 31 raw bits per
     * coefficient and the engine's 36 bytes past a step's first */
    D.wrow = 2 * (2 * ex + ng + 1) + 32;
    D.rrow = 4 * ex + 64;
    D.wspan = size - pos;
    D.rspan = nraw;
    tail.T = D.wrow > D.rrow ? D.wrow : D.rrow;
    tail.end = buf + size;
    tail.ts = tail.end - (tail.T < size - pos ? tail.T : size - pos);
    tail.buf = calloc(2 * tail.T, 1);
    D.rnz = malloc(b[0]->ext[1] * b[0]->ext[2] + 1);
    if (!tail.buf || !D.rnz || wvol__wvc_rans4_row_alloc(&row, &zrow, ex)) goto nomem;
    memcpy(tail.buf, tail.ts, (size_t)(tail.end - tail.ts));
    band = raw_signs ? r4_band_raw : r4_band_sgn;
#ifdef R4_HAVE_AVX2
    vec = engine == WVC_RANS4_AUTO && ex % 8 == 0 && r4_cpu_avx2();
    if (vec) band = raw_signs ? r4_band_avx2_raw : r4_band_avx2_sgn;
#endif
    (void)vec;
    for (int i = 0; i < n; i++) {
        const size_t rows = b[i]->ext[1] * b[i]->ext[2];
        P.row = 0;
        P.plast = 0;
        for (;;) {
            if (band(&D, Q[i], p[i], b[i], &row, zrow, xs, &P, why)) goto done;
            if (P.row >= rows) break;
            if (r4_to_tail(&D, &P, &tail)) {
                *why = "mode-4 decoder: no room for a row";
                goto done;
            }
        }
    }
    *nonzero = P.nzc;
    for (int l = 0; l < R4_NX; l++)
        if (xs[l] != R4_L) {
            *why = "mode-4 rANS states do not end where they should";
            goto done;
        }
    if (P.ps != nw || 8 * (uint64_t)nraw - P.bits >= 8) {
        *why = "mode-4 streams do not end where they should";
        goto done;
    }
    r = 0;
    goto done;
nomem:
    *why = "out of memory";
    goto done;
bad_table:
    *why = "mode-4 table malformed";
done:
    free(flat);
    free(tail.buf);
    free(D.rnz);
    wvol__wvc_rans4_row_free(&row, zrow);
    return r;
}
