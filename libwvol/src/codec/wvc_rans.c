/* SPDX-License-Identifier: MIT
 * Chunk mode 3 of .wvc version 2: the detail bands of one chunk coded with a static,
 * per-chunk model and table-driven rANS, for the high rates where the CABAC chain of
 * binary decisions (significance, unary length, second bit, sign: each waits on the
 * previous one's range and context update) is most of a decode.
 * Based on: J. Duda 2013 (asymmetric numeral systems); F. Giesen 2014 (rANS with
 * word renormalisation and interleaved streams, ryg_rans); the magnitude contexts are
 * those of the CABAC band coder (wvc_cabac.c: Wu 1997, Chrysafis & Ortega 2000).
 *
 * Per coefficient one magnitude symbol: 0 for q = 0, 1 for |q| = 1, 2n + b for |q| of
 * bit length n + 1 >= 2 with b the bit below the leading one (the first two bits of a
 * magnitude carry most of its information and are modelled; the n - 1 below go raw).
 * Its context: the bit length (capped at 12) of 2(|W|+|N|+|U|) + the six causal
 * diagonals, times the parent's class (0, 1, 2-3, 4+). Per non-zero coefficient one
 * sign symbol, context: band x the signs of W, N and U. In smooth data neighbouring
 * coefficients' signs follow the band's orientation (a static table over these 189
 * contexts takes fewer bits than CABAC's adaptive W/N sign contexts on the turbulence
 * field); in noise they cost a bit each, as raw.
 *
 * Three streams per band, so the decoder's chains do not wait on each other: magnitude
 * symbols (rANS), signs (a second rANS state), raw bits (little-endian, LSB first, read
 * with one unaligned 64-bit load). The decoder runs two bands in lockstep (a chunk's
 * bands share the tile's extent): each coefficient's context waits on its left
 * neighbour's value, a chain of two table loads, and two independent chains overlap.
 * Everything the contexts need from the rows already decoded (N, U, the diagonals, the
 * parent) is gathered per row in a vectorised pass; the serial loop adds W. The
 * decoder's table per magnitude context gives a slot's symbol, frequency and offset in
 * one 32-bit word; a sign is one compare against its context's frequency of '+'. The
 * encoder makes two passes: contexts, symbols and histograms, then the rANS streams in
 * reverse. Frequencies are normalised to 2^11: a 2^12 total took fewer than 0.01% fewer
 * bits and twice the decoder's table memory (an L2 cache's worth at 52 contexts).
 *
 * Payload (after the chunk's mode and band-mask bytes):
 *   for each of the 52 magnitude contexts: LEB128 n_sym (0: unused), then n_sym LEB128
 *     frequencies (the last non-zero), summing to 2^11;
 *   for each of the 189 sign contexts: LEB128 f+ + 1 (0: unused; f+ in 0..2^11);
 *   per band (the mask's order): LEB128 byte lengths of its magnitude, sign and raw
 *     streams;
 *   per band: the magnitude stream, the sign stream (each: 4-byte final state, then
 *     16-bit words), the raw bits (the last byte holds the last bit).
 * The decoder checks every table and length, that each rANS state ends where the
 * encoder began it with every word read, and that the raw bits end in their last byte. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "rans_common.h"
#include "wvc2_internal.h"

#define R3_NA 13              /* neighbourhood classes: bit length 0..12 */
#define R3_NP 4               /* parent classes */
#define R3_NC (R3_NA * R3_NP) /* magnitude contexts */
#define R3_NS 62              /* magnitude symbols: 0, 1, 2n + b for n = 1..30 */
#define R3_NSG (7 * 27)       /* sign contexts */
#define R3_RAWMAX 29          /* raw bits of a magnitude symbol, at most (symbol 61) */
#ifndef R3_PBITS
#define R3_PBITS 11
#endif
#define R3_M (1u << R3_PBITS)
#define R3_FSHIFT 6                  /* decoder table word: symbol (6 bits), */
#define R3_OSHIFT (7 + R3_PBITS)     /* frequency (R3_PBITS + 1 bits), slot - start */
#define R3_L (1u << 16) /* state in [L, 2^32): one 16-bit word per renormalisation */

#define FORCE_INLINE static inline __attribute__((always_inline))

static inline uint32_t r3_mag_ctx(uint32_t t, uint8_t pc)
{
    /* the bit length of t < 2^31, without a branch on t == 0 */
    uint32_t n = 31 - (uint32_t)__builtin_clz(2 * t + 1);
    return (n < R3_NA - 1 ? n : R3_NA - 1) * R3_NP + pc;
}

/* Per row: A[x], the context sum without W; PC[x] the parent class; SG[x] = 27 (band - 1)
 * + 9 sign(U) + sign(N), the sign context without W; all from rows decoded before.
 * zrow: ex zeros. */
typedef struct r3_row {
    uint32_t *A;
    uint8_t *PC, *SG;
} r3_row;

WVOL__CLONES static void r3_row_prep(const r3_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                        size_t z, const int32_t *zrow)
{
    const size_t sy = p[0], sz = p[0] * p[1], ex = b->ext[0];
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const int32_t *N = y > 0 ? c - sy : zrow, *U = z > 0 ? c - sz : zrow;
    const int sbase = 27 * (b->band - 1);
    const int32_t *UN = z > 0 && y > 0 ? c - sz - sy : zrow, *US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    uint32_t *restrict A = w->A;
    uint8_t *restrict SG = w->SG, *restrict PC = w->PC;
    size_t x;
    wvc_rans_row_sum(A, N, U, UN, US, ex);
    /* comparisons as 0/1, so the loops vectorise */
    for (x = 0; x < ex; x++)
        SG[x] = (uint8_t)(sbase + 9 * ((U[x] > 0) + 2 * (U[x] < 0)) + (N[x] > 0) + 2 * (N[x] < 0));
    if (!b->has_parent) {
        memset(PC, 0, ex);
        return;
    }
    wvc_rans_parent_classes(PC, wvc_rans_parent_row(Q, sy, sz, b, y, z), b->pext[0], ex);
}

static int r3_row_alloc(r3_row *w, int32_t **zrow, int n, const wvc_band *const b[])
{
    size_t ex = 1;
    for (int i = 0; i < n; i++)
        if (b[i]->ext[0] > ex) ex = b[i]->ext[0];
    w->A = malloc(2 * ex * sizeof *w->A); /* the encoder's first pass uses a second row */
    w->PC = malloc(2 * ex);
    *zrow = calloc(ex, sizeof **zrow);
    if (!w->A || !w->PC || !*zrow) {
        free(w->A);
        free(w->PC);
        free(*zrow);
        w->A = NULL;
        w->PC = NULL;
        *zrow = NULL;
        return -1;
    }
    w->SG = w->PC + ex;
    return 0;
}

static void r3_row_free(r3_row *w, int32_t *zrow)
{
    free(w->A);
    free(w->PC);
    free(zrow);
}

/* The decoder's per-symbol lookups (s < 64): base | mask of the raw bits << 32, and
 * the number of raw bits. */
static uint64_t r3_symtab[64];
static uint8_t r3_symraw[64];
static void r3_symtab_init(void)
{
    for (int s = 0; s < 64; s++) {
        int k = s < R3_NS ? wvc_rans_nraw(s) : 0;
        r3_symtab[s] = (s < R3_NS ? wvc_rans_base(s) : 0) | (uint64_t)((1u << k) - 1) << 32;
        r3_symraw[s] = (uint8_t)k;
    }
}

/* ---- frequency tables ---- */

/* Counts scaled and rounded, then the difference taken from (or given to)
 * the largest frequencies, which lose least by it. */
void wvol__wvc_rans_normalise(const uint32_t *cnt, int ns, uint32_t *f, uint32_t m)
{
    uint64_t total = 0;
    int64_t sum = 0;
    int s, big = -1;
    for (s = 0; s < ns; s++) total += cnt[s];
    for (s = 0; s < ns; s++) {
        f[s] = 0;
        if (!cnt[s]) continue;
        f[s] = (uint32_t)(((uint64_t)cnt[s] * m + total / 2) / total);
        if (f[s] == 0) f[s] = 1;
        sum += f[s];
        if (big < 0 || f[s] > f[big]) big = s;
    }
    if (sum <= (int64_t)m) {
        f[big] += (uint32_t)((int64_t)m - sum);
        return;
    }
    while (sum > (int64_t)m) {
        int l = -1;
        uint32_t take;
        for (s = 0; s < ns; s++)
            if (f[s] > 1 && (l < 0 || f[s] > f[l])) l = s;
        take = f[l] / 8 + 1; /* a share of the largest, so the loss spreads over the large ones */
        if (take > f[l] - 1) take = f[l] - 1;
        if (take > (uint32_t)(sum - (int64_t)m)) take = (uint32_t)(sum - (int64_t)m);
        f[l] -= take;
        sum -= take;
    }
}

uint32_t wvol__wvc_rans_binary_f(uint64_t n0, uint64_t n1, uint32_t m)
{
    uint64_t f;
    if (!n1) return m;
    if (!n0) return 0;
    f = (n0 * m + (n0 + n1) / 2) / (n0 + n1);
    return (uint32_t)(f < 1 ? 1 : f > m - 1 ? m - 1 : f);
}

int wvol__wvc_rans_get_varint(const uint8_t *buf, size_t size, size_t *pos, uint32_t *v)
{
    uint32_t r = 0;
    for (int shift = 0; shift < 35; shift += 7) {
        uint8_t c;
        if (*pos >= size) return -1;
        c = buf[(*pos)++];
        r |= (uint32_t)(c & 0x7F) << shift;
        if (!(c & 0x80)) {
            *v = r;
            return 0;
        }
    }
    return -1;
}

/* ---- encoder ---- */

typedef struct r3_enc {
    uint8_t *ctx, *sym, *sctx; /* per coefficient; sym bit 7: negative */
    uint32_t H[R3_NC][R3_NS];
    uint64_t S[R3_NSG][2];
    uint16_t *sg; /* per non-zero coefficient, in band order: 2 x sign context + negative */
    size_t nsg;   /* the current band's count of them */
    uint8_t *raw; /* the current band's raw bits */
} r3_enc;

/* One row of the encoder's first pass, in two loops without a chain (the encoder knows W
 * already; restrict parameters, so no overlap checks) that vectorise: 32-bit lengths
 * first (T: A[x] in, the bit length of the context sum out; N: |q|'s leading one), then
 * the bytes. K receives the raw bit count of each coefficient. */
__attribute__((noinline)) WVOL__CLONES static void r3_scan_row(uint8_t *restrict ctx, uint8_t *restrict sym,
                                                                uint8_t *restrict sctx, uint32_t *restrict T,
                                                                uint32_t *restrict N, const uint8_t *restrict PC,
                                                                const uint8_t *restrict SG,
                                                                const int32_t *restrict c, size_t ex)
{
    /* x = 0 (W = 0) after the loops: peeled before them, it keeps them from vectorising */
    for (size_t x = 1; x < ex; x++) {
        const int32_t v = c[x];
        const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v, big = a >= (1u << 24);
        /* |q| < 2^31: above 2^24 the length of a >> 8, plus 8 (exact, unlike a float of a) */
        N[x] = wvc_rans_bitlen24(big ? a >> 8 : a | 1) + 8 * big - 1;
        T[x] = wvc_rans_bitlen24(T[x] + 2 * wvc_rans_abs(c[x - 1])); /* the sum < 12 * 65535 */
    }
    for (size_t x = 1; x < ex; x++) {
        const int32_t v = c[x], W = c[x - 1];
        const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v, neg = v < 0, n = N[x];
        const uint32_t cls = T[x] < R3_NA - 1 ? T[x] : R3_NA - 1;
        const uint32_t sW = (uint32_t)(W > 0) + 2u * (uint32_t)(W < 0);
        ctx[x] = (uint8_t)(cls * R3_NP + PC[x]);
        sym[x] = (uint8_t)((a < 2 ? a : 2 * n + ((a >> (n - (n > 0))) & 1)) | neg << 7);
        sctx[x] = (uint8_t)(3 * sW + SG[x]);
        N[x] = n > 1 ? n - 1 : 0;
    }
    if (ex) {
        const int32_t v = c[0];
        const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v, neg = v < 0;
        const uint32_t n = 31 - (uint32_t)__builtin_clz(a | 1), na = wvc_rans_bitlen24(T[0]);
        ctx[0] = (uint8_t)((na < R3_NA - 1 ? na : R3_NA - 1) * R3_NP + PC[0]);
        sym[0] = (uint8_t)((a < 2 ? a : 2 * n + ((a >> (n - (n > 0))) & 1)) | neg << 7);
        sctx[0] = SG[0];
        N[0] = n > 1 ? n - 1 : 0;
    }
}

/* Pass 1 over one band: contexts, symbols (from index k on), counts, raw bits (into
 * e->raw, flushed to a whole byte at the end). Per row, a pass without a chain (the
 * encoder knows W already) gives every coefficient's context, symbol and raw bit count;
 * then a short serial pass counts them and packs the raw bits. */
WVOL__CLONES static void r3_scan_band(r3_enc *e, const int32_t *Q, const size_t p[3], const wvc_band *b,
                                      const r3_row *w, const int32_t *zrow, size_t k)
{
    const size_t ex = b->ext[0];
    size_t i = k;
    uint64_t acc = 0;
    int nacc = 0;
    uint8_t *raw = e->raw;
    uint16_t *sg = e->sg + k;
    size_t ns = 0;
    for (size_t z = 0; z < b->ext[2]; z++)
        for (size_t y = 0; y < b->ext[1]; y++, i += ex) {
            const int32_t *c = Q + wvc_index(p, b, 0, y, z);
            uint8_t *ctx = e->ctx + i, *sym = e->sym + i, *sctx = e->sctx + i;
            uint32_t *K = w->A + ex; /* the raw bit counts */
            r3_row_prep(w, Q, p, b, y, z, zrow);
            r3_scan_row(ctx, sym, sctx, w->A, K, w->PC, w->SG, c, ex);
            for (size_t x = 0; x < ex; x++) {
                const int32_t v = c[x];
                const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v, kk = K[x];
                e->H[ctx[x]][sym[x] & 0x7F]++;
                e->S[sctx[x]][sym[x] >> 7] += a != 0;
                sg[ns] = (uint16_t)(2 * sctx[x] + (sym[x] >> 7)); /* kept for a non-zero */
                ns += a != 0;
                /* raw bits: a 32-bit word is stored when due (always written, kept when due) */
                acc |= (uint64_t)(a & ((1u << kk) - 1)) << nacc;
                nacc += (int)kk;
                {
                    const uint32_t lo = (uint32_t)acc;
                    const int due = nacc >= 32;
                    memcpy(raw, &lo, 4);
                    raw += 4 * due;
                    acc >>= 32 * due;
                    nacc -= 32 * due;
                }
            }
        }
    while (nacc > 0) { /* the last partial word, byte by byte */
        *raw++ = (uint8_t)acc;
        acc >>= 8;
        nacc -= 8;
    }
    e->raw = raw;
    e->nsg = ns;
}

/* G bands (i .. i + G - 1, the same count of coefficients) in lockstep, so that their
 * chains overlap: the magnitude streams over every coefficient, then the sign streams over
 * the non-zero ones (a zero's sign step is the identity, frequency 2^11: it changes
 * neither state nor stream, and is left out). Each stream in reverse, so that the
 * decoder reads it forward. ES1: the sign symbols by 2 x context + negative. */
FORCE_INLINE void r3_enc_group(const int G, const r3_enc *e, const wvc_rans_esym (*E)[R3_NS], const wvc_rans_esym *ES1,
                               const size_t *first, const size_t *nsg, int i, uint16_t **mp, uint16_t **sp,
                               uint32_t *xm_out, uint32_t *xs_out)
{
    const size_t cnt = first[i + 1] - first[i];
    uint32_t xm[4], xs[4];
    size_t nmax = 0;
#pragma GCC unroll 4
    for (int b = 0; b < G; b++) {
        xm[b] = xs[b] = R3_L;
        nmax = nsg[i + b] > nmax ? nsg[i + b] : nmax;
    }
    for (size_t j = cnt; j-- > 0;) {
#pragma GCC unroll 4
        for (int b = 0; b < G; b++) {
            const size_t jj = first[i + b] + j;
            xm[b] = wvc_rans_enc_put(xm[b], &E[e->ctx[jj]][e->sym[jj] & 0x7F], &mp[i + b], R3_PBITS);
        }
    }
    for (size_t k = nmax; k-- > 0;) {
#pragma GCC unroll 4
        for (int b = 0; b < G; b++)
            if (k < nsg[i + b]) xs[b] = wvc_rans_enc_put(xs[b], &ES1[e->sg[first[i + b] + k]], &sp[i + b], R3_PBITS);
    }
#pragma GCC unroll 4
    for (int b = 0; b < G; b++) xm_out[b] = xm[b], xs_out[b] = xs[b];
}

void wvol__wvc_rans_scratch_free(wvc_rans_scratch *s)
{
    if (!s) return;
    for (int k = 0; k < 5; k++) free(s->p[k]);
    wvol__wvc_zstd_scratch_free(&s->zstd);
    wvol__wvc_rans4_scratch_free(s->rans4);
    memset(s, 0, sizeof *s);
}

/* Buffer k of s, at least bytes long (its contents not kept). */
static void *r3_scratch(wvc_rans_scratch *s, int k, size_t bytes)
{
    if (bytes > s->cap[k]) {
        free(s->p[k]);
        s->p[k] = wvol__malloc_pages(&bytes); /* kept, so their first touches are paid once */
        s->cap[k] = s->p[k] ? bytes : 0;
    }
    return s->p[k];
}

int wvol__wvc_rans_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                          const wvc_band *const b[], wvc_rans_scratch *s)
{
    wvc_rans_scratch own = {0};
    r3_enc *e = NULL;
    r3_row w = {0};
    int32_t *zrow = NULL;
    uint32_t (*F)[R3_NS] = NULL, SF[R3_NSG];
    wvc_rans_esym (*E)[R3_NS] = NULL, (*ES)[2] = NULL;
    uint8_t *raw = NULL, *out = NULL;
    uint16_t *ms = NULL, *ss = NULL;
    uint16_t *mp[8], *sp[8];
    uint8_t *rp[8];
    size_t total = 0, first[9], mlen[8], slen[8], rlen[8], nsg[8], head = 0, body = 0;
    int ok = 0;
    *buf = NULL;
    *size = 0;
    for (int i = 0; i < n; i++) first[i] = total, total += (size_t)b[i]->count;
    first[n] = total;
    e = calloc(1, sizeof *e);
    F = calloc(R3_NC, sizeof *F);
    E = calloc(R3_NC, sizeof *E);
    ES = calloc(R3_NSG, sizeof *ES);
    /* per band: at most 29 raw bits per coefficient; at most one word per symbol and the state */
    if (!s) s = &own;
    raw = r3_scratch(s, 0, 4 * total + 8 * (size_t)n + 8);
    ms = r3_scratch(s, 1, 2 * (total + 4 * (size_t)n));
    ss = r3_scratch(s, 2, 2 * (total + 4 * (size_t)n));
    if (!e || !F || !E || !ES || !raw || !ms || !ss || r3_row_alloc(&w, &zrow, n, b)) goto done;
    e->ctx = r3_scratch(s, 3, 3 * (total ? total : 1));
    e->sg = r3_scratch(s, 4, sizeof *e->sg * (total ? total : 1));
    if (!e->ctx || !e->sg) goto done;
    e->sym = e->ctx + total;
    e->sctx = e->sym + total;
    for (int i = 0; i < n; i++) {
        rp[i] = e->raw = raw + 4 * first[i] + 8 * (size_t)i;
        r3_scan_band(e, Q[i], p[i], b[i], &w, zrow, first[i]);
        rlen[i] = (size_t)(e->raw - rp[i]);
        nsg[i] = e->nsg;
    }
    for (int c = 0; c < R3_NC; c++) {
        uint32_t any = 0, cum = 0;
        for (int s = 0; s < R3_NS; s++) any |= e->H[c][s];
        if (!any) continue;
        wvol__wvc_rans_normalise(e->H[c], R3_NS, F[c], R3_M);
        for (int s = 0; s < R3_NS; s++) E[c][s] = wvc_rans_esym_make(F[c][s], cum), cum += F[c][s];
    }
    for (int c = 0; c < R3_NSG; c++) {
        SF[c] = e->S[c][0] | e->S[c][1] ? wvol__wvc_rans_binary_f(e->S[c][0], e->S[c][1], R3_M) : 0;
        ES[c][0] = wvc_rans_esym_make(SF[c], 0);
        ES[c][1] = wvc_rans_esym_make(R3_M - SF[c], SF[c]);
    }
    for (int i = 0; i < n; i++) {
        mp[i] = ms + first[i + 1] + 4 * (size_t)(i + 1);
        sp[i] = ss + first[i + 1] + 4 * (size_t)(i + 1);
    }
    /* four bands at a time (a chunk's bands have the same count) */
    for (int i = 0; i < n; i += 4) {
        const int G = n - i < 4 ? n - i : 4;
        uint16_t *mend[4], *send[4];
        uint32_t xm[4], xs[4];
        for (int l = 0; l < G; l++) mend[l] = mp[i + l], send[l] = sp[i + l];
        switch (G) {
        case 4: r3_enc_group(4, e, E, &ES[0][0], first, nsg, i, mp, sp, xm, xs); break;
        case 3: r3_enc_group(3, e, E, &ES[0][0], first, nsg, i, mp, sp, xm, xs); break;
        case 2: r3_enc_group(2, e, E, &ES[0][0], first, nsg, i, mp, sp, xm, xs); break;
        default: r3_enc_group(1, e, E, &ES[0][0], first, nsg, i, mp, sp, xm, xs); break;
        }
        for (int l = 0; l < G; l++) {
            mp[i + l] -= 2;
            memcpy(mp[i + l], &xm[l], 4); /* little-endian hosts only, as the rest of the codec */
            sp[i + l] -= 2;
            memcpy(sp[i + l], &xs[l], 4);
            mlen[i + l] = 2 * (size_t)(mend[l] - mp[i + l]);
            slen[i + l] = 2 * (size_t)(send[l] - sp[i + l]);
            body += mlen[i + l] + slen[i + l] + rlen[i + l];
        }
    }
    out = malloc((size_t)R3_NC * (1 + 2 * R3_NS) + 2 * R3_NSG + 15 * (size_t)n + body);
    if (!out) goto done;
    for (int c = 0; c < R3_NC; c++) {
        int ns = 0;
        for (int s = 0; s < R3_NS; s++)
            if (F[c][s]) ns = s + 1;
        head += wvc2_put_varint(out + head, (uint32_t)ns);
        for (int s = 0; s < ns; s++) head += wvc2_put_varint(out + head, F[c][s]);
    }
    for (int c = 0; c < R3_NSG; c++)
        head += wvc2_put_varint(out + head, e->S[c][0] | e->S[c][1] ? SF[c] + 1 : 0);
    for (int i = 0; i < n; i++) {
        head += wvc2_put_varint(out + head, (uint32_t)mlen[i]);
        head += wvc2_put_varint(out + head, (uint32_t)slen[i]);
        head += wvc2_put_varint(out + head, (uint32_t)rlen[i]);
    }
    for (int i = 0; i < n; i++) {
        memcpy(out + head, mp[i], mlen[i]);
        memcpy(out + head + mlen[i], sp[i], slen[i]);
        memcpy(out + head + mlen[i] + slen[i], rp[i], rlen[i]);
        head += mlen[i] + slen[i] + rlen[i];
    }
    *buf = out;
    *size = head;
    ok = 1;
done:
    wvol__wvc_rans_scratch_free(&own);
    free(e);
    free(F);
    free(E);
    free(ES);
    if (w.A) r3_row_free(&w, zrow);
    return ok ? 0 : -1;
}

/* ---- decoder ---- */

/* One band's decoder state: its streams, copied with zero padding of a row's worth of
 * reads past their ends (a coefficient takes at most one word from each rANS stream and
 * R3_RAWMAX raw bits), so that the per-coefficient step reads without bounds checks: the
 * lockstep loop checks after every row that no stream was read past its end (an error),
 * and the caller afterwards that exactly everything was read. */
typedef struct r3_lane {
    int32_t *Q;
    const size_t *p;
    const wvc_band *b;
    r3_row w;
    int32_t *zrow;
    uint16_t *mw, *sw; /* words after the state */
    size_t mn, sn, mpos, spos;
    uint8_t *raw; /* rawbytes + the padding */
    size_t rawbytes;
    uint64_t bitpos, count;
    uint32_t xm, xs, over;
} r3_lane;

/* Renormalisation, at most one word: shifts and masks, no branch (whether a word is
 * due is hard to predict). w is padded (r3_lane_open). */
static inline uint32_t r3_renorm(uint32_t x, const uint16_t *w, size_t *pos)
{
    const uint32_t r = x < R3_L;
    const uint32_t v = w[*pos];
    *pos += r;
    return (x << (r << 4)) | (v & (0u - r));
}

/* The model: magnitude tables for every context side by side (slot -> symbol |
 * frequency << R3_FSHIFT | (slot - start) << R3_OSHIFT; an unused context's part is
 * never written, and its bit in `unused` is set), the frequencies of '+' per sign
 * context with one more entry, 2^11, for zeros. */
typedef struct r3_tabs {
    uint32_t *flat;
    uint64_t unused;
    uint32_t SF[R3_NSG + 1];
} r3_tabs;

/* A lane's running state, kept in registers by the lockstep loop. */
typedef struct r3_hot {
    uint32_t xm, xs, over, aW, sW;
    size_t mpos, spos;
    uint64_t bitpos, count;
} r3_hot;

/* One coefficient of a lane: *c from the streams; h->aW, h->sW: its left neighbour's |q|
 * (capped) and sign class, updated. Returns 0, or -1 when its context has no table. The
 * non-zeros and the range of the magnitudes are counted and checked per row, afterwards
 * (r3_row_check), not in the chain. */
FORCE_INLINE int r3_step(const r3_lane *L, r3_hot *h, const r3_tabs *T, int32_t *c, size_t x)
{
    const uint32_t cx = r3_mag_ctx(L->w.A[x] + 2 * h->aW, L->w.PC[x]);
    uint32_t e, s, nzm, f0, slot, neg, a, k, bits;
    uint64_t word, st;
    e = T->flat[cx * R3_M + (h->xm & (R3_M - 1))];
    s = e & 63;
    h->xm = (e >> R3_FSHIFT & (2 * R3_M - 1)) * (h->xm >> R3_PBITS) + (e >> R3_OSHIFT);
    h->xm = r3_renorm(h->xm, L->mw, &h->mpos);
    /* the sign: an identity step (entry R3_NSG: frequency 2^11) for a zero; masks, not
     * branches, as a zero is hard to predict */
    nzm = 0u - (uint32_t)(s != 0);
    f0 = T->SF[((3 * h->sW + L->w.SG[x]) & nzm) | (R3_NSG & ~nzm)];
    slot = h->xs & (R3_M - 1);
    neg = slot >= f0;
    {
        const uint32_t nm = 0u - neg;
        h->xs = (f0 ^ ((f0 ^ (R3_M - f0)) & nm)) * (h->xs >> R3_PBITS) + slot - (f0 & nm);
    }
    h->xs = r3_renorm(h->xs, L->sw, &h->spos);
    /* the raw bits: one unaligned load (the stream is padded) */
    st = r3_symtab[s];
    k = r3_symraw[s];
    memcpy(&word, L->raw + (h->bitpos >> 3), 8);
    bits = (uint32_t)(word >> (h->bitpos & 7)) & (uint32_t)(st >> 32);
    h->bitpos += k;
    a = (uint32_t)st | bits;
    *c = (int32_t)((a ^ (0u - neg)) + neg); /* a < 2^31: |*c| = a */
    h->aW = a > 65535 ? 65535 : a;
    h->sW = (s != 0) + neg; /* neg is 0 for a zero */
    return (int)(T->unused >> cx & 1);
}

/* A decoded row: its non-zeros added to h->count, h->over set if a magnitude passes
 * WVC_QMAX (a vectorised pass: the row is in L1). */
static inline void r3_row_check(r3_hot *h, const int32_t *restrict c, size_t ex)
{
    uint64_t nz = 0;
    uint32_t over = 0;
    for (size_t x = 0; x < ex; x++) {
        const uint32_t a = c[x] < 0 ? (uint32_t)0 - (uint32_t)c[x] : (uint32_t)c[x];
        nz += c[x] != 0;
        over |= a > WVC_QMAX;
    }
    h->count += nz;
    h->over |= over;
}

static inline void r3_hot_in(r3_hot *h, const r3_lane *L)
{
    h->xm = L->xm, h->xs = L->xs, h->over = L->over, h->mpos = L->mpos, h->spos = L->spos;
    h->bitpos = L->bitpos, h->count = L->count;
}

static inline void r3_hot_out(const r3_hot *h, r3_lane *L)
{
    L->xm = h->xm, L->xs = h->xs, L->over = h->over, L->mpos = h->mpos, L->spos = h->spos;
    L->bitpos = h->bitpos, L->count = h->count;
}

/* K (1 or 2) lanes in lockstep over their bands' rows (same extent). */
FORCE_INLINE int r3_lanes(int K, r3_lane *L, const r3_tabs *T, const char **why)
{
    const wvc_band *b = L[0].b;
    const size_t ex = b->ext[0];
    r3_hot h0, h1;
    int r = 0;
    r3_hot_in(&h0, &L[0]);
    if (K == 2) r3_hot_in(&h1, &L[1]);
    for (size_t z = 0; z < b->ext[2] && !r; z++)
        for (size_t y = 0; y < b->ext[1] && !r; y++) {
            int32_t *c0 = L[0].Q + wvc_index(L[0].p, L[0].b, 0, y, z), *c1 = NULL;
            r3_row_prep(&L[0].w, L[0].Q, L[0].p, L[0].b, y, z, L[0].zrow);
            if (K == 2) {
                c1 = L[1].Q + wvc_index(L[1].p, L[1].b, 0, y, z);
                r3_row_prep(&L[1].w, L[1].Q, L[1].p, L[1].b, y, z, L[1].zrow);
            }
            h0.aW = h0.sW = h1.aW = h1.sW = 0;
            for (size_t x = 0; x < ex; x++) {
                int bad = r3_step(&L[0], &h0, T, c0 + x, x);
                if (K == 2) bad |= r3_step(&L[1], &h1, T, c1 + x, x);
                if (__builtin_expect(bad, 0)) {
                    *why = "symbol in a context without a table";
                    r = -1;
                    break;
                }
            }
            r3_row_check(&h0, c0, ex);
            if (K == 2) r3_row_check(&h1, c1, ex);
            /* past a stream's end: the next row's reads could pass the padding */
            if (!r && (h0.over || h0.bitpos > 8 * (uint64_t)L[0].rawbytes || h0.mpos > L[0].mn ||
                       h0.spos > L[0].sn ||
                       (K == 2 && (h1.over || h1.bitpos > 8 * (uint64_t)L[1].rawbytes || h1.mpos > L[1].mn ||
                                   h1.spos > L[1].sn)))) {
                *why = h0.over || (K == 2 && h1.over) ? "magnitude out of range" : "coded data ends early";
                r = -1;
            }
        }
    r3_hot_out(&h0, &L[0]);
    if (K == 2) r3_hot_out(&h1, &L[1]);
    return r;
}

WVOL__CLONES static int r3_lanes2(r3_lane *lanes, const r3_tabs *T, const char **why)
{
    return r3_lanes(2, lanes, T, why);
}

WVOL__CLONES static int r3_lanes1(r3_lane *lanes, const r3_tabs *T, const char **why)
{
    return r3_lanes(1, lanes, T, why);
}

/* Copies a band's streams from src (lengths already checked against the payload), each
 * with zeros after it for the reads of one row of ex coefficients past its end. */
static int r3_lane_open(r3_lane *L, const uint8_t *src, size_t mlen, size_t slen, size_t rlen, size_t ex)
{
    L->mn = (mlen - 4) / 2;
    L->sn = (slen - 4) / 2;
    L->rawbytes = rlen;
    L->mw = calloc(L->mn + ex + 1, sizeof *L->mw);
    L->sw = calloc(L->sn + ex + 1, sizeof *L->sw);
    L->raw = calloc(rlen + (R3_RAWMAX * ex + 7) / 8 + 8, 1);
    if (!L->mw || !L->sw || !L->raw) return -1;
    memcpy(&L->xm, src, 4);
    memcpy(L->mw, src + 4, 2 * L->mn);
    memcpy(&L->xs, src + mlen, 4);
    memcpy(L->sw, src + mlen + 4, 2 * L->sn);
    memcpy(L->raw, src + mlen + slen, rlen);
    return 0;
}

int wvol__wvc_rans_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                          const uint8_t *buf, size_t size, uint64_t *nonzero, const char **why)
{
    r3_lane lane[8];
    r3_tabs T;
    uint32_t len[8][3];
    uint16_t freq[R3_NC][R3_NS];
    int ns[R3_NC], r = -1, i;
    size_t pos = 0;
    static pthread_once_t once = PTHREAD_ONCE_INIT;
    *nonzero = 0;
    memset(lane, 0, sizeof lane);
    T.flat = NULL;
    T.unused = 0;
    pthread_once(&once, r3_symtab_init);
    for (int c = 0; c < R3_NC; c++) {
        uint32_t v, sum = 0;
        if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > R3_NS) {
            *why = "malformed frequency table";
            return -1;
        }
        ns[c] = (int)v;
        for (int s = 0; s < ns[c]; s++) {
            if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > R3_M) {
                *why = "malformed frequency table";
                return -1;
            }
            freq[c][s] = (uint16_t)v;
            sum += v;
        }
        if (ns[c] && (sum != R3_M || freq[c][ns[c] - 1] == 0)) {
            *why = "frequency table does not sum to 2^11";
            return -1;
        }
        if (!ns[c]) T.unused |= (uint64_t)1 << c;
    }
    for (int c = 0; c < R3_NSG; c++) {
        uint32_t v;
        if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > R3_M + 1) {
            *why = "malformed sign table";
            return -1;
        }
        /* an unused context reads as all '+': a valid stream never decodes a sign there,
         * and a damaged one is caught by the end-of-stream checks */
        T.SF[c] = v ? v - 1 : R3_M;
    }
    T.SF[R3_NSG] = R3_M;
    {
        size_t rest;
        for (i = 0; i < n; i++)
            for (int k = 0; k < 3; k++)
                if (wvol__wvc_rans_get_varint(buf, size, &pos, &len[i][k])) {
                    *why = "malformed stream lengths";
                    return -1;
                }
        rest = size - pos;
        for (i = 0; i < n; i++) {
            if (len[i][0] < 4 || len[i][1] < 4 || (len[i][0] & 1) || (len[i][1] & 1) || len[i][0] > rest ||
                len[i][1] > rest - len[i][0] || len[i][2] > rest - len[i][0] - len[i][1]) {
                *why = "malformed stream lengths";
                return -1;
            }
            rest -= (size_t)len[i][0] + len[i][1] + len[i][2];
        }
        if (rest) {
            *why = "stream lengths do not add up to the chunk";
            return -1;
        }
    }
    /* pages of unused contexts are never touched */
    T.flat = calloc((size_t)R3_NC * R3_M, sizeof *T.flat);
    if (!T.flat) {
        *why = "out of memory";
        goto done;
    }
    for (int c = 0; c < R3_NC; c++) {
        uint32_t *t = T.flat + (size_t)c * R3_M, cum = 0;
        for (int s = 0; s < ns[c]; s++) {
            for (uint32_t k = 0; k < freq[c][s]; k++) t[cum + k] = (uint32_t)s | (uint32_t)freq[c][s] << R3_FSHIFT | k << R3_OSHIFT;
            cum += freq[c][s];
        }
    }
    for (i = 0; i < n; i++) {
        r3_lane *L = &lane[i];
        L->Q = Q[i];
        L->p = p[i];
        L->b = b[i];
        if (b[i]->band < 1 || b[i]->band > 7 || (i && b[i]->ext[0] != b[0]->ext[0]) ||
            (i && (b[i]->ext[1] != b[0]->ext[1] || b[i]->ext[2] != b[0]->ext[2]))) {
            *why = "chunk mode 3 needs detail bands of one extent";
            goto done;
        }
        if (r3_row_alloc(&L->w, &L->zrow, 1, &b[i]) || r3_lane_open(L, buf + pos, len[i][0], len[i][1], len[i][2], b[i]->ext[0])) {
            *why = "out of memory";
            goto done;
        }
        if (L->xm < R3_L || L->xs < R3_L) {
            *why = "rANS state out of range";
            goto done;
        }
        pos += (size_t)len[i][0] + len[i][1] + len[i][2];
    }
    for (i = 0; i + 1 < n; i += 2)
        if (r3_lanes2(&lane[i], &T, why)) goto done;
    if (i < n && r3_lanes1(&lane[i], &T, why)) goto done;
    for (i = 0; i < n; i++) {
        const r3_lane *L = &lane[i];
        if (L->xm != R3_L || L->xs != R3_L || L->mpos != L->mn || L->spos != L->sn) {
            *why = L->mpos > L->mn || L->spos > L->sn ? "coded data ends early"
                                                      : "rANS streams do not end where they should";
            goto done;
        }
        if (L->bitpos > 8 * (uint64_t)L->rawbytes || 8 * (uint64_t)L->rawbytes - L->bitpos >= 8) {
            *why = L->bitpos > 8 * (uint64_t)L->rawbytes ? "coded data ends early"
                                                         : "raw bits do not end where they should";
            goto done;
        }
        *nonzero += L->count;
    }
    r = 0;
done:
    free(T.flat);
    for (i = 0; i < n; i++) {
        free(lane[i].mw);
        free(lane[i].sw);
        free(lane[i].raw);
        if (lane[i].w.A) r3_row_free(&lane[i].w, lane[i].zrow);
    }
    return r;
}
