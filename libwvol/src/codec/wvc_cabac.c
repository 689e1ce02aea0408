/* SPDX-License-Identifier: MIT
 * Context-adaptive binary coding of one sub-band of quantised wavelet coefficients.
 * Based on: Shapiro 1993 (zerotrees: an insignificant parent predicts insignificant
 * children); Wu 1997 / Chrysafis & Ortega 2000 (context modelling of wavelet
 * coefficients from causal neighbours); Marpe, Schwarz & Wiegand 2003 (CABAC:
 * binarisation, significance flag, unary + exp-Golomb magnitude, bypass signs).
 *
 * A detail band is visited in 2x2x2 groups, the children of one parent coefficient
 * (same band, next coarser level). Per group one flag says whether any child is
 * non-zero; its context is the parent's magnitude (or, for a zero parent, how many
 * of the parent's six neighbours are non-zero) and how many of the three causal
 * neighbour groups were non-zero. Inside a non-zero group each coefficient gets a
 * significance flag (context: parent class x non-zero causal neighbours; the last
 * one is implied when the others are zero), then |q| >= 2, |q| >= 3 flags and an
 * exp-Golomb remainder with adaptive prefix contexts (context: magnitude of causal
 * neighbours and parent), then a raw sign bit. The low-pass cube codes the residual
 * of the 3D Lorenzo predictor with the same magnitude binarisation. The `blocks`
 * variant (version-2 chunk mode 2) puts a flag per 4x4x4 block before the group flags
 * (block_row): zero blocks, most of a fine level at low rates, are then passed over
 * whole. Based on: Pearlman, Islam, Nagaraj & Said 2004 (SPECK: set partitioning of
 * the insignificant coefficients).
 *
 * One body serves both directions: `dec` is a compile-time constant at each call,
 * so encoder and decoder share every context decision by construction. */
#include <stdlib.h>

#include "core/clones.h"
#include "rangecoder.h"
#include "wvc_internal.h"

#define NPC 6   /* parent classes: 0..2 zero parent (0, 1-2, 3+ non-zero neighbours), 3: |p|=1, 4: |p|>=2, 5: none */
#define NMC 16  /* magnitude classes: bit length of a weighted neighbourhood magnitude */
#define NLEN 40 /* longest magnitude bit length */

#define NBC 4 /* block parent classes: all 8 parents 0, max |p| = 1, max |p| >= 2, none */

typedef struct band_model {
    rc_ctx block[NBC * 4];
    rc_ctx group[NPC * 4];
    rc_ctx sig[NPC * 4 * 4];
    rc_ctx len[NMC][NLEN + 1];  /* unary bit length of |q| */
    rc_ctx sub[NMC][NLEN + 1];  /* the bit below the leading one */
    rc_ctx sign[9];
    rc_ctx lsig[NMC];
} band_model;

typedef struct coder {
    rc_enc *e;
    rc_dec *d;
    uint64_t nz; /* decoder: non-zero values written, so no caller counts them in another pass */
} coder;

#define FORCE_INLINE static inline __attribute__((always_inline))

#ifdef WVC_STATS
#include <math.h>
double wvc_stat_bits[8];
int wvc_stat_cat;
#define STAT_CAT(k) (wvc_stat_cat = (k))
#else
#define STAT_CAT(k) ((void)0)
#endif
FORCE_INLINE int code_bit(int dec, coder *c, rc_ctx *ctx, int bit)
{
#ifdef WVC_STATS
    if (!dec) { double p0 = rc_ctx_p0(ctx) / 65536.0; wvc_stat_bits[wvc_stat_cat] -= log2(bit ? 1 - p0 : p0); }
#endif
    if (dec) return rc_dec_bit(c->d, ctx);
    rc_enc_bit(c->e, ctx, bit);
    return bit;
}

FORCE_INLINE uint64_t code_direct(int dec, coder *c, uint64_t v, int n)
{
    uint64_t out = 0;
    while (n > 0) {
        int k = n > 24 ? 24 : n;
        n -= k;
#ifdef WVC_STATS
        if (!dec) wvc_stat_bits[wvc_stat_cat] += k;
#endif
        if (dec) {
            out = (out << k) | rc_dec_direct(c->d, k);
        } else {
            rc_enc_direct(c->e, (uint32_t)((v >> n) & ((1u << k) - 1)), k);
        }
    }
    return dec ? out : v;
}

/* Bit length of a weighted neighbourhood sum, the magnitude context. */
static inline int mag_class(uint32_t t)
{
    int n = t ? 32 - __builtin_clz(t) : 0;
    return n < NMC ? n : NMC - 1;
}

/* |value| >= 1 as its bit length n + 1 (unary, adaptive per class and position),
 * the bit below the leading one (adaptive), the rest raw. At most max_len + 1 bits
 * of magnitude. Returns 0 on a malformed code (decoder). */
FORCE_INLINE uint64_t code_mag(int dec, coder *c, band_model *m, int mc, uint64_t a, int max_len)
{
    int n = 0, i;
    uint64_t v;
    rc_ctx *len = m->len[mc];
    if (!dec) n = 63 - __builtin_clzll(a);
    for (i = 0;; i++) {
        if (!code_bit(dec, c, &len[i < NLEN ? i : NLEN], i < n)) break;
        if (i + 1 > max_len) return 0;
    }
    n = i;
    if (n == 0) return 1;
    v = (uint64_t)1 << n;
    if (code_bit(dec, c, &m->sub[mc][n < NLEN ? n : NLEN], (int)((a >> (n - 1)) & 1))) v |= (uint64_t)1 << (n - 1);
    if (n > 1) v |= code_direct(dec, c, a & (((uint64_t)1 << (n - 1)) - 1), n - 1);
    return v;
}

static inline int sign_of(int32_t v) { return v > 0 ? 1 : v < 0 ? 2 : 0; }

static inline uint32_t absq(int32_t v)
{
    uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
    return a > 65535 ? 65535 : a;
}

/* Parent class (see NPC) and |parent| of the groups g0..g1-1 of the group row (gj, gk)
 * (a row has gx groups), written to pc[g0..g1) and P[g0..g1). A group's parent is its
 * index clamped to the parent band; rows and columns outside the parent band count as
 * zero (the pointer then aims at the parent row itself and the flag masks it out). */
WVOL__CLONES static void parent_row(const int32_t *Q, const size_t p[3], const wvc_band *b, size_t gx, size_t g0, size_t g1,
                       size_t gj, size_t gk, uint8_t *pc, uint32_t *P)
{
    const ptrdiff_t sy = (ptrdiff_t)p[0], sz = (ptrdiff_t)(p[0] * p[1]);
    size_t pj, pk, gi, pe = b->pext[0];
    const int32_t *pr, *rN, *rS, *rD, *rU;
    int fN, fS, fD, fU;
    if (!b->has_parent) {
        memset(pc + g0, 5, g1 - g0);
        memset(P + g0, 0, (g1 - g0) * sizeof *P);
        return;
    }
    pj = gj < b->pext[1] ? gj : b->pext[1] - 1;
    pk = gk < b->pext[2] ? gk : b->pext[2] - 1;
    pr = Q + b->poff[0] + (size_t)sy * (b->poff[1] + pj) + (size_t)sz * (b->poff[2] + pk);
    fN = pj > 0, fS = pj + 1 < b->pext[1], fD = pk > 0, fU = pk + 1 < b->pext[2];
    rN = fN ? pr - sy : pr, rS = fS ? pr + sy : pr, rD = fD ? pr - sz : pr, rU = fU ? pr + sz : pr;
    for (gi = g0; gi < g1; gi++) {
        size_t pi = gi < pe ? gi : pe - 1;
        uint32_t v;
        int pn;
        if (pi > 0 && pi + 1 < pe && gi + 1 < gx) {
            /* interior: no bounds to test along x, so the loop runs without branches */
            size_t end = (gx < pe ? gx : pe) - 1;
            if (end > g1) end = g1;
            for (; gi < end; gi++) {
                v = absq(pr[gi]);
                pn = (pr[gi - 1] != 0) + (pr[gi + 1] != 0) + (fN & (rN[gi] != 0)) + (fS & (rS[gi] != 0)) +
                     (fD & (rD[gi] != 0)) + (fU & (rU[gi] != 0));
                P[gi] = v;
                pc[gi] = (uint8_t)(v >= 2 ? 4 : v == 1 ? 3 : pn == 0 ? 0 : pn <= 2 ? 1 : 2);
            }
            gi--;
            continue;
        }
        v = absq(pr[pi]);
        pn = (pi > 0 && pr[pi - 1] != 0) + (pi + 1 < pe && pr[pi + 1] != 0) + (fN & (rN[pi] != 0)) +
             (fS & (rS[pi] != 0)) + (fD & (rD[pi] != 0)) + (fU & (rU[pi] != 0));
        P[gi] = v;
        pc[gi] = (uint8_t)(v >= 2 ? 4 : v == 1 ? 3 : pn == 0 ? 0 : pn <= 2 ? 1 : 2);
    }
}

/* Encoder: whether each 2x2x2 group of the group row starting at (y, z) holds a non-zero. */
WVOL__CLONES static void any_row(const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y, size_t z, size_t gx,
                    uint8_t *any)
{
    const size_t ex = b->ext[0];
    const int32_t *r0 = Q + wvc_index(p, b, 0, y, z);
    const int32_t *r1 = y + 1 < b->ext[1] ? r0 + p[0] : r0, *r2 = z + 1 < b->ext[2] ? r0 + p[0] * p[1] : r0;
    const int32_t *r3 = y + 1 < b->ext[1] ? r2 + p[0] : r2;
    size_t gi, full = ex / 2; /* groups with two columns; an odd extent leaves one of one */
    for (gi = 0; gi < full; gi++) {
        size_t x = 2 * gi;
        any[gi] = ((r0[x] | r1[x] | r2[x] | r3[x]) | (r0[x + 1] | r1[x + 1] | r2[x + 1] | r3[x + 1])) != 0;
    }
    if (full < gx) any[full] = (r0[2 * full] | r1[2 * full] | r2[2 * full] | r3[2 * full]) != 0;
}

/* The next group at or after g in [0, gx) whose state is non-zero (gx if none). */
static inline size_t next_group(const uint8_t *grow, size_t g, size_t gx)
{
    uint64_t w;
    while (g + 8 <= gx) {
        memcpy(&w, grow + g, 8);
        /* the first non-zero byte of the eight: its index from the word's zero bits */
#if __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
        if (w) return g + (size_t)(__builtin_ctzll(w) >> 3);
#else
        if (w) return g + (size_t)(__builtin_clzll(w) >> 3);
#endif
        g += 8;
    }
    while (g < gx && !grow[g]) g++;
    return g;
}

/* Block flags (the `blocks` variant of detail_band): one flag per block of 2x2x2 groups
 * (4x4x4 coefficients, fewer at the band's far edges) says whether any of its
 * coefficients is non-zero; the flags of a block row (bj, bk) are all coded before its
 * coefficients. Context: the block's parents (the parents of its groups: all zero,
 * max |p| = 1, max |p| >= 2, or none at the coarsest level) x its non-zero causal
 * neighbour blocks (W, N, U). A zero block then costs one decision instead of eight group
 * flags, and the decoder skips it without computing its parents' classes: at low rates
 * most of a fine level is such blocks (SPECK's insight: code the many zeros as sets).
 * The encoder's bany (bx bytes) receives which blocks of the row hold a non-zero. */
FORCE_INLINE void block_row(int dec, coder *cd, band_model *m, const int32_t *Q, const size_t p[3],
                            const wvc_band *b, size_t bj, size_t bk, size_t bx, size_t by, uint8_t *bstate,
                            uint8_t *bany)
{
    const size_t ex = b->ext[0], ey = b->ext[1], ez = b->ext[2];
    const size_t gx = (ex + 1) / 2, gy = (ey + 1) / 2, gz = (ez + 1) / 2;
    uint8_t *brow = bstate + bx * (bj + by * bk);
    const uint8_t *bN = bj > 0 ? brow - bx : NULL, *bU = bk > 0 ? brow - bx * by : NULL;
    size_t bi;
    if (!dec) {
        const size_t z1 = 4 * bk + 4 < ez ? 4 * bk + 4 : ez, y1 = 4 * bj + 4 < ey ? 4 * bj + 4 : ey;
        const size_t full = ex / 4;
        memset(bany, 0, bx);
        for (size_t z = 4 * bk; z < z1; z++)
            for (size_t y = 4 * bj; y < y1; y++) {
                const int32_t *r = Q + wvc_index(p, b, 0, y, z);
                for (bi = 0; bi < full; bi++) bany[bi] |= (r[4 * bi] | r[4 * bi + 1] | r[4 * bi + 2] | r[4 * bi + 3]) != 0;
                for (size_t x = 4 * full; x < ex; x++) bany[full] |= r[x] != 0;
            }
    }
    for (bi = 0; bi < bx; bi++) {
        int cls = NBC - 1, nb;
        if (b->has_parent) {
            const size_t *pe = b->pext;
            uint32_t mx = 0;
            for (size_t gk = 2 * bk; gk < 2 * bk + 2 && gk < gz; gk++)
                for (size_t gj = 2 * bj; gj < 2 * bj + 2 && gj < gy; gj++) {
                    size_t pj = gj < pe[1] ? gj : pe[1] - 1, pk = gk < pe[2] ? gk : pe[2] - 1;
                    const int32_t *pr = Q + b->poff[0] + p[0] * ((b->poff[1] + pj) + p[1] * (b->poff[2] + pk));
                    for (size_t gi = 2 * bi; gi < 2 * bi + 2 && gi < gx; gi++) {
                        uint32_t v = absq(pr[gi < pe[0] ? gi : pe[0] - 1]);
                        mx = v > mx ? v : mx;
                    }
                }
            cls = mx == 0 ? 0 : mx == 1 ? 1 : 2;
        }
        nb = (bi > 0 && brow[bi - 1]) + (bN && bN[bi]) + (bU && bU[bi]);
        STAT_CAT(4);
        brow[bi] = (uint8_t)code_bit(dec, cd, &m->block[cls * 4 + nb], dec ? 0 : bany[bi]);
    }
}

/* Group states: 0 all zero, 1 non-zero with no non-zero child coded yet, 2 one seen.
 * With `blocks`, block states likewise: 0 zero, 1 non-zero with no non-zero group coded
 * yet (the last group of such a block is non-zero by implication), 2 one seen. */
FORCE_INLINE int detail_band(int dec, int blocks, coder *cd, int32_t *Q, const size_t p[3], const wvc_band *b,
                             band_model *m, uint8_t *gstate)
{
    const size_t ex = b->ext[0], ey = b->ext[1], ez = b->ext[2];
    const size_t gx = (ex + 1) / 2, gy = (ey + 1) / 2, gz = (ez + 1) / 2;
    const size_t bx = (gx + 1) / 2, by = (gy + 1) / 2;
    const ptrdiff_t sy = (ptrdiff_t)p[0], sz = (ptrdiff_t)(p[0] * p[1]);
    const size_t ngroups = gx * gy * gz;
    /* the parent class and |parent| of the current slab of groups, computed at first touch */
    uint32_t *gP = (uint32_t *)(void *)(gstate + ((ngroups + 7) & ~(size_t)7));
    uint8_t *gpc = (uint8_t *)(gP + gx * gy), *gany = gpc + gx * gy;
    uint8_t *bstate = gany + gx, *bany = bstate + bx * by * ((gz + 1) / 2);
    /* a row of zeros (x from -1 to ex) that stands in for a neighbour row outside the band */
    int32_t *zr = (int32_t *)(void *)(((uintptr_t)(bany + bx) + 15) & ~(uintptr_t)15) + 1;
    size_t x, y, z;
    /* a group of a zero block is never touched: its state must read zero */
    if (blocks) memset(gstate, 0, ngroups);
    memset(zr - 1, 0, (ex + 2) * sizeof *zr);
    for (z = 0; z < ez; z++)
        for (y = 0; y < ey; y++) {
            const size_t gk = z >> 1, gj = y >> 1;
            uint8_t *grow = gstate + gx * (gj + gy * gk);
            uint8_t *brow = blocks ? bstate + bx * ((y >> 2) + by * (z >> 2)) : NULL;
            int32_t *row = Q + wvc_index(p, b, 0, y, z);
            const int first = (y & 1) == 0 && (z & 1) == 0;
            /* the neighbour rows N (y - 1), U (z - 1) and U's rows y -+ 1: the zero row where
             * the band has none */
            const int32_t *rN = y > 0 ? row - sy : zr, *rU = z > 0 ? row - sz : zr;
            const int32_t *rUN = z > 0 && y > 0 ? row - sz - sy : zr, *rUS = z > 0 && y + 1 < ey ? row - sz + sy : zr;
            if (blocks && (y & 3) == 0 && (z & 3) == 0) block_row(dec, cd, m, Q, p, b, y >> 2, z >> 2, bx, by, bstate, bany);
            if (dec && y + 2 < ey && (!blocks || next_group(brow, 0, bx) < bx)) {
                /* the decoder's stores and neighbour loads meet rows of a large array that are
                 * cold: ask for the row two ahead while this one is decoded, unless this row's
                 * blocks are all zero (a sparse band's rows are mostly such: never touched) */
                const char *ahead = (const char *)(row + 2 * sy);
                for (size_t o = 0; o < ex * sizeof *row; o += 64) __builtin_prefetch(ahead + o, 1, 3);
            }
            if (first) {
                if (!blocks) {
                    parent_row(Q, p, b, gx, 0, gx, gj, gk, gpc + gx * gj, gP + gx * gj);
                } else {
                    /* only the groups of non-zero blocks are ever coded: their parents alone */
                    size_t b0 = 0, b1;
                    while ((b0 = next_group(brow, b0, bx)) < bx) {
                        for (b1 = b0 + 1; b1 < bx && brow[b1]; b1++) {
                        }
                        parent_row(Q, p, b, gx, 2 * b0, 2 * b1 < gx ? 2 * b1 : gx, gj, gk, gpc + gx * gj,
                                   gP + gx * gj);
                        b0 = b1;
                    }
                }
                if (!dec) any_row(Q, p, b, y, z, gx, gany);
            }
            for (x = 0; x < ex; x++) {
                const size_t gi = x >> 1;
                int32_t *c = row + x;
                uint32_t P, dsum;
                int32_t vW, vN, vU, v[6];
                int pc, sig, a, dn;
                uint64_t mag;
                if (first && (x & 1) == 0) {
                    /* first touch of the group: its flag */
                    int any = dec ? 0 : gany[gi], gn;
                    if (blocks && !brow[gi >> 1]) {
                        /* a zero block: on to the next non-zero one (its groups stay zero) */
                        x = 4 * next_group(brow, (gi >> 1) + 1, bx) - 1;
                        continue;
                    }
                    gn = (gi > 0 && grow[gi - 1]) + (gj > 0 && grow[(ptrdiff_t)gi - (ptrdiff_t)gx]) +
                         (gk > 0 && grow[(ptrdiff_t)gi - (ptrdiff_t)(gx * gy)]);
                    pc = gpc[gi + gx * gj];
                    if (blocks && brow[gi >> 1] == 1 && (gi == gx - 1 || (gi & 1)) && (gj == gy - 1 || (gj & 1)) &&
                        (gk == gz - 1 || (gk & 1))) {
                        any = 1; /* the last group of a non-zero block whose others are all zero */
                    } else {
                        STAT_CAT(0);
                        any = code_bit(dec, cd, &m->group[pc * 4 + gn], any);
                    }
                    grow[gi] = (uint8_t)any;
                    if (blocks && any) brow[gi >> 1] = 2;
                }
                if (!grow[gi]) {
                    if (first) {
                        x |= 1; /* the group's other column is zero too */
                    } else {
                        size_t g = next_group(grow, gi + 1, gx); /* flags were coded: skip to a non-zero group */
                        x = 2 * g - 1;
                    }
                    continue;
                }
                pc = gpc[gi + gx * gj];
                /* the neighbours' values (0 outside the band); the significance context needs
                 * only which are non-zero, the magnitudes only for a significant one */
                vW = x > 0 ? c[-1] : 0;
                vN = rN[x];
                vU = rU[x];
                v[0] = x > 0 ? rN[x - 1] : 0;
                v[1] = x + 1 < ex ? rN[x + 1] : 0;
                v[2] = x > 0 ? rU[x - 1] : 0;
                v[3] = x + 1 < ex ? rU[x + 1] : 0;
                v[4] = rUN[x];
                v[5] = rUS[x];
                {
                    /* the last child of a non-zero group whose others are all zero is non-zero */
                    int last = (x == ex - 1 || (x & 1)) && (y == ey - 1 || (y & 1)) && (z == ez - 1 || (z & 1));
                    if (last && grow[gi] == 1) {
                        sig = 1;
                    } else {
                        dn = (v[0] != 0) + (v[1] != 0) + (v[2] != 0) + (v[3] != 0) + (v[4] != 0) + (v[5] != 0);
                        a = (vW != 0) + (vN != 0) + (vU != 0);
                        STAT_CAT(1);
                        sig = code_bit(dec, cd, &m->sig[(pc * 4 + a) * 4 + (dn > 3 ? 3 : dn)], *c != 0);
                    }
                }
                if (!sig) continue;
                grow[gi] = 2;
                if (dec) cd->nz++;
                STAT_CAT(2);
                mag = dec ? 0 : *c < 0 ? (uint64_t)(-(int64_t)*c) : (uint64_t)*c;
                P = gP[gi + gx * gj];
                dsum = absq(v[0]) + absq(v[1]) + absq(v[2]) + absq(v[3]) + absq(v[4]) + absq(v[5]);
                mag = code_mag(dec, cd, m, mag_class(2 * (absq(vW) + absq(vN) + absq(vU)) + dsum + 4 * P), mag, 30);
                STAT_CAT(3);
                {
                    rc_ctx *sc = &m->sign[3 * sign_of(vW) + sign_of(vN)];
                    if (dec) {
                        if (mag == 0 || mag > WVC_QMAX) return -1;
                        *c = code_bit(dec, cd, sc, 0) ? -(int32_t)mag : (int32_t)mag;
                    } else {
                        code_bit(dec, cd, sc, *c < 0);
                    }
                }
            }
        }
    return 0;
}

FORCE_INLINE int lowpass_band(int dec, coder *cd, int32_t *Q, const size_t p[3], const wvc_band *b,
                              band_model *m, uint16_t *R)
{
    const size_t ex = b->ext[0], ey = b->ext[1], ez = b->ext[2];
    size_t x, y, z, i = 0;
    for (z = 0; z < ez; z++)
        for (y = 0; y < ey; y++)
            for (x = 0; x < ex; x++, i++) {
                int32_t *c = Q + wvc_index(p, b, x, y, z);
                int64_t pred = wvc_lorenzo(Q, p, b, x, y, z), r = dec ? 0 : (int64_t)*c - pred;
                uint32_t s = (x ? R[i - 1] : 0) + (y ? R[i - ex] : 0) + (z ? R[i - ex * ey] : 0);
                int mc = mag_class(4 * s);
                uint64_t mag = 0;
                if (code_bit(dec, cd, &m->lsig[mc], r != 0)) {
                    mag = code_mag(dec, cd, m, mc, r < 0 ? (uint64_t)(-r) : (uint64_t)r, 36);
                    if (dec) {
                        int neg;
                        if (mag == 0) return -1;
                        neg = (int)code_direct(dec, cd, 0, 1);
                        r = neg ? -(int64_t)mag : (int64_t)mag;
                        if (r + pred > WVC_QMAX || r + pred < -(int64_t)WVC_QMAX) return -1;
                        *c = (int32_t)(r + pred);
                        cd->nz += *c != 0;
                    } else {
                        code_direct(dec, cd, r < 0, 1);
                    }
                } else if (dec) {
                    if (pred > WVC_QMAX || pred < -(int64_t)WVC_QMAX) return -1;
                    *c = (int32_t)pred;
                    cd->nz += *c != 0;
                }
                R[i] = (uint16_t)(mag > 65535 ? 65535 : mag);
            }
    return 0;
}

static void model_init(band_model *m)
{
    rc_ctx_init((rc_ctx *)m, (int)(sizeof *m / sizeof(rc_ctx)));
}

/* detail_band's scratch: group states, a slab of parent classes and magnitudes, the
 * encoder's group row flags, block states, the encoder's block row flags and a row of zeros
 * (detail_band's zr) */
static int band_scratch(const wvc_band *b, void **scratch)
{
    size_t g[3], bl[3];
    for (int a = 0; a < 3; a++) g[a] = (b->ext[a] + 1) / 2, bl[a] = (g[a] + 1) / 2;
    size_t gxy = g[0] * g[1], ng = gxy * g[2];
    size_t n = b->band == 0 ? (size_t)b->count * sizeof(uint16_t)
                             : ((ng + 7) & ~(size_t)7) + gxy * 5 + g[0] + bl[0] * bl[1] * bl[2] + bl[0] + 16 +
                                   (b->ext[0] + 2) * sizeof(int32_t);
    *scratch = malloc(n ? n : 1);
    return *scratch ? 0 : -1;
}

int wvol__wvc_cabac_encode(uint8_t **buf, size_t *size, const int32_t *Q, const size_t p[3],
                           const wvc_band *b)
{
    int32_t *q = (int32_t *)Q; /* the encoder only reads it */
    const size_t *pp = p;
    return wvol__wvc_cabac_encode_multi(buf, size, 1, &q, &pp, &b, 0);
}

int wvol__wvc_cabac_decode(int32_t *Q, const size_t p[3], const wvc_band *b, const uint8_t *buf,
                           size_t size, const char **why)
{
    const size_t *pp = p;
    return wvol__wvc_cabac_decode_multi(1, &Q, &pp, &b, buf, size, 0, NULL, why);
}

/* Several bands in one stream with one model that keeps adapting from band to band: a
 * version-2 chunk's bands are small, and one model learns once instead of per band
 * (a fixed prior for the flags instead of 1/2 did not help). */
WVOL__CLONES int wvol__wvc_cabac_encode_multi(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                                 const wvc_band *const b[], int blocks)
{
    rc_enc e;
    coder cd = {&e, NULL, 0};
    band_model m;
    const uint8_t *data;
    size_t len;
    int failed = 0;
    *buf = NULL;
    *size = 0;
    model_init(&m);
    rc_enc_init(&e);
    for (int i = 0; i < n && !failed; i++) {
        void *scratch;
        if (band_scratch(b[i], &scratch)) {
            failed = 1;
            break;
        }
        if (b[i]->band == 0)
            lowpass_band(0, &cd, Q[i], p[i], b[i], &m, scratch);
        else if (blocks)
            detail_band(0, 1, &cd, Q[i], p[i], b[i], &m, scratch);
        else
            detail_band(0, 0, &cd, Q[i], p[i], b[i], &m, scratch);
        free(scratch);
    }
    rc_enc_finish(&e);
    if (e.oom || failed) {
        rc_enc_free(&e);
        return -1;
    }
    data = rc_enc_data(&e, &len);
    memmove(e.buf, data, len);
    *buf = e.buf;
    *size = len;
    return 0;
}

int wvol__wvc_cabac_decode_multi(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                                 const uint8_t *buf, size_t size, int blocks, uint64_t *nonzero, const char **why)
{
    rc_dec d;
    coder cd = {NULL, &d, 0};
    band_model m;
    int r = 0;
    model_init(&m);
    rc_dec_init(&d, buf, size);
    for (int i = 0; i < n && !r; i++) {
        void *scratch;
        if (band_scratch(b[i], &scratch)) {
            *why = "out of memory";
            return -1;
        }
        if (b[i]->band == 0)
            r = lowpass_band(1, &cd, Q[i], p[i], b[i], &m, scratch);
        else if (blocks)
            r = detail_band(1, 1, &cd, Q[i], p[i], b[i], &m, scratch);
        else
            r = detail_band(1, 0, &cd, Q[i], p[i], b[i], &m, scratch);
        free(scratch);
    }
    if (r) {
        *why = "malformed coefficient code";
        return -1;
    }
    if (d.overrun) {
        *why = "coded data ends early";
        return -1;
    }
    if (nonzero) *nonzero = cd.nz;
    return 0;
}
