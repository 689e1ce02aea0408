/* SPDX-License-Identifier: MIT
 * Prototype chunk coder ("mode 4"), for bench_chunkcoder.c (bench/results/chunkcoder.md):
 * the detail bands of a chunk with a static per-chunk model as chunk mode 3
 * (codec/wvc_rans.c), but
 *  - contexts from the rows decoded before only (N, U, their x neighbours, the diagonals
 *    U +- y, the parent): computed per row before its symbols, so that nothing in the
 *    symbol loop waits on the left neighbour;
 *  - twelve rANS states over one stream of 16-bit words: coefficient x's magnitude on
 *    state x mod 8, the k-th non-zero sign of a group on state 8 + k mod 4, the flags on
 *    state 0;
 *  - a flag per row (any non-zero; context from the flags of the rows N, U, the diagonal
 *    rows above and the parent row) and in a non-zero row one per group of G coefficients
 *    (context: the group's neighbourhood sum and parent classes; the last one implied when
 *    the others are zero): a zero row costs one binary step and no context pass;
 *  - magnitudes as mode 3's symbols (0, 1, 2n + b) and raw bits below; signs raw (in the
 *    raw bits after each magnitude) or after each group's magnitudes, for its non-zeros,
 *    with a binary model (band x sign(N) x sign(U), x sign(N(x-1)) with comp & 1).
 * Payload: 12 final states (4 bytes each), 52 magnitude tables (LEB128 n_sym, then the
 * frequencies, summing to 2^10), the group-flag entries (LEB128 f0 + 1, 0 unused), the sign
 * entries when modelled (same), the row-flag entries (same), LEB128 word count and raw byte
 * count, the words, the raw bits (LSB first). The checks are a prototype's: tables, lengths,
 * the final states, the streams' ends and each row's range; enough for the benchmark's round
 * trips, not the fuzzing a chunk mode needs. */
#include "chunk4.h"

#include "codec/rans_common.h"
#include "codec/wvc2_internal.h"

#include <stdlib.h>
#include <string.h>

#define C4_NA 13
#define C4_NP 4
#define C4_NC (C4_NA * C4_NP)
#define C4_NS 62
#define C4_NGA 8
#define C4_NG (C4_NGA * C4_NP)
#define C4_NSG 63
#define C4_NSGW (3 * C4_NSG) /* with W's sign (encoder-only variant) */
#define C4_PBITS 10
#define C4_M (1u << C4_PBITS)
#define C4_FSHIFT 6
#define C4_OSHIFT (7 + C4_PBITS)
#define C4_L (1u << 16)
#define C4_RAWMAX 30 /* raw bits of one coefficient: 29 and a sign */
/* encoder event numbers: magnitudes ctx * NS + sym, then flags, then signs */
#define C4_EV_FLAG (C4_NC * C4_NS)
#define C4_EV_SIGN (C4_EV_FLAG + 2 * C4_NG)
#define C4_NR 12 /* row flag contexts */
#define C4_EV_ROW (C4_EV_SIGN + 2 * C4_NSGW)
#define C4_NEV (C4_EV_ROW + 2 * C4_NR)

#define FORCE_INLINE static inline __attribute__((always_inline))

static inline uint32_t c4_abs(int32_t v)
{
    uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
    return a > 65535 ? 65535 : a;
}

static inline uint32_t c4_bitlen(uint32_t t) { return 31 - (uint32_t)__builtin_clz(2 * t + 1); }

/* Per row: CX[x] the magnitude context, SG[x] the sign context, GX[g] the flag context. */
typedef struct c4_row {
    uint32_t *A;
    uint8_t *CX, *PC, *SG, *GX;
} c4_row;

WVOL__CLONES static void c4_row_prep(const c4_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b,
                                     size_t y, size_t z, const int32_t *zrow, int gs, int signs, int comp)
{
    const size_t sy = p[0], sz = p[0] * p[1], ex = b->ext[0];
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const int32_t *N = y > 0 ? c - sy : zrow, *U = z > 0 ? c - sz : zrow;
    const int32_t *UN = z > 0 && y > 0 ? c - sz - sy : zrow, *US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    const int sbase = 9 * (b->band - 1);
    uint32_t *restrict A = w->A;
    uint8_t *restrict PC = w->PC, *restrict CX = w->CX, *restrict SG = w->SG;
    size_t x;
    for (x = 0; x < ex; x++) A[x] = 2 * (c4_abs(N[x]) + c4_abs(U[x])) + c4_abs(UN[x]) + c4_abs(US[x]);
    for (x = 1; x < ex; x++) A[x] += c4_abs(N[x - 1]) + c4_abs(U[x - 1]);
    for (x = 0; x + 1 < ex; x++) A[x] += c4_abs(N[x + 1]) + c4_abs(U[x + 1]);
    if (comp & 2) {
        const int32_t *NN = y > 1 ? c - 2 * sy : zrow, *UU = z > 1 ? c - 2 * sz : zrow;
        for (x = 0; x < ex; x++) A[x] += c4_abs(NN[x]) + c4_abs(UU[x]);
    }
    if (signs) /* the sign contexts, when the signs are modelled */
        for (x = 0; x < ex; x++) SG[x] = (uint8_t)(sbase + 3 * ((U[x] > 0) + 2 * (U[x] < 0)) + (N[x] > 0) + 2 * (N[x] < 0));
    if (signs && (comp & 1))
        for (x = 1; x < ex; x++) SG[x] = (uint8_t)(SG[x] + C4_NSG * ((N[x - 1] > 0) + 2 * (N[x - 1] < 0)));
    if (!b->has_parent) {
        memset(PC, 0, ex);
    } else {
        const size_t pe = b->pext[0];
        size_t pj = y >> 1, pk = z >> 1, half = ex >> 1 < pe ? ex >> 1 : pe;
        const int32_t *pr;
        if (pj >= b->pext[1]) pj = b->pext[1] - 1;
        if (pk >= b->pext[2]) pk = b->pext[2] - 1;
        pr = Q + b->poff[0] + sy * (b->poff[1] + pj) + sz * (b->poff[2] + pk);
        if (comp & 4) /* 2|p| + its x neighbours */
            for (x = 0; x < half; x++) {
                uint32_t a = 2 * c4_abs(pr[x]) + (x ? c4_abs(pr[x - 1]) : 0) + (x + 1 < pe ? c4_abs(pr[x + 1]) : 0);
                uint8_t k = (uint8_t)((a > 0) + (a > 2) + (a > 6));
                PC[2 * x] = k;
                PC[2 * x + 1] = k;
            }
        else
            for (x = 0; x < half; x++) {
                uint32_t a = c4_abs(pr[x]);
                uint8_t k = (uint8_t)((a > 0) + (a > 1) + (a > 3));
                PC[2 * x] = k;
                PC[2 * x + 1] = k;
            }
        for (x = 2 * half; x < ex; x++) {
            uint32_t a = c4_abs(pr[(x >> 1) < pe ? x >> 1 : pe - 1]);
            PC[x] = (uint8_t)((a > 0) + (a > 1) + (a > 3));
        }
    }
    for (x = 0; x < ex; x++) {
        uint32_t n = wvc_rans_bitlen24(A[x]);
        CX[x] = (uint8_t)((n < C4_NA - 1 ? n : C4_NA - 1) * C4_NP + PC[x]);
    }
    if (gs == 16 && ex % 16 == 0) { /* fixed trip counts, so that the sums vectorise */
        for (size_t g = 0; g < ex / 16; g++) {
            uint32_t s = 0, pm = 0, n;
            for (x = 0; x < 16; x++) s += A[16 * g + x], pm |= PC[16 * g + x];
            n = c4_bitlen(s);
            pm = pm > 3 ? 3 : pm; /* OR of classes 0..3: 3 when 1 and 2 meet, an upper bound */
            w->GX[g] = (uint8_t)((n < C4_NGA - 1 ? n : C4_NGA - 1) * C4_NP + pm);
        }
        return;
    }
    for (size_t g = 0, x0 = 0; x0 < ex; g++, x0 += (size_t)gs) {
        size_t x1 = x0 + (size_t)gs < ex ? x0 + (size_t)gs : ex;
        uint32_t s = 0, pm = 0, n;
        for (x = x0; x < x1; x++) s += A[x], pm |= PC[x];
        n = c4_bitlen(s);
        pm = pm > 3 ? 3 : pm;
        w->GX[g] = (uint8_t)((n < C4_NGA - 1 ? n : C4_NGA - 1) * C4_NP + pm);
    }
}

static int c4_row_alloc(c4_row *w, int32_t **zrow, size_t ex)
{
    w->A = malloc(ex * sizeof *w->A);
    w->CX = malloc(4 * ex + 8);
    *zrow = calloc(ex, sizeof **zrow);
    if (!w->A || !w->CX || !*zrow) return -1;
    w->PC = w->CX + ex;
    w->SG = w->PC + ex;
    w->GX = w->SG + ex;
    return 0;
}

static void c4_row_free(c4_row *w, int32_t *zrow)
{
    free(w->A);
    free(w->CX);
    free(zrow);
}

/* The context of row (y, z)'s flag: whether the rows N and U are non-zero, either diagonal
 * row above (U +- y), the parent row. rnz: the band's row flags so far, y fastest. */
static inline uint32_t c4_row_ctx(const uint8_t *rnz, const int32_t *Q, const size_t p[3], const wvc_band *b,
                                  size_t y, size_t z, uint32_t *plast)
{
    const size_t ey = b->ext[1];
    const uint8_t *u = rnz + (z - 1) * ey + y;
    uint32_t n = y ? rnz[z * ey + y - 1] : 0, up = z ? u[0] : 0, d = 0, pr = 0;
    if (z) d = (y ? u[-1] : 0) | (y + 1 < ey ? u[1] : 0);
    if (y & 1) {
        pr = *plast; /* row y - 1 had the same parent row */
    } else if (b->has_parent) {
        size_t pj = y >> 1, pk = z >> 1;
        const int32_t *r;
        int32_t o = 0;
        if (pj >= b->pext[1]) pj = b->pext[1] - 1;
        if (pk >= b->pext[2]) pk = b->pext[2] - 1;
        r = Q + b->poff[0] + p[0] * (b->poff[1] + pj) + p[0] * p[1] * (b->poff[2] + pk);
        if (pj + 2 < b->pext[1]) /* the parent rows are a level decoded long before: fetch ahead */
            for (size_t x = 0; x < b->pext[0]; x += 16) __builtin_prefetch(r + 2 * p[0] + x);
        for (size_t x = 0; x < b->pext[0]; x++) o |= r[x];
        pr = o != 0;
    }
    *plast = pr;
    return ((n + up) * 2 + d) * 2 + pr;
}

/* ---- encoder ---- */

uint64_t c4_stats[4]; /* rows, non-zero rows, non-zero groups, events */

int c4_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
              const wvc_band *const b[], const c4_opts *o)
{
    const int gs = o->group;
    const size_t ex = b[0]->ext[0];
    size_t total = 0, nev = 0, head = 0;
    uint16_t *ev = NULL, *words = NULL, *wp;
    uint8_t *lane = NULL, *raw = NULL, *rp, *out = NULL;
    uint32_t (*H)[C4_NS] = calloc(C4_NC, sizeof *H), F[C4_NS];
    uint64_t G[C4_NG][2], S[C4_NSGW][2], R[C4_NR][2];
    uint8_t *rnz = NULL;
    uint32_t plast = 0;
    wvc_rans_esym *E = calloc(C4_NEV, sizeof *E);
    c4_row w = {0};
    int32_t *zrow = NULL;
    uint64_t acc = 0;
    int nacc = 0, ok = 0;
    uint32_t xs[12], GF[C4_NG], SF[C4_NSGW];
    const int nsg = o->with_w || (o->comp & 1) ? C4_NSGW : C4_NSG;
    memset(G, 0, sizeof G);
    memset(S, 0, sizeof S);
    memset(R, 0, sizeof R);
    *buf = NULL;
    *size = 0;
    for (int i = 0; i < n; i++) total += (size_t)b[i]->count;
    /* events: every coefficient, its sign and a flag per group at most */
    ev = malloc((3 * total + total / 4 + 64) * sizeof *ev);
    lane = malloc(3 * total + total / 4 + 64);
    raw = malloc(4 * total + 64);
    words = malloc((3 * total + total / 4 + 64) * sizeof *words);
    rnz = malloc(b[0]->ext[1] * b[0]->ext[2] + 1);
    if (!rnz || !H || !E || !ev || !lane || !raw || !words || c4_row_alloc(&w, &zrow, ex)) goto done;
    rp = raw;
    for (int i = 0; i < n; i++)
        for (size_t z = 0; z < b[i]->ext[2]; z++)
            for (size_t y = 0; y < b[i]->ext[1]; y++) {
                const int32_t *c = Q[i] + wvc_index(p[i], b[i], 0, y, z);
                const uint32_t rc = c4_row_ctx(rnz, Q[i], p[i], b[i], y, z, &plast);
                const size_t ng = (ex + (size_t)gs - 1) / (size_t)gs;
                int rowz = 0, any = 0;
                for (size_t x = 0; x < ex; x++) rowz |= c[x] != 0;
                R[rc][rowz]++;
                ev[nev] = (uint16_t)(C4_EV_ROW + 2 * rc + rowz);
                lane[nev++] = 0;
                rnz[z * b[i]->ext[1] + y] = (uint8_t)rowz;
                c4_stats[0]++;
                if (!rowz) continue;
                c4_stats[1]++;
                c4_row_prep(&w, Q[i], p[i], b[i], y, z, zrow, gs, !o->raw_signs, o->comp);
                if (o->with_w)
                    for (size_t x = 1; x < ex; x++) {
                        const uint32_t n = c4_bitlen(w.A[x] + 2 * c4_abs(c[x - 1]));
                        w.CX[x] = (uint8_t)((n < C4_NA - 1 ? n : C4_NA - 1) * C4_NP + w.PC[x]);
                        w.SG[x] = (uint8_t)(w.SG[x] + C4_NSG * ((c[x - 1] > 0) + 2 * (c[x - 1] < 0)));
                    }
                for (size_t g = 0, x0 = 0; x0 < ex; g++, x0 += (size_t)gs) {
                    const size_t x1 = x0 + (size_t)gs < ex ? x0 + (size_t)gs : ex;
                    int nz = 0;
                    for (size_t x = x0; x < x1; x++) nz |= c[x] != 0;
                    if (ng > 1 && (g + 1 < ng || any)) { /* else implied */
                        G[w.GX[g]][nz]++;
                        ev[nev] = (uint16_t)(C4_EV_FLAG + 2 * w.GX[g] + nz);
                        lane[nev++] = 0;
                    }
                    any |= nz;
                    if (!nz) continue;
                    c4_stats[2]++;
                    for (size_t x = x0; x < x1; x++) {
                        const int32_t v = c[x];
                        const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
                        const uint32_t nb = 31 - (uint32_t)__builtin_clz(a | 1);
                        const int sym = (int)(a < 2 ? a : 2 * nb + ((a >> (nb - 1)) & 1));
                        const int k = wvc_rans_nraw(sym);
                        H[w.CX[x]][sym]++;
                        ev[nev] = (uint16_t)(w.CX[x] * C4_NS + sym);
                        lane[nev++] = (uint8_t)(x & 7);
                        acc |= (uint64_t)(a & ((1u << k) - 1)) << nacc;
                        nacc += k;
                        if (a) {
                            if (o->raw_signs) {
                                acc |= (uint64_t)(v < 0) << nacc;
                                nacc++;
                            }
                        }
                        if (nacc >= 32) {
                            const uint32_t lo = (uint32_t)acc;
                            memcpy(rp, &lo, 4);
                            rp += 4;
                            acc >>= 32;
                            nacc -= 32;
                        }
                    }
                    /* the group's signs after its magnitudes, the k-th non-zero on sign state k mod 4 */
                    if (!o->raw_signs)
                        for (size_t x = x0, k = 0; x < x1; x++)
                            if (c[x]) {
                                S[w.SG[x]][c[x] < 0]++;
                                ev[nev] = (uint16_t)(C4_EV_SIGN + 2 * w.SG[x] + (c[x] < 0));
                                lane[nev++] = (uint8_t)(8 + (k++ & 3));
                            }
                }
            }
    while (nacc > 0) {
        *rp++ = (uint8_t)acc;
        acc >>= 8;
        nacc -= 8;
    }
    out = malloc((size_t)C4_NC * (1 + 2 * C4_NS) + 3 * (C4_NG + C4_NSGW + C4_NR) + 64 + 2 * nev + 8 + (size_t)(rp - raw));
    if (!out) goto done;
    head = 48;
    for (int c = 0; c < C4_NC; c++) {
        uint32_t any = 0, cum = 0;
        int ns = 0;
        for (int s = 0; s < C4_NS; s++) any |= H[c][s];
        if (any) wvol__wvc_rans_normalise(H[c], C4_NS, F, C4_M);
        for (int s = 0; s < C4_NS; s++) {
            if (!any) F[s] = 0;
            if (F[s]) ns = s + 1;
            E[c * C4_NS + s] = wvc_rans_esym_make(F[s], cum), cum += F[s];
        }
        head += wvc2_put_varint(out + head, (uint32_t)ns);
        for (int s = 0; s < ns; s++) head += wvc2_put_varint(out + head, F[s]);
    }
    for (int c = 0; c < C4_NG; c++) {
        int used = (G[c][0] | G[c][1]) != 0;
        GF[c] = used ? wvol__wvc_rans_binary_f(G[c][0], G[c][1], C4_M) : 0;
        E[C4_EV_FLAG + 2 * c] = wvc_rans_esym_make(GF[c], 0);
        E[C4_EV_FLAG + 2 * c + 1] = wvc_rans_esym_make(C4_M - GF[c], GF[c]);
        head += wvc2_put_varint(out + head, used ? GF[c] + 1 : 0);
    }
    if (!o->raw_signs)
        for (int c = 0; c < nsg; c++) {
            int used = (S[c][0] | S[c][1]) != 0;
            SF[c] = used ? wvol__wvc_rans_binary_f(S[c][0], S[c][1], C4_M) : 0;
            E[C4_EV_SIGN + 2 * c] = wvc_rans_esym_make(SF[c], 0);
            E[C4_EV_SIGN + 2 * c + 1] = wvc_rans_esym_make(C4_M - SF[c], SF[c]);
            head += wvc2_put_varint(out + head, used ? SF[c] + 1 : 0);
        }
    for (int c = 0; c < C4_NR; c++) {
        int used = (R[c][0] | R[c][1]) != 0;
        uint32_t f = used ? wvol__wvc_rans_binary_f(R[c][0], R[c][1], C4_M) : 0;
        E[C4_EV_ROW + 2 * c] = wvc_rans_esym_make(f, 0);
        E[C4_EV_ROW + 2 * c + 1] = wvc_rans_esym_make(C4_M - f, f);
        head += wvc2_put_varint(out + head, used ? f + 1 : 0);
    }
    c4_stats[3] += nev;
    /* the rANS pass, in reverse */
    for (int l = 0; l < 12; l++) xs[l] = C4_L;
    wp = words + nev + 8; /* at most a word per event, written downwards */
    {
        uint16_t *end = wp;
        for (size_t j = nev; j-- > 0;) {
            const int l = lane[j];
            xs[l] = wvc_rans_enc_put(xs[l], &E[ev[j]], &wp, C4_PBITS);
        }
        for (int l = 0; l < 12; l++) memcpy(out + 4 * l, &xs[l], 4);
        head += wvc2_put_varint(out + head, (uint64_t)(end - wp));
        head += wvc2_put_varint(out + head, (uint64_t)(rp - raw));
        memcpy(out + head, wp, 2 * (size_t)(end - wp));
        head += 2 * (size_t)(end - wp);
    }
    memcpy(out + head, raw, (size_t)(rp - raw));
    head += (size_t)(rp - raw);
    *buf = out;
    *size = head;
    out = NULL;
    ok = 1;
done:
    free(out);
    free(H);
    free(E);
    free(ev);
    free(lane);
    free(raw);
    free(words);
    free(rnz);
    if (w.A || w.CX || zrow) c4_row_free(&w, zrow);
    return ok ? 0 : -1;
}

/* ---- decoder ---- */

static uint64_t c4_symtab[64];
static uint8_t c4_symraw[64];

static void c4_symtab_init(void)
{
    for (int s = 0; s < 64; s++) {
        int k = s < C4_NS ? wvc_rans_nraw(s) : 0;
        /* symbol 63: what an unused context's table gives, a magnitude out of range */
        c4_symtab[s] = (s < C4_NS ? wvc_rans_base(s) : s == 63 ? 0x7FFFFFFFu : 0) | (uint64_t)((1u << k) - 1) << 32;
        c4_symraw[s] = (uint8_t)k;
    }
}

typedef struct c4_dec {
    const uint32_t *flat;
    uint32_t GF[C4_NG], SF[C4_NSGW + 1], RF[C4_NR];
    int comp;
    uint8_t *rnz;
    const uint16_t *w;
    const uint8_t *raw;
} c4_dec;

/* A binary step: bit out, state updated (renormalised by the caller). */
FORCE_INLINE uint32_t c4_bin(uint32_t *x, uint32_t f0)
{
    const uint32_t slot = *x & (C4_M - 1), bit = slot >= f0, m = 0u - bit;
    *x = (f0 ^ ((f0 ^ (C4_M - f0)) & m)) * (*x >> C4_PBITS) + slot - (f0 & m);
    return bit;
}

FORCE_INLINE uint32_t c4_renorm(uint32_t x, const uint16_t *w, size_t *pos)
{
    const uint32_t r = x < C4_L;
    const uint32_t v = w[*pos];
    *pos += r;
    return (x << (r << 4)) | (v & (0u - r));
}

/* One coefficient on state *x: magnitude, raw bits, sign (modelled: a binary step with
 * frequency 2^11, the identity, for a zero). */
FORCE_INLINE void c4_coef(const c4_dec *D, uint32_t *x, uint32_t *xsg, size_t *pos, uint64_t *bp, int32_t *c, uint32_t cx,
                          int raw_signs, uint64_t *nzc, uint32_t *over, uint32_t *m, int i)
{
    const uint32_t e = D->flat[cx * C4_M + (*x & (C4_M - 1))];
    const uint32_t s = e & 63, nz = s != 0;
    uint64_t word;
    uint32_t a, neg, k = c4_symraw[s];
    const uint64_t st = c4_symtab[s];
    *x = (e >> C4_FSHIFT & (2 * C4_M - 1)) * (*x >> C4_PBITS) + (e >> C4_OSHIFT);
    *x = c4_renorm(*x, D->w, pos);
    memcpy(&word, D->raw + (*bp >> 3), 8);
    word >>= *bp & 7;
    a = (uint32_t)st | ((uint32_t)word & (uint32_t)(st >> 32));
    if (raw_signs) {
        neg = (uint32_t)(word >> k) & nz;
        *bp += k + nz;
    } else {
        (void)xsg;
        *bp += k;
        neg = 0; /* the group's signs follow its magnitudes (c4_signs) */
        *m |= nz << i;
    }
    *c = (int32_t)((a ^ (0u - neg)) + neg);
    *nzc += nz; /* in the step: a vector reload of the row just stored stalls on forwarding */
    *over |= a > WVC_QMAX;
}

/* The magnitudes of coefficient x on state x mod 8 (s0..s7), its sign on state x mod 4
 * (t0..t3); the row and group flags on s0. States stay in registers: every access names
 * its variable (a switch for the lanes of short groups). */
#define C4_COEF(SV, TV, X) \
    c4_coef(D, &SV, &TV, &ps, &bits, c + (X), w->CX[X], raw_signs, &nzc, &over, &m, (int)((X) - g0))
/* the sign of the next non-zero of mask m (coefficients g0 ..) on state TV */
#define C4_SIGN(TV)                                                                                                  \
    do {                                                                                                             \
        const int i_ = __builtin_ctz(m);                                                                              \
        const uint32_t neg_ = c4_bin(&TV, D->SF[w->SG[g0 + (size_t)i_]]);                                             \
        TV = c4_renorm(TV, D->w, &ps);                                                                               \
        m &= m - 1;                                                                                                  \
        c[g0 + (size_t)i_] = (int32_t)(((uint32_t)c[g0 + (size_t)i_] ^ (0u - neg_)) + neg_);                          \
    } while (0)

FORCE_INLINE int c4_band(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const c4_row *w,
                         const int32_t *zrow, int gs, int raw_signs, uint32_t xs[12], size_t *pos, uint64_t *bp,
                         size_t nwords, size_t rawbytes, uint64_t *count, const char **why)
{
    const size_t ex = b->ext[0];
    uint32_t s0 = xs[0], s1 = xs[1], s2 = xs[2], s3 = xs[3], s4 = xs[4], s5 = xs[5], s6 = xs[6], s7 = xs[7];
    uint32_t t0 = xs[8], t1 = xs[9], t2 = xs[10], t3 = xs[11];
    size_t ps = *pos;
    uint64_t bits = *bp, nzc = 0;
    uint32_t plast = 0;
    int r = 0;
    for (size_t z = 0; z < b->ext[2] && !r; z++)
        for (size_t y = 0; y < b->ext[1]; y++) {
            int32_t *c = Q + wvc_index(p, b, 0, y, z);
            uint32_t over = 0, any = 0, rowz, m;
            const size_t ng = (ex + (size_t)gs - 1) / (size_t)gs;
            rowz = c4_bin(&s0, D->RF[c4_row_ctx(D->rnz, Q, p, b, y, z, &plast)]);
            s0 = c4_renorm(s0, D->w, &ps);
            D->rnz[z * b->ext[1] + y] = (uint8_t)rowz;
            if (!rowz) {
                if (ps > nwords) {
                    *why = "coded data ends early";
                    r = -1;
                    break;
                }
                continue;
            }
            c4_row_prep(w, Q, p, b, y, z, zrow, gs, !raw_signs, D->comp);
            for (size_t g = 0, g0 = 0; g0 < ex; g++, g0 += (size_t)gs) {
                const size_t g1 = g0 + (size_t)gs < ex ? g0 + (size_t)gs : ex;
                uint32_t nz = 1;
                if (ng > 1 && (g + 1 < ng || any)) {
                    nz = c4_bin(&s0, D->GF[w->GX[g]]);
                    s0 = c4_renorm(s0, D->w, &ps);
                }
                any |= nz;
                if (!nz) continue;
                m = 0;
                if (g1 - g0 == 16) {
                    const size_t x = g0;
                    C4_COEF(s0, t0, x), C4_COEF(s1, t1, x + 1), C4_COEF(s2, t2, x + 2), C4_COEF(s3, t3, x + 3);
                    C4_COEF(s4, t0, x + 4), C4_COEF(s5, t1, x + 5), C4_COEF(s6, t2, x + 6), C4_COEF(s7, t3, x + 7);
                    C4_COEF(s0, t0, x + 8), C4_COEF(s1, t1, x + 9), C4_COEF(s2, t2, x + 10), C4_COEF(s3, t3, x + 11);
                    C4_COEF(s4, t0, x + 12), C4_COEF(s5, t1, x + 13), C4_COEF(s6, t2, x + 14), C4_COEF(s7, t3, x + 15);
                } else {
                for (size_t x = g0; x < g1; x++) switch (x & 7) {
                    case 0: C4_COEF(s0, t0, x); break;
                    case 1: C4_COEF(s1, t1, x); break;
                    case 2: C4_COEF(s2, t2, x); break;
                    case 3: C4_COEF(s3, t3, x); break;
                    case 4: C4_COEF(s4, t0, x); break;
                    case 5: C4_COEF(s5, t1, x); break;
                    case 6: C4_COEF(s6, t2, x); break;
                    default: C4_COEF(s7, t3, x); break;
                    }
                }
                if (!raw_signs)
                    while (m) {
                        C4_SIGN(t0);
                        if (!m) break;
                        C4_SIGN(t1);
                        if (!m) break;
                        C4_SIGN(t2);
                        if (!m) break;
                        C4_SIGN(t3);
                    }
            }
            if (over || ps > nwords || bits > 8 * (uint64_t)rawbytes) {
                /* a symbol in a context without a table gives symbol 63, out of range */
                *why = over ? "magnitude out of range or a context without a table" : "coded data ends early";
                r = -1;
                break;
            }
        }
    xs[0] = s0, xs[1] = s1, xs[2] = s2, xs[3] = s3, xs[4] = s4, xs[5] = s5, xs[6] = s6, xs[7] = s7;
    xs[8] = t0, xs[9] = t1, xs[10] = t2, xs[11] = t3;
    *pos = ps;
    *bp = bits;
    *count += nzc;
    return r;
}

WVOL__CLONES static int c4_band_raw(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b,
                                    const c4_row *w, const int32_t *zrow, int gs, uint32_t xs[12], size_t *pos,
                                    uint64_t *bp, size_t nwords, size_t rawbytes, uint64_t *count, const char **why)
{
    return c4_band(D, Q, p, b, w, zrow, gs, 1, xs, pos, bp, nwords, rawbytes, count, why);
}

WVOL__CLONES static int c4_band_sgn(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b,
                                    const c4_row *w, const int32_t *zrow, int gs, uint32_t xs[12], size_t *pos,
                                    uint64_t *bp, size_t nwords, size_t rawbytes, uint64_t *count, const char **why)
{
    return c4_band(D, Q, p, b, w, zrow, gs, 0, xs, pos, bp, nwords, rawbytes, count, why);
}

int c4_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[], const uint8_t *buf,
              size_t size, const c4_opts *o, uint64_t *nonzero, const char **why)
{
    static int init;
    const size_t ex = b[0]->ext[0];
    const int gs = o->group;
    uint32_t xs[12], nw, nraw;
    uint16_t freq[C4_NS];
    uint32_t *flat = NULL;
    uint16_t *w = NULL;
    uint8_t *raw = NULL;
    c4_dec D;
    c4_row row = {0};
    int32_t *zrow = NULL;
    size_t pos = 48, wpos = 0;
    uint64_t bp = 0;
    int r = -1;
    *nonzero = 0;
    if (!init) c4_symtab_init(), init = 1; /* single-threaded benchmark */
    memset(&D, 0, sizeof D);
    if (size < 48) {
        *why = "truncated";
        return -1;
    }
    for (int l = 0; l < 12; l++) memcpy(&xs[l], buf + 4 * l, 4);
    flat = malloc((size_t)C4_NC * C4_M * sizeof *flat);
    if (!flat) goto done;
    for (int c = 0; c < C4_NC; c++) {
        uint32_t v, sum = 0, ns;
        if (wvol__wvc_rans_get_varint(buf, size, &pos, &ns) || ns > C4_NS) goto bad_table;
        for (uint32_t s = 0; s < ns; s++) {
            if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > C4_M) goto bad_table;
            freq[s] = (uint16_t)v;
            sum += v;
        }
        if (!ns) { /* identity steps giving symbol 63, caught by the range check: no test in the step */
            uint32_t *t = flat + (size_t)c * C4_M;
            for (uint32_t k = 0; k < C4_M; k++) t[k] = 63u | C4_M << C4_FSHIFT | k << C4_OSHIFT;
            continue;
        }
        if (sum != C4_M || !freq[ns - 1]) goto bad_table;
        {
            uint32_t *t = flat + (size_t)c * C4_M, cum = 0;
            for (uint32_t s = 0; s < ns; s++) {
                for (uint32_t k = 0; k < freq[s]; k++) t[cum + k] = s | (uint32_t)freq[s] << C4_FSHIFT | k << C4_OSHIFT;
                cum += freq[s];
            }
        }
    }
    for (int c = 0; c < C4_NG; c++) {
        uint32_t v;
        if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > C4_M + 1) goto bad_table;
        D.GF[c] = v ? v - 1 : C4_M;
    }
    D.comp = o->comp;
    if (!o->raw_signs)
        for (int c = 0; c < (o->comp & 1 ? C4_NSGW : C4_NSG); c++) {
            uint32_t v;
            if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > C4_M + 1) goto bad_table;
            D.SF[c] = v ? v - 1 : C4_M;
        }
    D.SF[C4_NSGW] = C4_M;
    for (int c = 0; c < C4_NR; c++) {
        uint32_t v;
        if (wvol__wvc_rans_get_varint(buf, size, &pos, &v) || v > C4_M + 1) goto bad_table;
        D.RF[c] = v ? v - 1 : C4_M;
    }
    if (wvol__wvc_rans_get_varint(buf, size, &pos, &nw) || wvol__wvc_rans_get_varint(buf, size, &pos, &nraw) || 2 * (size_t)nw > size - pos ||
        nraw != size - pos - 2 * (size_t)nw) {
        *why = "malformed stream lengths";
        goto done;
    }
    /* padding: a row's events (3 per coefficient at most, flags) and raw bits */
    w = calloc((size_t)nw + 3 * ex + 8, sizeof *w);
    raw = calloc((size_t)nraw + (C4_RAWMAX * ex + 7) / 8 + 16, 1);
    D.rnz = malloc(b[0]->ext[1] * b[0]->ext[2] + 1);
    if (!D.rnz || !w || !raw || c4_row_alloc(&row, &zrow, ex)) goto done;
    memcpy(w, buf + pos, 2 * (size_t)nw);
    memcpy(raw, buf + pos + 2 * (size_t)nw, nraw);
    D.flat = flat;
    D.w = w;
    D.raw = raw;
    for (int l = 0; l < 12; l++)
        if (xs[l] < C4_L) {
            *why = "rANS state out of range";
            goto done;
        }
    for (int i = 0; i < n; i++) {
        int e = o->raw_signs ? c4_band_raw(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why)
                             : c4_band_sgn(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why);
        if (e) goto done;
    }
    for (int l = 0; l < 12; l++)
        if (xs[l] != C4_L) {
            *why = "rANS states do not end where they should";
            goto done;
        }
    if (wpos != nw || bp > 8 * (uint64_t)nraw || 8 * (uint64_t)nraw - bp >= 8) {
        *why = "streams do not end where they should";
        goto done;
    }
    r = 0;
    goto done;
bad_table:
    *why = "malformed table";
done:
    free(flat);
    free(w);
    free(raw);
    free(D.rnz);
    if (row.A || row.CX || zrow) c4_row_free(&row, zrow);
    return r;
}
