/* SPDX-License-Identifier: MIT
 * The parts of a static-model rANS coder that chunk mode 3 (wvc_rans.c) shares with the
 * coders measured against it (bench/chunk4.c): the magnitude symbols, a row's neighbour sum
 * and parent classes, the normalisation of counts to frequencies, the encoder's step without
 * a division, LEB128 reading. The
 * frequency total 2^pbits is the caller's (pbits <= 11). Not installed. */
#ifndef WVOL_CODEC_RANS_COMMON_H
#define WVOL_CODEC_RANS_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "wvc_internal.h"

/* Magnitude symbols: 0 for q = 0, 1 for |q| = 1, 2n + b for |q| of bit length n + 1 >= 2
 * with b the bit below the leading one; the raw bits below the first two, and the
 * symbol's base value. */
static inline int wvc_rans_nraw(int s) { return s < 2 ? 0 : (s >> 1) - 1; }
static inline uint32_t wvc_rans_base(int s)
{
    return s < 2 ? (uint32_t)s : (2u | (uint32_t)(s & 1)) << ((s >> 1) - 1);
}

/* The bit length of t < 2^24 (0 for 0) through float's exponent, so that a loop of it
 * vectorises (x86-64-v3 has no vector count of leading zeros; it converts signed ints). */
static inline uint32_t wvc_rans_bitlen24(uint32_t t)
{
    float f = (float)(int32_t)t;
    uint32_t u;
    memcpy(&u, &f, 4);
    return ((u >> 23) - 126) & (0u - (t != 0));
}

/* |v| capped at 65535: the magnitudes the context sums add (12 of them stay below 2^24). */
static inline uint32_t wvc_rans_abs(int32_t v)
{
    uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
    return a > 65535 ? 65535 : a;
}

/* A row's magnitude context sum without its own row: A[x] = 2(|N| + |U|) + |UN| + |US| at x
 * and |N| + |U| at x - 1 and x + 1 (N the row above, U the row in the slice before, UN and
 * US that slice's rows above and below), in loops without a chain, so that they vectorise. */
static inline void wvc_rans_row_sum(uint32_t *restrict A, const int32_t *N, const int32_t *U, const int32_t *UN,
                                    const int32_t *US, size_t ex)
{
    size_t x;
    for (x = 0; x < ex; x++)
        A[x] = 2 * (wvc_rans_abs(N[x]) + wvc_rans_abs(U[x])) + wvc_rans_abs(UN[x]) + wvc_rans_abs(US[x]);
    for (x = 1; x < ex; x++) A[x] += wvc_rans_abs(N[x - 1]) + wvc_rans_abs(U[x - 1]);
    for (x = 0; x + 1 < ex; x++) A[x] += wvc_rans_abs(N[x + 1]) + wvc_rans_abs(U[x + 1]);
}

/* The parent row of row (y, z) of band b (which has a parent) in Q (strides sy, sz), or in
 * b->pq's block when the band has one: the parents' rows clamped to the parent region, as at
 * its edge. */
static inline const int32_t *wvc_rans_parent_row(const int32_t *Q, size_t sy, size_t sz, const wvc_band *b, size_t y,
                                                 size_t z)
{
    size_t pj = y >> 1, pk = z >> 1;
    if (pj >= b->pext[1]) pj = b->pext[1] - 1;
    if (pk >= b->pext[2]) pk = b->pext[2] - 1;
    if (b->pq) return b->pq + b->psy * pj + b->psz * pk;
    return Q + b->poff[0] + sy * (b->poff[1] + pj) + sz * (b->poff[2] + pk);
}

/* The parent classes of a row of ex coefficients from its parent row pr (pe values):
 * 0, 1, 2-3, 4+ of |parent|, each parent serving two x (the last one the rest). */
static inline void wvc_rans_parent_classes(uint8_t *restrict PC, const int32_t *pr, size_t pe, size_t ex)
{
    size_t x, half = ex >> 1 < pe ? ex >> 1 : pe;
    for (x = 0; x < half; x++) {
        uint32_t a = wvc_rans_abs(pr[x]);
        uint8_t k = (uint8_t)((a > 0) + (a > 1) + (a > 3));
        PC[2 * x] = k;
        PC[2 * x + 1] = k;
    }
    for (x = 2 * half; x < ex; x++) {
        uint32_t a = wvc_rans_abs(pr[(x >> 1) < pe ? x >> 1 : pe - 1]);
        PC[x] = (uint8_t)((a > 0) + (a > 1) + (a > 3));
    }
}

/* An encoder symbol: frequency, start, and m = ceil(2^63 / f), with which x / f =
 * (x m) >> 63 exactly for every x < 2^32 (the error x (m - 2^63/f) / 2^63 < 2^-31 never
 * reaches the next integer, as x / f's fraction is at most 1 - 1/f and f <= 2^11): a
 * multiply instead of a division. */
typedef struct wvc_rans_esym {
    uint64_t m;
    uint32_t f, start;
} wvc_rans_esym;

static inline wvc_rans_esym wvc_rans_esym_make(uint32_t f, uint32_t start)
{
    wvc_rans_esym e;
    e.f = f;
    e.start = start;
    e.m = f ? (((uint64_t)1 << 63) + f - 1) / f : 0;
    return e;
}

/* One rANS step of the encoder (32-bit state in [2^16, 2^32), 16-bit renormalisation into
 * *ptr, downwards). */
static inline uint32_t wvc_rans_enc_put(uint32_t x, const wvc_rans_esym *e, uint16_t **ptr, int pbits)
{
    /* the word is written either way (the buffer has room) and kept when due: no branch */
    const uint32_t r = x >= ((uint64_t)e->f << (32 - pbits));
    uint32_t q;
    (*ptr)[-1] = (uint16_t)x;
    *ptr -= r;
    x >>= r << 4;
    q = (uint32_t)(((unsigned __int128)x * e->m) >> 63);
    return (q << pbits) + (x - q * e->f) + e->start;
}

/* Normalises counts cnt[0..ns) (sum > 0) to frequencies summing to m, each present
 * symbol at least 1 (wvc_rans.c). */
void wvol__wvc_rans_normalise(const uint32_t *cnt, int ns, uint32_t *f, uint32_t m);
/* The frequency (of m) of the first of two symbols counted n0 and n1 times (not both 0):
 * m or 0 when one never occurs, else within [1, m - 1]. */
uint32_t wvol__wvc_rans_binary_f(uint64_t n0, uint64_t n1, uint32_t m);
/* One LEB128 value of at most 32 bits from buf[*pos..size); 0, or -1 when it runs past
 * size or is longer than 5 bytes. */
int wvol__wvc_rans_get_varint(const uint8_t *buf, size_t size, size_t *pos, uint32_t *v);

#endif
