/* SPDX-License-Identifier: MIT
 * Chunk mode 4's encoder (docs/wvc-format.md, "Chunk mode 4"). Two passes over the
 * coefficients, no record of the events:
 *  - forward: per non-zero row one pass (eight lanes per vector with AVX2) giving its contexts
 *    and symbols (they depend only on the rows before it and on the row's own values, never on
 *    the coder's state): the magnitude events, sign contexts, group masks and group-flag
 *    contexts, kept in the chunk's buffers; every event counted (four copies of the counts,
 *    coefficient x on copy x mod 4, so that repeated events do not wait on each other's store);
 *  - the tables from the counts, and the per-chunk sign choice from them as well: the modelled
 *    signs' ideal cost under their normalised frequencies plus their table, against one raw bit
 *    each; the raw bits' total length;
 *  - backward: the buffers read in reverse, the rANS steps in reverse order, eight states per
 *    vector step (Giesen's SIMD rANS: the words of the lanes that renormalise stored by one
 *    compressing shuffle, in lane order, which is the order the decoder reads them), the
 *    division by a multiply-high with a per-symbol magic number; a group's sign events put in
 *    the order of its non-zeros by permutations; the raw bits written backwards from the end
 *    (the counts give its position), eight coefficients' bits merged into one field.
 * The rows of Q are fetched ahead (C4E_AHEAD): a chunk's rows are a page apart in the pyramid.
 * Scratch (rows, tables, the word and raw-bit buffers) is the caller's per thread
 * (wvc_rans_scratch) and grown, not allocated per chunk. The scalar path (other CPUs, extents
 * that are not a multiple of 16, or asked for) gives the same bytes. */
#include "core/alloc.h"
#include "rans_common.h"
#include "wvc2_internal.h"
#include "wvc_rans4.h"
#include "wvc_rans4_avx2.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


/* event numbers: magnitude context x 64 + symbol, then group flags, signs, row flags */
#define C4E_EV_FLAG (R4_NC * 64)
#define C4E_EV_SIGN (C4E_EV_FLAG + 2 * R4_NG)
#define C4E_EV_ROW (C4E_EV_SIGN + 2 * R4_NSGW)
#define C4E_NEV (C4E_EV_ROW + 2 * R4_NR)
#define C4E_AHEAD 4 /* rows fetched ahead */
#define C4E_NBIN (R4_NG + R4_NSGW + R4_NR) /* binary contexts: group flags, signs, row flags (event order) */
/* the header's bound: per magnitude table its count and precision in 2 bytes and each frequency
 * in 3 (LEB128 needs 2, a packed one at most 21 bits); a binary entry in 2 */
#define C4E_HEADMAX (4 * R4_NX + R4_NC * (2 + 3 * R4_NS) + 2 * C4E_NBIN + 32)

/* A row's contexts and symbols from the forward pass: per coefficient EV (its magnitude
 * event), SG (its sign context) and SE (its sign event, C4E_NEV for a zero: counted only); per
 * group GM (the mask of its non-zeros) and GX (its flag's context). EV, SG, GM and GX point into
 * the chunk's buffers, which the backward pass reads; A, CX and PC are the scalar pass's. */
typedef struct c4e_row {
    uint32_t *A;
    uint16_t *EV, *SE, *GM;
    uint8_t *CX, *PC, *SG, *GX;
} c4e_row;

typedef struct c4e_scratch {
    size_t ex, rows, words, raw, coefs, groups; /* capacities */
    c4e_row w;
    void *rowmem;
    int32_t *zrow;
    uint8_t *rnz, *rctx; /* per row of every band: its flag and the flag's context */
    uint16_t *evb, *gmb; /* the non-zero rows' EV and GM, in order */
    uint8_t *sgb, *gxb;  /* their SG and GX */
    uint16_t *wbuf;
    uint8_t *rbuf;
    uint32_t cnt[4][C4E_NEV + 1]; /* four copies, coefficient x on copy x mod 4: repeated events do not
                                   * wait on each other's store */
    wvc_rans_esym es[C4E_NEV];
    uint32_t pk[C4E_NEV], mg[C4E_NEV]; /* the vector step's entries: packed f, start, shifts; magic */
    uint8_t cmp[256][16];             /* the compressing shuffles of the words (by renormalisation mask) */
    uint8_t cidx[256][8];             /* the lanes of a mask's set bits, in order (then zeros) */
    uint8_t head[C4E_HEADMAX];
    double lg[R4_M + 1];                /* log2 k, for the packed tables' costs */
    uint8_t tp[R4_NC];                  /* packed: each magnitude table's precision (0: unused) */
    uint8_t bk[C4E_NBIN], bp[C4E_NBIN]; /* packed: each binary entry's kind and precision */
} c4e_scratch;

void wvol__wvc_rans4_scratch_free(void *p)
{
    c4e_scratch *s = p;
    if (!s) return;
    free(s->rowmem);
    free(s->zrow);
    /* the buffers c4e_grow made, back to the reuse pool */
    wvol__reuse_put(s->rnz);
    wvol__reuse_put(s->rctx);
    wvol__reuse_put(s->evb);
    wvol__reuse_put(s->gmb);
    wvol__reuse_put(s->sgb);
    wvol__reuse_put(s->gxb);
    wvol__reuse_put(s->wbuf);
    wvol__reuse_put(s->rbuf);
    free(s);
}

/* Grows a buffer to n elements of size sz (contents not kept), from the reuse pool
 * (core/alloc.h): a dense chunk's buffers are megabytes, which fresh memory in 4 KiB pages
 * faulted in one at a time; the pool has pages an earlier pass touched, else whole huge
 * pages. */
static int c4e_grow(void **p, size_t cap, size_t n, size_t sz)
{
    void *q;
    if (n <= cap) return 0;
    q = wvol__reuse_get(n * sz);
    if (!q) return -1;
    wvol__reuse_put(*p);
    *p = q;
    return 0;
}

/* *slot's scratch (made on first use), grown to the sizes given; NULL when out of memory. */
static c4e_scratch *c4e_scratch_get(void **slot, size_t ex, size_t rows, size_t coefs, size_t groups, size_t words,
                                    size_t raw)
{
    c4e_scratch *s = *slot;
    if (!s) {
        s = calloc(1, sizeof *s);
        if (!s) return NULL;
        for (uint32_t k = 1; k <= R4_M; k++) s->lg[k] = log2((double)k);
        for (int mk = 0; mk < 256; mk++) { /* the words of the lanes in mk at the top of 8, in lane order */
            int j = 8 - __builtin_popcount((unsigned)mk), k = 0;
            for (int i = 0; i < 8; i++)
                if (mk >> i & 1) s->cidx[mk][k++] = (uint8_t)i;
            memset(s->cmp[mk], 0x80, 16);
            for (int i = 0; i < 8; i++)
                if (mk >> i & 1) {
                    s->cmp[mk][2 * j] = (uint8_t)(2 * i);
                    s->cmp[mk][2 * j + 1] = (uint8_t)(2 * i + 1);
                    j++;
                }
        }
        *slot = s;
    }
    if (ex > s->ex) {
        const size_t e = ex + 16; /* room for a vector store past a row */
        uint8_t *m = malloc(e * (4 + 2 + 1 + 1) + 64);
        int32_t *z = calloc(e, sizeof *z);
        if (!m || !z) {
            free(m);
            free(z);
            return NULL;
        }
        free(s->rowmem);
        free(s->zrow);
        s->rowmem = m;
        s->zrow = z;
        s->w.A = (uint32_t *)m;
        s->w.SE = (uint16_t *)(s->w.A + e);
        s->w.PC = (uint8_t *)(s->w.SE + e);
        s->w.CX = s->w.PC + e;
        s->ex = ex;
    }
    if (c4e_grow((void **)&s->rnz, s->rows, rows, 1) || c4e_grow((void **)&s->rctx, s->rows, rows, 1)) {
        s->rows = 0;
        return NULL;
    }
    s->rows = rows > s->rows ? rows : s->rows;
    coefs += 16; /* a vector's store past the last row */
    if (c4e_grow((void **)&s->evb, s->coefs, coefs, 2) || c4e_grow((void **)&s->sgb, s->coefs, coefs, 1)) {
        s->coefs = 0;
        return NULL;
    }
    s->coefs = coefs > s->coefs ? coefs : s->coefs;
    if (c4e_grow((void **)&s->gmb, s->groups, groups, 2) || c4e_grow((void **)&s->gxb, s->groups, groups, 1)) {
        s->groups = 0;
        return NULL;
    }
    s->groups = groups > s->groups ? groups : s->groups;
    if (c4e_grow((void **)&s->wbuf, s->words, words, sizeof *s->wbuf)) {
        s->words = 0;
        return NULL;
    }
    s->words = words > s->words ? words : s->words;
    if (c4e_grow((void **)&s->rbuf, s->raw, raw, 1)) {
        s->raw = 0;
        return NULL;
    }
    s->raw = raw > s->raw ? raw : s->raw;
    return s;
}

/* Fetches ahead the lines of row y + d (d < 0: a row before) of Q, and going forward its
 * parent row: the chunk's rows are far apart in the pyramid (a page or more) and the hardware's
 * prefetcher misses them. Always inlined: GCC drops a call to a function that only prefetches. */
static inline __attribute__((always_inline)) void c4e_prefetch(const int32_t *Q, const size_t p[3],
                                                                const wvc_band *b, size_t y, size_t z, int d)
{
    const size_t yd = y + (size_t)(ptrdiff_t)d;
    const int32_t *c;
    if (yd >= b->ext[1]) return;
    c = Q + wvc_index(p, b, 0, yd, z);
    for (size_t x = 0; x < b->ext[0]; x += 16) __builtin_prefetch(c + x);
    if (d > 0 && b->has_parent && !(yd & 1)) {
        const int32_t *r = wvc_rans_parent_row(Q, p[0], p[0] * p[1], b, yd, z);
        for (size_t x = 0; x < b->pext[0]; x += 16) __builtin_prefetch(r + x);
    }
}

/* A group's flag context from its neighbour sum s (< 16 * 12 * 65535 < 2^24) and the OR of its
 * parent classes. */
static inline uint8_t c4e_gx(uint32_t s, uint32_t pm)
{
    const uint32_t n = wvc_rans_bitlen24(s);
    return (uint8_t)((n < R4_NGA - 1 ? n : R4_NGA - 1) * R4_NP + (pm > 3 ? 3 : pm));
}

/* Row (y, z)'s contexts (the decoder's scalar pass, wvc_rans4_ctx.c) and symbols. */
WVOL__CLONES static void c4e_row_scalar(const c4e_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b,
                                        size_t y, size_t z, const int32_t *zrow, int signs)
{
    const r4_row r = {w->A, w->CX, w->PC, w->SG, w->GX};
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const size_t ex = b->ext[0];
    const uint8_t *restrict CX = w->CX, *restrict SG = w->SG;
    uint16_t *restrict EV = w->EV, *restrict SE = w->SE;
    wvol__wvc_rans4_row_prep(&r, Q, p, b, y, z, zrow, signs);
    /* loops without a chain or a count of leading zeros, so that they vectorise */
    for (size_t x = 0; x < ex; x++) {
        const int32_t v = c[x];
        const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
        const uint32_t sh = a >> 24 ? 8 : 0, nb = wvc_rans_bitlen24(a >> sh) + sh - 1; /* floor(log2 a), a > 0 */
        const uint32_t sym = a < 2 ? a : 2 * nb + ((a >> ((nb - 1) & 31)) & 1);
        EV[x] = (uint16_t)((uint32_t)CX[x] * 64 + sym);
    }
    if (signs)
        for (size_t x = 0; x < ex; x++) SE[x] = (uint16_t)(c[x] ? C4E_EV_SIGN + 2 * (uint32_t)SG[x] + (c[x] < 0) : C4E_NEV);
    for (size_t g = 0, x0 = 0; x0 < ex; g++, x0 += R4_GROUP) {
        const size_t x1 = x0 + R4_GROUP < ex ? x0 + R4_GROUP : ex;
        uint32_t gm = 0;
        for (size_t x = x0; x < x1; x++) gm |= (uint32_t)(c[x] != 0) << (x - x0);
        w->GM[g] = (uint16_t)gm;
    }
}

#ifdef R4_HAVE_AVX2
/* the bit length of lanes below 2^24 (0 for 0) through float's exponent */
R4_AVX2_INLINE __m256i c4e_bitlen24(__m256i t)
{
    const __m256i n = _mm256_sub_epi32(_mm256_srli_epi32(_mm256_castps_si256(_mm256_cvtepi32_ps(t)), 23),
                                       _mm256_set1_epi32(126));
    return _mm256_andnot_si256(_mm256_cmpeq_epi32(t, _mm256_setzero_si256()), n);
}
R4_AVX2_INLINE uint32_t c4e_hsum(__m256i v)
{
    __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4E));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0xB1));
    return (uint32_t)_mm_cvtsi128_si32(s);
}
R4_AVX2_INLINE uint32_t c4e_hor(__m256i v)
{
    __m128i s = _mm_or_si128(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    s = _mm_or_si128(s, _mm_shuffle_epi32(s, 0x4E));
    s = _mm_or_si128(s, _mm_shuffle_epi32(s, 0xB1));
    return (uint32_t)_mm_cvtsi128_si32(s);
}

/* c4e_row_scalar in vectors of eight, for extents that are multiples of 16 with a parent row at
 * least half as long (else the scalar pass): the same numbers. */
R4_AVX2 static void c4e_row_avx2(const c4e_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                                  size_t z, const int32_t *zrow, int signs)
{
    /* the rows N, U, UN, US of row (y, z) (zrow outside the band) */
    const size_t sy = p[0], sz = p[0] * p[1], ex = b->ext[0];
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const int32_t *N = y > 0 ? c - sy : zrow, *U = z > 0 ? c - sz : zrow;
    const int32_t *UN = z > 0 && y > 0 ? c - sz - sy : zrow, *US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    const size_t nv = ex / 8;
    const __m256i zero = _mm256_setzero_si256(), one = _mm256_set1_epi32(1);
    const __m256i sbase = _mm256_set1_epi32(9 * (b->band - 1));
    const int32_t *pr = NULL;
    __m256i Sp = zero, Sc, Np = zero, Nc, Agrp = zero, Pgrp = zero;
    uint32_t gm = 0;
    if (b->has_parent && b->pext[0] < ex / 2) {
        c4e_row_scalar(w, Q, p, b, y, z, zrow, signs);
        return;
    }
    if (b->has_parent) pr = wvc_rans_parent_row(Q, sy, sz, b, y, z);
    Nc = _mm256_loadu_si256((const __m256i *)N);
    Sc = _mm256_add_epi32(r4v_abs16(Nc), r4v_abs16(_mm256_loadu_si256((const __m256i *)U)));
    for (size_t v = 0; v < nv; v++) {
        const size_t x = 8 * v;
        const __m256i Nn = v + 1 < nv ? _mm256_loadu_si256((const __m256i *)(N + x + 8)) : zero;
        const __m256i Sn = v + 1 < nv ? _mm256_add_epi32(r4v_abs16(Nn), r4v_abs16(_mm256_loadu_si256((const __m256i *)(U + x + 8))))
                                      : zero;
        const __m256i A = _mm256_add_epi32(
            _mm256_add_epi32(_mm256_add_epi32(Sc, Sc), _mm256_add_epi32(r4v_left(Sc, Sp), r4v_right(Sc, Sn))),
            _mm256_add_epi32(r4v_abs16(_mm256_loadu_si256((const __m256i *)(UN + x))),
                             r4v_abs16(_mm256_loadu_si256((const __m256i *)(US + x)))));
        const __m256i q = _mm256_loadu_si256((const __m256i *)(c + x)), a = _mm256_abs_epi32(q);
        /* floor(log2 a) through float's exponent, exact for a >= 2^24 too (shifted by 8 first) */
        const __m256i big = _mm256_and_si256(_mm256_cmpgt_epi32(a, _mm256_set1_epi32((1 << 24) - 1)), _mm256_set1_epi32(8));
        const __m256i nb = _mm256_add_epi32(
            _mm256_sub_epi32(_mm256_srli_epi32(_mm256_castps_si256(_mm256_cvtepi32_ps(_mm256_srlv_epi32(a, big))), 23),
                             _mm256_set1_epi32(127)),
            big);
        const __m256i ge2 = _mm256_cmpgt_epi32(a, one);
        const __m256i K = _mm256_and_si256(_mm256_sub_epi32(nb, one), ge2);
        const __m256i sym = _mm256_blendv_epi8(
            a, _mm256_add_epi32(_mm256_add_epi32(nb, nb), _mm256_and_si256(_mm256_srlv_epi32(a, K), one)), ge2);
        __m256i PC = zero, n, cx, ev;
        if (pr) PC = r4v_parent_class(pr + x / 2);
        n = _mm256_min_epi32(c4e_bitlen24(A), _mm256_set1_epi32(R4_NA - 1));
        cx = _mm256_add_epi32(_mm256_slli_epi32(n, 2), PC);
        ev = _mm256_add_epi32(_mm256_slli_epi32(cx, 6), sym);
        _mm_storeu_si128((__m128i *)(w->EV + x),
                         _mm_packus_epi32(_mm256_castsi256_si128(ev), _mm256_extracti128_si256(ev, 1)));
        if (signs) { /* sign contexts, and sign events for the counts (C4E_NEV for a zero) */
            const __m256i sg = _mm256_add_epi32(
                _mm256_add_epi32(sbase, _mm256_mullo_epi32(r4v_sgn3(_mm256_loadu_si256((const __m256i *)(U + x))),
                                                           _mm256_set1_epi32(3))),
                _mm256_add_epi32(r4v_sgn3(Nc),
                                 _mm256_mullo_epi32(r4v_sgn3(r4v_left(Nc, Np)), _mm256_set1_epi32(R4_NSG))));
            const __m256i se = _mm256_blendv_epi8(
                _mm256_sub_epi32(_mm256_add_epi32(_mm256_set1_epi32(C4E_EV_SIGN), _mm256_add_epi32(sg, sg)),
                                 _mm256_cmpgt_epi32(zero, q)),
                _mm256_set1_epi32(C4E_NEV), _mm256_cmpeq_epi32(q, zero));
            r4v_bytes(w->SG + x, sg);
            _mm_storeu_si128((__m128i *)(w->SE + x),
                             _mm_packus_epi32(_mm256_castsi256_si128(se), _mm256_extracti128_si256(se, 1)));
        }
        {
            const uint32_t nzm = 255u ^ (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(q, zero)));
            if (v & 1) {
                w->GX[v / 2] = c4e_gx(c4e_hsum(_mm256_add_epi32(Agrp, A)), c4e_hor(_mm256_or_si256(Pgrp, PC)));
                w->GM[v / 2] = (uint16_t)(gm | nzm << 8);
            } else {
                Agrp = A;
                Pgrp = PC;
                gm = nzm;
            }
        }
        Sp = Sc, Sc = Sn, Np = Nc, Nc = Nn;
    }
}
#endif

/* The per-call state of the encoder. */
typedef struct c4e_job {
    int n;
    int32_t *const *Q;
    const size_t *const *p;
    const wvc_band *const *b;
    c4e_scratch *s;
    int vec, raw_signs;
    uint64_t sumk, nnz; /* raw magnitude bits and non-zeros of the chunk (from the counts) */
    size_t sgoff, sglen; /* the sign table in the header */
    size_t eo, go;       /* the chunk buffers' lengths after the forward pass */
} c4e_job;

static inline void c4e_prep(const c4e_job *J, int i, size_t y, size_t z, int signs)
{
#ifdef R4_HAVE_AVX2
    if (J->vec) {
        c4e_row_avx2(&J->s->w, J->Q[i], J->p[i], J->b[i], y, z, J->s->zrow, signs);
        return;
    }
#endif
    c4e_row_scalar(&J->s->w, J->Q[i], J->p[i], J->b[i], y, z, J->s->zrow, signs);
}

/* Whether group g's flag is coded: not for a single group, nor for the last one when the
 * others are zero (first: the row's first non-zero group). */
static inline int c4e_flag_coded(size_t g, size_t ng, size_t first) { return ng > 1 && (g + 1 < ng || first < g); }

static inline size_t c4e_first_nz(const uint16_t *GM, size_t ng)
{
    size_t g = 0;
    while (g < ng && !GM[g]) g++;
    return g;
}

/* The forward pass: row flags and their contexts; each non-zero row's contexts and symbols into
 * the chunk's buffers (in row order); every event counted. */
static void c4e_pass1(c4e_job *J, int signs)
{
    c4e_scratch *s = J->s;
    c4e_row *w = &s->w;
    size_t row0 = 0, eo = 0, go = 0;
    for (int i = 0; i < J->n; i++) {
        const wvc_band *b = J->b[i];
        const size_t ex = b->ext[0], ey = b->ext[1], ng = (ex + R4_GROUP - 1) / R4_GROUP;
        uint8_t *rnz = s->rnz + row0, *rctx = s->rctx + row0;
        uint32_t plast = 0;
        for (size_t z = 0; z < b->ext[2]; z++)
            for (size_t y = 0; y < ey; y++) {
                const int32_t *c = J->Q[i] + wvc_index(J->p[i], b, 0, y, z);
                uint32_t rc;
                int32_t o = 0;
                size_t first;
                c4e_prefetch(J->Q[i], J->p[i], b, y, z, C4E_AHEAD);
                rc = r4_row_ctx(rnz, J->Q[i], J->p[i], b, y, z, &plast);
                /* whether the row holds a non-zero: sixteen values at a time, to the first */
                for (size_t x = 0; x < ex && !o; x += 16)
                    for (size_t k = x; k < x + 16 && k < ex; k++) o |= c[k];
                rnz[z * ey + y] = (uint8_t)(o != 0);
                rctx[z * ey + y] = (uint8_t)rc;
                s->cnt[0][C4E_EV_ROW + 2 * rc + (o != 0)]++;
                if (!o) continue;
                w->EV = s->evb + eo, w->SG = s->sgb + eo, w->GM = s->gmb + go, w->GX = s->gxb + go;
                eo += ex, go += ng;
                c4e_prep(J, i, y, z, signs);
                first = c4e_first_nz(w->GM, ng);
                for (size_t g = 0, x0 = 0; g < ng; g++, x0 += R4_GROUP) {
                    const size_t x1 = x0 + R4_GROUP < ex ? x0 + R4_GROUP : ex;
                    const uint32_t m = w->GM[g];
                    if (c4e_flag_coded(g, ng, first)) s->cnt[0][C4E_EV_FLAG + 2 * w->GX[g] + (m != 0)]++;
                    if (!m) continue;
                    if (x1 - x0 == R4_GROUP) { /* unrolled over the four copies */
                        uint32_t *c0 = s->cnt[0], *c1 = s->cnt[1], *c2 = s->cnt[2], *c3 = s->cnt[3];
                        const uint16_t *ev = w->EV + x0, *se = w->SE + x0;
                        for (int k = 0; k < R4_GROUP; k += 4) c0[ev[k]]++, c1[ev[k + 1]]++, c2[ev[k + 2]]++, c3[ev[k + 3]]++;
                        if (signs)
                            for (int k = 0; k < R4_GROUP; k += 4)
                                c0[se[k]]++, c1[se[k + 1]]++, c2[se[k + 2]]++, c3[se[k + 3]]++;
                        continue;
                    }
                    for (size_t x = x0; x < x1; x++) s->cnt[x & 3][w->EV[x]]++;
                    if (signs)
                        for (size_t x = x0; x < x1; x++) s->cnt[x & 3][w->SE[x]]++;
                }
            }
        row0 += ey * b->ext[2];
    }
    J->eo = eo, J->go = go;
}

/* A binary context's two events from its counts; its table entry (f0 + 1, 0 unused). */
static uint32_t c4e_binary(uint32_t *ev, wvc_rans_esym *es)
{
    const int used = (ev[0] | ev[1]) != 0;
    const uint32_t f = used ? wvol__wvc_rans_binary_f(ev[0], ev[1], R4_M) : 0;
    es[0] = wvc_rans_esym_make(f, 0);
    es[1] = wvc_rans_esym_make(R4_M - f, f);
    return used ? f + 1 : 0;
}

/* The ideal code length in bits of n events of frequency f (of 2^10). */
static double c4e_bits(uint32_t n, uint32_t f) { return n ? (double)n * (R4_PBITS - log2((double)f)) : 0; }

/* The vector step's entries: f | start << 11 | sh2 << 22 | sh1 << 26 and the magic number m' with
 * x / f = (t + ((x - t) >> sh1)) >> sh2, t = (x m') >> 32, for every 32-bit x (Granlund and
 * Montgomery's unsigned division, fig. 4.1; f <= 2^10). */
static void c4e_vec_entry(const wvc_rans_esym *e, uint32_t *pk, uint32_t *mg)
{
    const uint32_t f = e->f, l = f > 1 ? 32 - (uint32_t)__builtin_clz(f - 1) : 0;
    const uint32_t sh1 = l ? 1 : 0, sh2 = l ? l - 1 : 0;
    const uint64_t num = (((uint64_t)1 << l) - f) << 32;
    *mg = f ? (uint32_t)(num / f + 1) : 0;
    *pk = f | e->start << 11 | sh2 << 22 | sh1 << 26;
}

/* The four copies of the counts summed into the first (returned); the chunk's raw magnitude
 * bits and non-zeros from them. */
static uint32_t *c4e_counts(c4e_job *J)
{
    c4e_scratch *s = J->s;
    uint32_t *cnt = s->cnt[0];
    for (int e = 0; e < C4E_NEV; e++) cnt[e] += s->cnt[1][e] + s->cnt[2][e] + s->cnt[3][e];
    for (int c = 0; c < R4_NC; c++)
        for (int k = 0; k < R4_NS; k++) {
            J->sumk += (uint64_t)cnt[64 * c + k] * (uint64_t)wvc_rans_nraw(k);
            J->nnz += k ? cnt[64 * c + k] : 0;
        }
    return cnt;
}

/* The LEB128 tables (flags bit 1 clear) into s->head (after the final states' room) and the
 * encoder's entries; returns the header's length. Also the estimated bytes of the modelled and
 * the raw signs. */
static size_t c4e_tables(c4e_job *J, int signs, double *est_mod, double *est_raw)
{
    c4e_scratch *s = J->s;
    uint32_t *cnt = c4e_counts(J), F[R4_NS];
    size_t head = 4 * R4_NX, head_signs;
    double bits = 0, sbits = 0;
    for (int c = 0; c < R4_NC; c++) {
        uint32_t any = 0, cum = 0;
        int ns = 0;
        const uint32_t *h = cnt + 64 * c;
        for (int k = 0; k < R4_NS; k++) any |= h[k];
        if (any) wvol__wvc_rans_normalise(h, R4_NS, F, R4_M);
        for (int k = 0; k < R4_NS; k++) {
            if (!any) F[k] = 0;
            if (F[k]) ns = k + 1;
            bits += c4e_bits(h[k], F[k]);
            s->es[64 * c + k] = wvc_rans_esym_make(F[k], cum), cum += F[k];
        }
        head += wvc2_put_varint(s->head + head, (uint32_t)ns);
        for (int k = 0; k < ns; k++) head += wvc2_put_varint(s->head + head, F[k]);
    }
    for (int c = 0; c < R4_NG; c++) {
        uint32_t *ev = cnt + C4E_EV_FLAG + 2 * c;
        head += wvc2_put_varint(s->head + head, c4e_binary(ev, s->es + C4E_EV_FLAG + 2 * c));
        bits += c4e_bits(ev[0], s->es[C4E_EV_FLAG + 2 * c].f) + c4e_bits(ev[1], s->es[C4E_EV_FLAG + 2 * c + 1].f);
    }
    J->sgoff = head_signs = head;
    if (signs)
        for (int c = 0; c < R4_NSGW; c++) {
            uint32_t *ev = cnt + C4E_EV_SIGN + 2 * c;
            head += wvc2_put_varint(s->head + head, c4e_binary(ev, s->es + C4E_EV_SIGN + 2 * c));
            sbits += c4e_bits(ev[0], s->es[C4E_EV_SIGN + 2 * c].f) + c4e_bits(ev[1], s->es[C4E_EV_SIGN + 2 * c + 1].f);
        }
    J->sglen = head_signs = head - head_signs;
    for (int c = 0; c < R4_NR; c++) {
        uint32_t *ev = cnt + C4E_EV_ROW + 2 * c;
        head += wvc2_put_varint(s->head + head, c4e_binary(ev, s->es + C4E_EV_ROW + 2 * c));
        bits += c4e_bits(ev[0], s->es[C4E_EV_ROW + 2 * c].f) + c4e_bits(ev[1], s->es[C4E_EV_ROW + 2 * c + 1].f);
    }
    *est_raw = (double)(head - head_signs) + bits / 8 + (double)((J->sumk + J->nnz + 7) / 8);
    *est_mod = (double)head + (bits + sbits) / 8 + (double)((J->sumk + 7) / 8);
    return head;
}

/* Packed tables (wvc_rans4.h): Elias-gamma lengths, and the bit writer (most significant bit
 * first, into a zeroed buffer). */
static uint32_t c4e_eg_len(uint32_t v) { return 2 * (31 - (uint32_t)__builtin_clz(v)) + 1; }

typedef struct c4e_bitw {
    uint8_t *p;
    size_t n; /* bits written */
} c4e_bitw;

static void c4e_bits_put(c4e_bitw *w, uint32_t v, uint32_t len)
{
    for (uint32_t i = len; i-- > 0; w->n++)
        if (v >> i & 1) w->p[w->n >> 3] |= (uint8_t)(0x80u >> (w->n & 7));
}

static void c4e_eg_put(c4e_bitw *w, uint32_t v)
{
    const uint32_t n = 31 - (uint32_t)__builtin_clz(v);
    c4e_bits_put(w, 0, n);
    c4e_bits_put(w, v, n + 1);
}

/* A magnitude context's frequencies F (of 2^10) at the precision P that minimises its packed
 * table's bits plus its events' ideal code length under it (a table costs about as much as the
 * events it describes in a sparse chunk, where few events fall in most contexts). P from 10
 * down, stopping where the total grows. Returns P (0: no event); *tab and *code the two parts. */
static int c4e_mag_choose(const c4e_scratch *s, const uint32_t *h, uint32_t F[R4_NS], double *tab, double *code)
{
    uint32_t T[R4_NS];
    int ns = 0, used = 0, best = 0;
    double least = 0;
    for (int k = 0; k < R4_NS; k++)
        if (h[k]) ns = k + 1, used++;
    memset(F, 0, R4_NS * sizeof *F);
    *tab = c4e_eg_len(1), *code = 0;
    for (int P = R4_PBITS; ns && P >= R4_PMIN && used <= 1 << P; P--) {
        double t = c4e_eg_len((uint32_t)ns + 1) + R4_PFIELD, c = 0;
        wvol__wvc_rans_normalise(h, ns, T, 1u << P);
        for (int k = 0; k < ns; k++) {
            if (k + 1 < ns) t += c4e_eg_len(T[k] + 1);
            if (h[k]) c += (double)h[k] * (P - s->lg[T[k]]);
        }
        if (best && t + c >= least) break;
        best = P, least = t + c, *tab = t, *code = c;
        for (int k = 0; k < ns; k++) F[k] = T[k] << (R4_PBITS - P);
    }
    return best;
}

/* A binary context's packed kind from its counts (n0 of the first symbol, n1 of the second):
 * the least entry plus code length; *P its precision (explicit kind), *f0 the first symbol's
 * frequency of 2^10. */
static int c4e_bin_choose(const c4e_scratch *s, uint32_t n0, uint32_t n1, int *P, uint32_t *f0, double *tab,
                          double *code)
{
    int kind = R4_BIN_HALF;
    double least;
    *P = 0, *tab = R4_BKIND, *code = 0;
    if (!n1) {
        *f0 = R4_M;
        return R4_BIN_ZEROS;
    }
    if (!n0) {
        *f0 = 0;
        return R4_BIN_ONES;
    }
    *f0 = R4_M / 2, *code = (double)n0 + (double)n1;
    least = *tab + *code;
    for (int p = R4_PBITS; p >= R4_BPMIN; p--) {
        const uint32_t m = 1u << p, f = wvol__wvc_rans_binary_f(n0, n1, m);
        const double t = R4_BKIND + R4_BPFIELD + p, c = n0 * (p - s->lg[f]) + n1 * (p - s->lg[m - f]);
        if (t + c < least) least = t + c, kind = R4_BIN_EXPLICIT, *P = p, *f0 = f << (R4_PBITS - p), *tab = t, *code = c;
    }
    return kind;
}

/* The packed tables' choices and the encoder's entries from the counts (signs: their contexts
 * were counted); the estimated bytes of the modelled and the raw signs, as c4e_tables'. */
static void c4e_tables_packed(c4e_job *J, int signs, double *est_mod, double *est_raw)
{
    c4e_scratch *s = J->s;
    const uint32_t *cnt = c4e_counts(J);
    uint32_t F[R4_NS];
    double bits = 8.0 * R4_HEAD, sbits = 0, t, c;
    for (int x = 0; x < R4_NC; x++) {
        uint32_t cum = 0;
        s->tp[x] = (uint8_t)c4e_mag_choose(s, cnt + 64 * x, F, &t, &c);
        bits += t + c;
        for (int k = 0; k < R4_NS; k++) s->es[64 * x + k] = wvc_rans_esym_make(F[k], cum), cum += F[k];
    }
    for (int j = 0; j < C4E_NBIN; j++) {
        const int e = C4E_EV_FLAG + 2 * j, sign = e >= C4E_EV_SIGN && e < C4E_EV_ROW;
        int P = 0;
        uint32_t f0 = R4_M;
        s->bk[j] = sign && !signs ? R4_BIN_ZEROS
                                  : (uint8_t)c4e_bin_choose(s, cnt[e], cnt[e + 1], &P, &f0, &t, &c);
        s->bp[j] = (uint8_t)P;
        s->es[e] = wvc_rans_esym_make(f0, 0);
        s->es[e + 1] = wvc_rans_esym_make(R4_M - f0, f0);
        if (sign && signs) sbits += t + c;
        else if (!sign) bits += t + c;
    }
    *est_raw = bits / 8 + (double)((J->sumk + J->nnz + 7) / 8);
    *est_mod = (bits + sbits) / 8 + (double)((J->sumk + 7) / 8);
}

/* The packed tables into s->head after the final states' room (the sign entries when the signs
 * are modelled); returns the header's length. */
static size_t c4e_write_packed(const c4e_job *J)
{
    c4e_scratch *s = J->s;
    c4e_bitw w = {s->head + R4_HEAD, 0};
    memset(w.p, 0, sizeof s->head - R4_HEAD);
    for (int x = 0; x < R4_NC; x++) {
        const wvc_rans_esym *es = s->es + 64 * x;
        const uint32_t P = s->tp[x];
        uint32_t ns = 0;
        for (uint32_t k = 0; k < R4_NS; k++)
            if (es[k].f) ns = k + 1;
        c4e_eg_put(&w, ns + 1);
        if (!ns) continue;
        c4e_bits_put(&w, P - R4_PMIN, R4_PFIELD);
        for (uint32_t k = 0; k + 1 < ns; k++) c4e_eg_put(&w, (es[k].f >> (R4_PBITS - P)) + 1);
    }
    for (int j = 0; j < C4E_NBIN; j++) {
        const int e = C4E_EV_FLAG + 2 * j;
        if (J->raw_signs && e >= C4E_EV_SIGN && e < C4E_EV_ROW) continue;
        c4e_bits_put(&w, s->bk[j], R4_BKIND);
        if (s->bk[j] != R4_BIN_EXPLICIT) continue;
        c4e_bits_put(&w, s->bp[j], R4_BPFIELD);
        c4e_bits_put(&w, s->es[e].f >> (R4_PBITS - s->bp[j]), s->bp[j]);
    }
    return R4_HEAD + (w.n + 7) / 8;
}

/* The per-chunk sign choice (the prototype's rule, on estimated bytes): raw signs unless the
 * modelled ones take at least 1% fewer bytes. */
static int c4e_keep_raw_signs(double modelled, double raw) { return modelled > 0.99 * raw; }

/* The raw bits, written backwards: acc holds n < 32 bits at positions [B - n, B), B a
 * multiple of 8 at p; a field goes below them. */
typedef struct c4e_bitsw {
    uint64_t acc;
    uint32_t n;
    uint8_t *p;
} c4e_bitsw;

/* A field of len <= 32 bits. */
static inline void c4e_put_back(c4e_bitsw *w, uint32_t fld, uint32_t len)
{
    w->acc = w->acc << len | fld;
    w->n += len;
    if (w->n >= 32) {
        const uint32_t v = (uint32_t)(w->acc >> (w->n - 32));
        w->p -= 4;
        memcpy(w->p, &v, 4);
        w->n -= 32;
    }
}

/* Coefficient v's raw bits (k of them; with raw signs its sign after them), from its symbol. */
static inline void c4e_coef_raw(c4e_bitsw *bw, int32_t v, uint32_t sym, int raw_signs)
{
    const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v, k = (uint32_t)wvc_rans_nraw((int)sym);
    if (raw_signs)
        c4e_put_back(bw, (a & ((1u << k) - 1)) | (uint32_t)(v < 0) << k, k + (v != 0));
    else
        c4e_put_back(bw, a & ((1u << k) - 1), k);
}

/* The backward pass walks the rows in reverse: band, plane, row; in a non-zero row the groups
 * in reverse, each one's events in reverse (signs, raw bits, magnitudes, its flag), then the
 * row's flag. BODY codes group g (coefficients c + x0 ..; EV, SG at ev, sg; mask m). */
#define C4E_BACKWARD(BODY, ROWFLAG)                                                                                   \
    do {                                                                                                               \
        size_t row0 = 0, eo = J->eo, go = J->go;                                                                       \
        for (int i = 0; i < J->n; i++) row0 += J->b[i]->ext[1] * J->b[i]->ext[2];                                      \
        for (int i = J->n; i-- > 0;) {                                                                                 \
            const wvc_band *b = J->b[i];                                                                               \
            const size_t ex = b->ext[0], ey = b->ext[1], ng = (ex + R4_GROUP - 1) / R4_GROUP;                                 \
            row0 -= ey * b->ext[2];                                                                                    \
            for (size_t z = b->ext[2]; z-- > 0;)                                                                       \
                for (size_t y = ey; y-- > 0;) {                                                                        \
                    const size_t r = row0 + z * ey + y;                                                                \
                    c4e_prefetch(J->Q[i], J->p[i], b, y, z, -C4E_AHEAD);                                                     \
                    if (s->rnz[r]) {                                                                                   \
                        const int32_t *c = J->Q[i] + wvc_index(J->p[i], b, 0, y, z);                                   \
                        const uint16_t *GM, *EVr;                                                                      \
                        const uint8_t *GX, *SGr;                                                                       \
                        size_t first;                                                                                  \
                        eo -= ex, go -= ng;                                                                            \
                        GM = s->gmb + go, GX = s->gxb + go, EVr = s->evb + eo, SGr = s->sgb + eo;                      \
                        first = c4e_first_nz(GM, ng);                                                                  \
                        for (size_t g = ng; g-- > 0;) {                                                                \
                            const size_t x0 = g * R4_GROUP, x1 = x0 + R4_GROUP < ex ? x0 + R4_GROUP : ex;                        \
                            const uint32_t m = GM[g];                                                                  \
                            (void)x1;                                                                                  \
                            if (m) BODY;                                                                               \
                            if (c4e_flag_coded(g, ng, first)) ROWFLAG(C4E_EV_FLAG + 2 * GX[g] + (m != 0));            \
                        }                                                                                              \
                    }                                                                                                  \
                    ROWFLAG(C4E_EV_ROW + 2 * s->rctx[r] + s->rnz[r]);                                                  \
                }                                                                                                      \
        }                                                                                                              \
    } while (0)

/* The backward pass, scalar: states xs (magnitudes 0..15, signs 16..23). */
static void c4e_pass2_scalar(c4e_job *J, uint32_t xs[R4_NX], uint16_t **wpp, c4e_bitsw *bw)
{
    c4e_scratch *s = J->s;
    const wvc_rans_esym *es = s->es;
    const int raw = J->raw_signs;
    uint16_t *wp = *wpp;
#define C4E_FLAG_S(EV) (xs[0] = wvc_rans_enc_put(xs[0], &es[EV], &wp, R4_PBITS))
#define C4E_GROUP_S                                                                                                    \
    {                                                                                                                  \
        if (!raw) { /* the k-th non-zero's sign on state k mod 8, the last first */                                    \
            int k = __builtin_popcount(m);                                                                             \
            for (uint32_t r2 = m; r2;) {                                                                               \
                const int hi = 31 - __builtin_clz(r2);                                                                 \
                const int l = R4_TS + (--k & 7);                                                                      \
                const size_t x = x0 + (size_t)hi;                                                                      \
                xs[l] = wvc_rans_enc_put(xs[l], &es[C4E_EV_SIGN + 2 * SGr[x] + (c[x] < 0)], &wp, R4_PBITS);           \
                r2 &= ~(1u << hi);                                                                                     \
            }                                                                                                          \
        }                                                                                                              \
        for (size_t x = x1; x-- > x0;) c4e_coef_raw(bw, c[x], EVr[x] & 63u, raw);                                      \
        for (size_t x = x1; x-- > x0;) xs[x & 15] = wvc_rans_enc_put(xs[x & 15], &es[EVr[x]], &wp, R4_PBITS);        \
    }
    C4E_BACKWARD(C4E_GROUP_S, C4E_FLAG_S);
#undef C4E_GROUP_S
#undef C4E_FLAG_S
    *wpp = wp;
}

#ifdef R4_HAVE_AVX2
/* One encoder step on eight states x (lanes in act; the others unchanged) with the events ev:
 * the words of the lanes that renormalise stored below *wp in lane order. */
R4_AVX2_INLINE __m256i c4e_step8(__m256i x, __m256i ev, __m256i act, const c4e_scratch *s, uint16_t **wp)
{
    const __m256i P = _mm256_i32gather_epi32((const int *)s->pk, ev, 4);
    const __m256i MG = _mm256_i32gather_epi32((const int *)s->mg, ev, 4);
    const __m256i f = _mm256_and_si256(P, _mm256_set1_epi32(0x7FF));
    const __m256i R = _mm256_andnot_si256(_mm256_cmpgt_epi32(f, _mm256_srli_epi32(x, 32 - R4_PBITS)), act);
    const uint32_t rm = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(R));
    const __m256i pick = _mm256_setr_epi8(0, 1, 4, 5, 8, 9, 12, 13, -1, -1, -1, -1, -1, -1, -1, -1, 0, 1, 4, 5, 8, 9,
                                          12, 13, -1, -1, -1, -1, -1, -1, -1, -1);
    const __m128i w16 = _mm256_castsi256_si128(_mm256_permute4x64_epi64(_mm256_shuffle_epi8(x, pick), 0x08));
    __m256i y, t, q;
    _mm_storeu_si128((__m128i *)(*wp - 8), _mm_shuffle_epi8(w16, _mm_loadu_si128((const __m128i *)s->cmp[rm])));
    *wp -= _mm_popcnt_u32(rm);
    y = _mm256_blendv_epi8(x, _mm256_srli_epi32(x, 16), R);
    t = _mm256_blend_epi32(_mm256_srli_epi64(_mm256_mul_epu32(y, MG), 32),
                           _mm256_mul_epu32(_mm256_srli_epi64(y, 32), _mm256_srli_epi64(MG, 32)), 0xAA);
    q = _mm256_srlv_epi32(
        _mm256_add_epi32(t, _mm256_srlv_epi32(_mm256_sub_epi32(y, t),
                                              _mm256_and_si256(_mm256_srli_epi32(P, 26), _mm256_set1_epi32(1)))),
        _mm256_and_si256(_mm256_srli_epi32(P, 22), _mm256_set1_epi32(15)));
    y = _mm256_add_epi32(_mm256_add_epi32(y, _mm256_mullo_epi32(q, _mm256_sub_epi32(_mm256_set1_epi32(R4_M), f))),
                         _mm256_and_si256(_mm256_srli_epi32(P, 11), _mm256_set1_epi32(0x7FF)));
    return _mm256_blendv_epi8(x, y, act);
}


/* The raw bits of eight coefficients q (symbols in sym's low 6 bits), written backwards: merged
 * into one 64-bit field (offsets by a prefix sum of the lengths, 64-bit shifts) when they fit,
 * else one by one. */
R4_AVX2_INLINE void c4e_raw8(c4e_bitsw *bw, __m256i q, __m256i sym, int raw_signs)
{
    const __m256i one = _mm256_set1_epi32(1), zero = _mm256_setzero_si256();
    const __m256i S = _mm256_and_si256(sym, _mm256_set1_epi32(63));
    const __m256i K = _mm256_max_epi32(_mm256_sub_epi32(_mm256_srli_epi32(S, 1), one), zero);
    __m256i F = _mm256_and_si256(_mm256_abs_epi32(q), _mm256_sub_epi32(_mm256_sllv_epi32(one, K), one)), L = K, P, O;
    uint32_t total;
    if (raw_signs) {
        F = _mm256_or_si256(F, _mm256_sllv_epi32(_mm256_srli_epi32(q, 31), K));
        L = _mm256_sub_epi32(K, _mm256_xor_si256(_mm256_cmpeq_epi32(q, zero), _mm256_set1_epi32(-1)));
    }
    P = _mm256_add_epi32(L, _mm256_slli_si256(L, 4));
    P = _mm256_add_epi32(P, _mm256_slli_si256(P, 8));
    P = _mm256_add_epi32(P, _mm256_blend_epi32(zero, _mm256_permutevar8x32_epi32(P, _mm256_set1_epi32(3)), 0xF0));
    total = (uint32_t)_mm256_extract_epi32(P, 7);
    if (__builtin_expect(total <= 64, 1)) {
        O = _mm256_sub_epi32(P, L);
        const __m256i V = _mm256_or_si256(
            _mm256_sllv_epi64(_mm256_cvtepu32_epi64(_mm256_castsi256_si128(F)),
                              _mm256_cvtepu32_epi64(_mm256_castsi256_si128(O))),
            _mm256_sllv_epi64(_mm256_cvtepu32_epi64(_mm256_extracti128_si256(F, 1)),
                              _mm256_cvtepu32_epi64(_mm256_extracti128_si256(O, 1))));
        const __m128i h = _mm_or_si128(_mm256_castsi256_si128(V), _mm256_extracti128_si256(V, 1));
        const uint64_t v = (uint64_t)_mm_cvtsi128_si64(_mm_or_si128(h, _mm_unpackhi_epi64(h, h)));
        if (total > 32) {
            c4e_put_back(bw, (uint32_t)(v >> 32), total - 32);
            c4e_put_back(bw, (uint32_t)v, 32);
        } else {
            c4e_put_back(bw, (uint32_t)v, total);
        }
    } else {
        uint32_t f[8], l[8];
        _mm256_storeu_si256((__m256i *)f, F);
        _mm256_storeu_si256((__m256i *)l, L);
        for (int i = 8; i-- > 0;) c4e_put_back(bw, f[i], l[i]);
    }
}

/* The backward pass in vectors (extents multiples of 16): magnitude states 0..7 in X0, 8..15 in
 * X1, the sign states in T; the flags on X0's lane 0. */
R4_AVX2 static void c4e_pass2_avx2(c4e_job *J, uint32_t xs[R4_NX], uint16_t **wpp, c4e_bitsw *bw)
{
    c4e_scratch *s = J->s;
    const int raw = J->raw_signs;
    const __m256i all = _mm256_set1_epi32(-1), lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256i one = _mm256_set1_epi32(1);
    __m256i X0 = _mm256_loadu_si256((const __m256i *)xs), X1 = _mm256_loadu_si256((const __m256i *)(xs + 8));
    __m256i T = _mm256_loadu_si256((const __m256i *)(xs + R4_TS));
    uint16_t *wp = *wpp;
#define C4E_FLAG_V(EV) (X0 = r4v_set0(X0, wvc_rans_enc_put((uint32_t)_mm256_cvtsi256_si32(X0), &s->es[EV], &wp, R4_PBITS)))
#define C4E_GROUP_V                                                                                                    \
    {                                                                                                                  \
        const __m256i q0 = _mm256_loadu_si256((const __m256i *)(c + x0));                                              \
        const __m256i q1 = _mm256_loadu_si256((const __m256i *)(c + x0 + 8));                                          \
        const __m256i e0 = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(EVr + x0)));                        \
        const __m256i e1 = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(EVr + x0 + 8)));                    \
        if (!raw) { /* the sign events of the non-zeros in order: each half's compressed by a permutation, \
                     * the second's rotated behind the first's */                                                   \
            const __m256i zero = _mm256_setzero_si256(), base = _mm256_set1_epi32(C4E_EV_SIGN);                        \
            const __m256i g0 = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(SGr + x0)));                      \
            const __m256i g1 = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(SGr + x0 + 8)));                  \
            const uint32_t mlo = m & 255, mhi = m >> 8, nlo = (uint32_t)_mm_popcnt_u32(mlo);                            \
            const uint32_t nk = nlo + (uint32_t)_mm_popcnt_u32(mhi);                                                   \
            const __m256i c0 = _mm256_permutevar8x32_epi32(                                                            \
                _mm256_sub_epi32(_mm256_add_epi32(base, _mm256_add_epi32(g0, g0)), _mm256_cmpgt_epi32(zero, q0)),        \
                _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)s->cidx[mlo])));                                  \
            const __m256i c1 = _mm256_permutevar8x32_epi32(                                                            \
                _mm256_sub_epi32(_mm256_add_epi32(base, _mm256_add_epi32(g1, g1)), _mm256_cmpgt_epi32(zero, q1)),        \
                _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)s->cidx[mhi])));                                  \
            const __m256i n8 = _mm256_set1_epi32((int)nlo);                                                            \
            const __m256i r1 = _mm256_permutevar8x32_epi32(c1, _mm256_sub_epi32(lanes, n8));                           \
            if (nk > 8) T = c4e_step8(T, r1, _mm256_cmpgt_epi32(_mm256_set1_epi32((int)nk - 8), lanes), s, &wp);       \
            T = c4e_step8(T, _mm256_blendv_epi8(c0, r1, _mm256_cmpgt_epi32(lanes, _mm256_sub_epi32(n8, one))),         \
                          _mm256_cmpgt_epi32(_mm256_set1_epi32((int)nk), lanes), s, &wp);                              \
        }                                                                                                              \
        c4e_raw8(bw, q1, e1, raw);                                                                                     \
        c4e_raw8(bw, q0, e0, raw);                                                                                     \
        X1 = c4e_step8(X1, e1, all, s, &wp);                                                                           \
        X0 = c4e_step8(X0, e0, all, s, &wp);                                                                           \
    }
    C4E_BACKWARD(C4E_GROUP_V, C4E_FLAG_V);
#undef C4E_GROUP_V
#undef C4E_FLAG_V
    _mm256_storeu_si256((__m256i *)xs, X0);
    _mm256_storeu_si256((__m256i *)(xs + 8), X1);
    _mm256_storeu_si256((__m256i *)(xs + R4_TS), T);
    *wpp = wp;
}

#endif

/* The stream with `lead` bytes reserved before it; raw_req: -1 the per-chunk choice, else the
 * signs raw (1) or modelled (0); packed: the tables packed (else LEB128); scalar: the scalar
 * passes whatever the CPU. */
static int c4e_encode(uint8_t **buf, size_t *size, size_t lead, int n, int32_t *const Q[], const size_t *const p[],
                      const wvc_band *const b[], int raw_req, int packed, int scalar, void **slot, int *raw_out)
{
    c4e_job J;
    size_t total = 0, rows = 0, head, nw, nraw, pos;
    uint64_t tbits;
    double est_mod, est_raw;
    uint32_t xs[R4_NX];
    uint16_t *wp, *wend;
    c4e_bitsw bw;
    uint8_t *out;
    const size_t ex = n > 0 ? b[0]->ext[0] : 0;
    *buf = NULL;
    *size = 0;
    if (n < 1) return -1;
    for (int i = 0; i < n; i++) {
        if (b[i]->ext[0] != ex) return -1; /* one extent for every band */
        total += (size_t)b[i]->count;
        rows += b[i]->ext[1] * b[i]->ext[2];
    }
    memset(&J, 0, sizeof J);
    J.n = n, J.Q = Q, J.p = p, J.b = b;
    /* words: at most one per event (a magnitude and a sign per coefficient, flags), and a vector's
     * store below the last */
    J.s = c4e_scratch_get(slot, ex, rows, total, rows * ((ex + R4_GROUP - 1) / R4_GROUP),
                          2 * total + total / 8 + rows + 64, (30 * total + 7) / 8 + 16);
    if (!J.s) return -1;
#ifdef R4_HAVE_AVX2
    J.vec = !scalar && ex % R4_GROUP == 0 && r4_cpu_avx2();
#else
    (void)scalar;
#endif
    memset(J.s->cnt, 0, sizeof J.s->cnt);
    /* sign contexts are counted unless the signs are raw by request */
    c4e_pass1(&J, raw_req != 1);
    if (packed) {
        c4e_tables_packed(&J, raw_req != 1, &est_mod, &est_raw);
        J.raw_signs = raw_req < 0 ? c4e_keep_raw_signs(est_mod, est_raw) : raw_req;
        head = c4e_write_packed(&J);
    } else {
        head = c4e_tables(&J, raw_req != 1, &est_mod, &est_raw);
        J.raw_signs = raw_req < 0 ? c4e_keep_raw_signs(est_mod, est_raw) : raw_req;
        if (J.raw_signs && J.sglen) { /* the sign table was written for the estimate: drop it */
            memmove(J.s->head + J.sgoff, J.s->head + J.sgoff + J.sglen, head - J.sgoff - J.sglen);
            head -= J.sglen;
        }
    }
    if (raw_out) *raw_out = J.raw_signs;
    for (int e = 0; e < C4E_NEV; e++) c4e_vec_entry(&J.s->es[e], &J.s->pk[e], &J.s->mg[e]);
    /* the backward pass */
    tbits = J.sumk + (J.raw_signs ? J.nnz : 0);
    nraw = (size_t)((tbits + 7) / 8);
    bw.acc = 0;
    bw.n = (uint32_t)(8 * nraw - tbits);
    bw.p = J.s->rbuf + nraw;
    for (int l = 0; l < R4_NX; l++) xs[l] = R4_L;
    wend = wp = J.s->wbuf + J.s->words;
#ifdef R4_HAVE_AVX2
    if (J.vec)
        c4e_pass2_avx2(&J, xs, &wp, &bw);
    else
#endif
        c4e_pass2_scalar(&J, xs, &wp, &bw);
    if (bw.p != J.s->rbuf + bw.n / 8) return -1; /* the counts and the fields disagree: a bug */
    for (uint32_t k = 0; k < bw.n / 8; k++) /* the first bits, at positions 0 .. n - 1 */
        J.s->rbuf[k] = (uint8_t)(bw.acc >> (8 * k));
    nw = (size_t)(wend - wp);
    for (int l = 0; l < R4_NX; l++) memcpy(J.s->head + 4 * l, &xs[l], 4); /* little-endian, as the codec */
    /* from the reuse pool's middle tier: a chunk's payload is a few hundred KiB, made and freed
     * (by the writer, wvol__reuse_put) a few chunks at a time */
    out = wvol__reuse_get(lead + head + 20 + 2 * nw + nraw);
    if (!out) return -1;
    memcpy(out + lead, J.s->head, head);
    pos = lead + head;
    pos += wvc2_put_varint(out + pos, nw);
    pos += wvc2_put_varint(out + pos, nraw);
    memcpy(out + pos, wp, 2 * nw);
    pos += 2 * nw;
    memcpy(out + pos, J.s->rbuf, nraw);
    *buf = out;
    *size = pos + nraw;
    return 0;
}

/* The caller's scratch slot, or one for this call (freed by the caller's *own). */
static void **c4e_slot(wvc_rans_scratch *s, void **own) { return s ? &s->rans4 : own; }

int wvol__wvc_rans4_encode(uint8_t **buf, size_t *size, size_t lead, int n, int32_t *const Q[],
                           const size_t *const p[], const wvc_band *const b[], wvc_rans_scratch *s)
{
    void *own = NULL;
    int raw = 0, r = c4e_encode(buf, size, lead + 1, n, Q, p, b, -1, 1, 0, c4e_slot(s, &own), &raw);
    wvol__wvc_rans4_scratch_free(own);
    if (!r) (*buf)[lead] = (uint8_t)((raw ? 0 : R4_SIGNS_MODELLED) | R4_TABLES_PACKED);
    return r;
}

int wvol__wvc_rans4_encode_stream(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                                  const wvc_band *const b[], const wvc_rans4_opts *o)
{
    void *own = NULL;
    int r = c4e_encode(buf, size, 0, n, Q, p, b, o->raw_signs ? 1 : 0, o->packed_tables, o->scalar, &own, NULL);
    wvol__wvc_rans4_scratch_free(own);
    return r;
}
