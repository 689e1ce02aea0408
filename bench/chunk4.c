/* SPDX-License-Identifier: MIT
 * Prototype chunk coder ("mode 4"), for bench_chunkcoder.c (bench/results/chunkcoder.md):
 * the detail bands of a chunk with a static per-chunk model as chunk mode 3
 * (codec/wvc_rans.c), but
 *  - contexts from the rows decoded before only (N, U, their x neighbours, the diagonals
 *    U +- y, the parent): computed per row before its symbols, so that nothing in the
 *    symbol loop waits on the left neighbour;
 *  - twelve rANS states over one stream of 16-bit words: coefficient x's magnitude on
 *    state x mod 8, the k-th non-zero sign of a group on sign state k mod 4, the flags on
 *    state 0 (with states = 16, twenty: the magnitude on state x mod 16, so that the two
 *    halves of a group of 16 are independent, for the AVX2 engine's two registers);
 *  - a flag per row (any non-zero; context from the flags of the rows N, U, the diagonal
 *    rows above and the parent row) and in a non-zero row one per group of G coefficients
 *    (context: the group's neighbourhood sum and parent classes; the last one implied when
 *    the others are zero): a zero row costs one binary step and no context pass;
 *  - magnitudes as mode 3's symbols (0, 1, 2n + b) and raw bits below; signs raw (in the
 *    raw bits after each magnitude) or after each group's magnitudes, for its non-zeros,
 *    with a binary model (band x sign(N) x sign(U), x sign(N(x-1)) with comp & 1).
 * The decoder has a scalar path and, where the CPU has AVX2 (simd >= 1), an engine over the
 * same stream: eight magnitude steps per vector, the modelled signs four per vector, the row's
 * contexts in one vector pass.
 * Payload: the 8 or 16 magnitude states' and the 4 sign states' final values (4 bytes each),
 * 52 magnitude tables (LEB128 n_sym, then the frequencies, summing to 2^10), the group-flag
 * entries (LEB128 f0 + 1, 0 unused), the sign entries when modelled (same), the row-flag
 * entries (same), LEB128 word count and raw byte count, the words, the raw bits (LSB first).
 * The checks are a prototype's: tables, lengths, the final states, the streams' ends and each
 * row's range; enough for the benchmark's round trips, not the fuzzing a chunk mode needs. */
#include "chunk4.h"

#include "codec/rans_common.h"
#include "codec/wvc2_internal.h"

#include <stdlib.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define C4_HAVE_AVX2 1
#endif

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
#define C4_TS 16 /* the sign states' index in a state array: after at most 16 magnitude states */
#define C4_NX (C4_TS + 8) /* and at most 8 sign states */
#define C4_EV_ROW (C4_EV_SIGN + 2 * C4_NSGW)
#define C4_NEV (C4_EV_ROW + 2 * C4_NR)

#define FORCE_INLINE static inline __attribute__((always_inline))


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
    wvc_rans_row_sum(A, N, U, UN, US, ex);
    if (comp & 2) {
        const int32_t *NN = y > 1 ? c - 2 * sy : zrow, *UU = z > 1 ? c - 2 * sz : zrow;
        for (x = 0; x < ex; x++) A[x] += wvc_rans_abs(NN[x]) + wvc_rans_abs(UU[x]);
    }
    if (signs) /* the sign contexts, when the signs are modelled */
        for (x = 0; x < ex; x++) SG[x] = (uint8_t)(sbase + 3 * ((U[x] > 0) + 2 * (U[x] < 0)) + (N[x] > 0) + 2 * (N[x] < 0));
    if (signs && (comp & 1))
        for (x = 1; x < ex; x++) SG[x] = (uint8_t)(SG[x] + C4_NSG * ((N[x - 1] > 0) + 2 * (N[x - 1] < 0)));
    if (!b->has_parent) {
        memset(PC, 0, ex);
    } else {
        const size_t pe = b->pext[0], half = ex >> 1 < pe ? ex >> 1 : pe;
        const int32_t *pr = wvc_rans_parent_row(Q, sy, sz, b, y, z);
        wvc_rans_parent_classes(PC, pr, pe, ex); /* mode 3's */
        if (comp & 4) /* the candidate: 2|p| + its x neighbours */
            for (x = 0; x < half; x++) {
                uint32_t a = 2 * wvc_rans_abs(pr[x]) + (x ? wvc_rans_abs(pr[x - 1]) : 0) + (x + 1 < pe ? wvc_rans_abs(pr[x + 1]) : 0);
                uint8_t k = (uint8_t)((a > 0) + (a > 2) + (a > 6));
                PC[2 * x] = k;
                PC[2 * x + 1] = k;
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
    uint32_t xs[C4_NX], GF[C4_NG], SF[C4_NSGW];
    const int nst = o->states == 16 ? 16 : 8, nss = o->sign_states == 8 ? 8 : 4;
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
                        const uint32_t n = c4_bitlen(w.A[x] + 2 * wvc_rans_abs(c[x - 1]));
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
                        lane[nev++] = (uint8_t)(x & (size_t)(nst - 1));
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
                                lane[nev++] = (uint8_t)(C4_TS + (k++ & (size_t)(nss - 1)));
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
    head = 4 * ((size_t)nst + (size_t)nss);
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
    for (int l = 0; l < C4_NX; l++) xs[l] = C4_L;
    wp = words + nev + 8; /* at most a word per event, written downwards */
    {
        uint16_t *end = wp;
        for (size_t j = nev; j-- > 0;) {
            const int l = lane[j];
            xs[l] = wvc_rans_enc_put(xs[l], &E[ev[j]], &wp, C4_PBITS);
        }
        for (int l = 0; l < nst; l++) memcpy(out + 4 * l, &xs[l], 4);
        for (int l = 0; l < nss; l++) memcpy(out + 4 * (nst + l), &xs[C4_TS + l], 4);
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
/* for a renormalisation mask (bit i: lane i takes a word): lane i's word is the
 * popcount(mask below i)-th of the words read in lane order */
static uint32_t c4_perm[256][8] __attribute__((aligned(32)));

static void c4_symtab_init(void)
{
    for (int s = 0; s < 64; s++) {
        int k = s < C4_NS ? wvc_rans_nraw(s) : 0;
        /* symbol 63: what an unused context's table gives, a magnitude out of range */
        c4_symtab[s] = (s < C4_NS ? wvc_rans_base(s) : s == 63 ? 0x7FFFFFFFu : 0) | (uint64_t)((1u << k) - 1) << 32;
        c4_symraw[s] = (uint8_t)k;
    }
    for (int mk = 0; mk < 256; mk++)
        for (int i = 0; i < 8; i++) c4_perm[mk][i] = (uint32_t)__builtin_popcount((unsigned)mk & ((1u << i) - 1));
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
FORCE_INLINE void c4_coef(const c4_dec *D, uint32_t *x, size_t *pos, uint64_t *bp, int32_t *c, uint32_t cx,
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
        *bp += k;
        neg = 0; /* the group's signs follow its magnitudes (c4_signs) */
        *m |= nz << i;
    }
    *c = (int32_t)((a ^ (0u - neg)) + neg);
    *nzc += nz; /* in the step: a vector reload of the row just stored stalls on forwarding */
    *over |= a > WVC_QMAX;
}

/* Row (y, z)'s flag on state *s0, recorded for the rows after it. */
FORCE_INLINE uint32_t c4_row_flag(const c4_dec *D, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                                  size_t z, uint32_t *plast, uint32_t *s0, size_t *ps)
{
    const uint32_t rowz = c4_bin(s0, D->RF[c4_row_ctx(D->rnz, Q, p, b, y, z, plast)]);
    *s0 = c4_renorm(*s0, D->w, ps);
    D->rnz[z * b->ext[1] + y] = (uint8_t)rowz;
    return rowz;
}

/* The magnitudes of coefficient x on state x mod nst (s0 .. s7 or s15), the k-th non-zero sign
 * of a group on state k mod 4 (t0..t3); the row and group flags on s0. States stay in
 * registers: every access names its variable (a switch for the lanes of short groups). */
#define C4_COEF(SP, X) c4_coef(D, SP, &ps, &bits, c + (X), w->CX[X], raw_signs, &nzc, &over, &m, (int)((X) - g0))
/* the sign of the next non-zero of mask m (coefficients g0 ..) on state TV */
#define C4_SIGN(TV)                                                                                                  \
    do {                                                                                                             \
        const int i_ = __builtin_ctz(m);                                                                              \
        const uint32_t neg_ = c4_bin(&TV, D->SF[w->SG[g0 + (size_t)i_]]);                                             \
        TV = c4_renorm(TV, D->w, &ps);                                                                               \
        m &= m - 1;                                                                                                  \
        c[g0 + (size_t)i_] = (int32_t)(((uint32_t)c[g0 + (size_t)i_] ^ (0u - neg_)) + neg_);                          \
    } while (0)

/* the next up to four signs on states A .. D, in a loop over m (leaves it when m is spent) */
#define C4_SIGNS4(A, B, C, D_)                                                                                     \
    C4_SIGN(A);                                                                                                    \
    if (!m) break;                                                                                                 \
    C4_SIGN(B);                                                                                                    \
    if (!m) break;                                                                                                 \
    C4_SIGN(C);                                                                                                    \
    if (!m) break;                                                                                                 \
    C4_SIGN(D_)

FORCE_INLINE int c4_band(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const c4_row *w,
                         const int32_t *zrow, int gs, int raw_signs, int nst, int nss, uint32_t xs[C4_NX], size_t *pos,
                         uint64_t *bp, size_t nwords, size_t rawbytes, uint64_t *count, const char **why)
{
    const size_t ex = b->ext[0];
    uint32_t s0 = xs[0], s1 = xs[1], s2 = xs[2], s3 = xs[3], s4 = xs[4], s5 = xs[5], s6 = xs[6], s7 = xs[7];
    uint32_t s8 = xs[8], s9 = xs[9], s10 = xs[10], s11 = xs[11], s12 = xs[12], s13 = xs[13], s14 = xs[14], s15 = xs[15];
    uint32_t t0 = xs[C4_TS], t1 = xs[C4_TS + 1], t2 = xs[C4_TS + 2], t3 = xs[C4_TS + 3];
    uint32_t t4 = xs[C4_TS + 4], t5 = xs[C4_TS + 5], t6 = xs[C4_TS + 6], t7 = xs[C4_TS + 7];
    size_t ps = *pos;
    uint64_t bits = *bp, nzc = 0;
    uint32_t plast = 0;
    int r = 0;
    for (size_t z = 0; z < b->ext[2] && !r; z++)
        for (size_t y = 0; y < b->ext[1]; y++) {
            int32_t *c = Q + wvc_index(p, b, 0, y, z);
            uint32_t over = 0, any = 0, rowz, m;
            const size_t ng = (ex + (size_t)gs - 1) / (size_t)gs;
            rowz = c4_row_flag(D, Q, p, b, y, z, &plast, &s0, &ps);
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
                    const int h = nst == 16;
                    C4_COEF(&s0, x), C4_COEF(&s1, x + 1), C4_COEF(&s2, x + 2), C4_COEF(&s3, x + 3);
                    C4_COEF(&s4, x + 4), C4_COEF(&s5, x + 5), C4_COEF(&s6, x + 6), C4_COEF(&s7, x + 7);
                    C4_COEF(h ? &s8 : &s0, x + 8), C4_COEF(h ? &s9 : &s1, x + 9), C4_COEF(h ? &s10 : &s2, x + 10);
                    C4_COEF(h ? &s11 : &s3, x + 11), C4_COEF(h ? &s12 : &s4, x + 12), C4_COEF(h ? &s13 : &s5, x + 13);
                    C4_COEF(h ? &s14 : &s6, x + 14), C4_COEF(h ? &s15 : &s7, x + 15);
                } else {
                for (size_t x = g0; x < g1; x++) switch (x & (size_t)(nst - 1)) {
                    case 0: C4_COEF(&s0, x); break;
                    case 1: C4_COEF(&s1, x); break;
                    case 2: C4_COEF(&s2, x); break;
                    case 3: C4_COEF(&s3, x); break;
                    case 4: C4_COEF(&s4, x); break;
                    case 5: C4_COEF(&s5, x); break;
                    case 6: C4_COEF(&s6, x); break;
                    case 7: C4_COEF(&s7, x); break;
                    case 8: C4_COEF(&s8, x); break;
                    case 9: C4_COEF(&s9, x); break;
                    case 10: C4_COEF(&s10, x); break;
                    case 11: C4_COEF(&s11, x); break;
                    case 12: C4_COEF(&s12, x); break;
                    case 13: C4_COEF(&s13, x); break;
                    case 14: C4_COEF(&s14, x); break;
                    default: C4_COEF(&s15, x); break;
                    }
                }
                if (!raw_signs)
                    while (m) {
                        C4_SIGNS4(t0, t1, t2, t3);
                        if (nss == 4 || !m) continue;
                        C4_SIGNS4(t4, t5, t6, t7);
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
    xs[8] = s8, xs[9] = s9, xs[10] = s10, xs[11] = s11, xs[12] = s12, xs[13] = s13, xs[14] = s14, xs[15] = s15;
    xs[C4_TS] = t0, xs[C4_TS + 1] = t1, xs[C4_TS + 2] = t2, xs[C4_TS + 3] = t3;
    xs[C4_TS + 4] = t4, xs[C4_TS + 5] = t5, xs[C4_TS + 6] = t6, xs[C4_TS + 7] = t7;
    *pos = ps;
    *bp = bits;
    *count += nzc;
    return r;
}

/* The scalar decoder's instances: raw or modelled signs, 8 or 16 magnitude states, 4 or 8 sign states. */
#define C4_BAND_SCALAR(NAME, RAW, NST, NSS)                                                                           \
    WVOL__CLONES static int NAME(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const c4_row *w, \
                                 const int32_t *zrow, int gs, uint32_t xs[C4_NX], size_t *pos, uint64_t *bp,         \
                                 size_t nwords, size_t rawbytes, uint64_t *count, const char **why)                  \
    {                                                                                                              \
        return c4_band(D, Q, p, b, w, zrow, gs, RAW, NST, NSS, xs, pos, bp, nwords, rawbytes, count, why);          \
    }
C4_BAND_SCALAR(c4_band_raw8, 1, 8, 4)
C4_BAND_SCALAR(c4_band_raw16, 1, 16, 4)
C4_BAND_SCALAR(c4_band_sgn8, 0, 8, 4)
C4_BAND_SCALAR(c4_band_sgn16, 0, 16, 4)
C4_BAND_SCALAR(c4_band_sgn16s8, 0, 16, 8)

#ifdef C4_HAVE_AVX2
/* ---- the AVX2 engine: the magnitudes of eight coefficients x .. x + 7 (states s0 .. s7, one
 * register) in one step. The stream order is the scalar decoder's: the eight states
 * renormalise in lane order, so a lane that needs a word takes the next one in the stream
 * (the words of the step loaded at once, distributed by a permutation indexed by the mask of
 * the lanes that need one); the raw bits of the eight follow each other in coefficient order
 * (their offsets a prefix sum of the lanes' bit counts, the bits fetched by a gather). ---- */
#define C4_AVX2 __attribute__((target("avx2,bmi,bmi2,popcnt")))
#define C4_AVX2_INLINE static inline __attribute__((always_inline, target("avx2,bmi,bmi2,popcnt")))

/* The low 32 bits at bit offsets OFF (lanes) from base, for counts up to 57 - 7 bits. */
C4_AVX2_INLINE __m256i c4v_bits64(const uint8_t *base, __m256i OFF)
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
 * stored; returns the mask of the non-zeros. *amax: the largest magnitude so far (range check). */
C4_AVX2_INLINE uint32_t c4v_eight(const c4_dec *D, __m256i *X, const uint8_t *cx, size_t *pos, uint64_t *bits,
                                  int32_t *c, int raw_signs, __m256i *amax)
{
    const __m256i one = _mm256_set1_epi32(1), zero = _mm256_setzero_si256();
    const __m256i C = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)cx));
    __m256i x = *X, E, S, F, R, Wd, NZ, K, Bs, L, P, OFF, Wr, A;
    const uint8_t *base;
    uint32_t rm, nzm;
    /* the table entries: symbol | frequency << 6 | slot - cumulative << 17 */
    E = _mm256_i32gather_epi32(
        (const int *)D->flat,
        _mm256_or_si256(_mm256_slli_epi32(C, C4_PBITS), _mm256_and_si256(x, _mm256_set1_epi32(C4_M - 1))), 4);
    S = _mm256_and_si256(E, _mm256_set1_epi32(63));
    F = _mm256_and_si256(_mm256_srli_epi32(E, C4_FSHIFT), _mm256_set1_epi32(2 * C4_M - 1));
    x = _mm256_add_epi32(_mm256_mullo_epi32(F, _mm256_srli_epi32(x, C4_PBITS)), _mm256_srli_epi32(E, C4_OSHIFT));
    R = _mm256_cmpeq_epi32(_mm256_srli_epi32(x, 16), zero); /* x < 2^16 */
    rm = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(R));
    Wd = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(D->w + *pos)));
    Wd = _mm256_permutevar8x32_epi32(Wd, _mm256_load_si256((const __m256i *)c4_perm[rm]));
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
        Wr = c4v_bits64(base, OFF);
    A = _mm256_or_si256(Bs, _mm256_and_si256(Wr, _mm256_sub_epi32(_mm256_sllv_epi32(one, K), one)));
    *amax = _mm256_max_epu32(*amax, A);
    if (raw_signs) {
        const __m256i ng =
            _mm256_sub_epi32(zero, _mm256_and_si256(_mm256_srlv_epi32(Wr, K), _mm256_and_si256(NZ, one)));
        A = _mm256_sub_epi32(_mm256_xor_si256(A, ng), ng);
    }
    _mm256_storeu_si256((__m256i *)c, A);
    *bits += (uint32_t)_mm256_extract_epi32(P, 7);
    nzm = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(NZ));
    return nzm;
}

/* The modelled signs of a group's non-zeros (mask m over c[0 .. 15]) on the states T (t0 .. t3),
 * four per step in the scalar order: the k-th non-zero on t(k mod 4), renormalised in lane
 * order. The contexts of the non-zeros packed by pext, the sign bits put back by pdep. */
C4_AVX2_INLINE void c4v_signs(const c4_dec *D, __m128i *T, const uint8_t *sg, uint32_t m, int32_t *c, size_t glen,
                              size_t *pos)
{
    const uint64_t ones = 0x0101010101010101ull;
    const uint32_t mlo = m & 255, mhi = m >> 8 & 255, nlo = (uint32_t)_mm_popcnt_u32(mlo);
    const uint32_t n = nlo + (uint32_t)_mm_popcnt_u32(mhi);
    uint64_t lo, hi;
    unsigned __int128 ctx;
    uint32_t sb = 0;
    memcpy(&lo, sg, 8);
    memcpy(&hi, sg + 8, 8);
    lo = _pext_u64(lo, _pdep_u64(mlo, ones) * 255);
    hi = glen > 8 ? _pext_u64(hi, _pdep_u64(mhi, ones) * 255) : 0;
    ctx = (unsigned __int128)lo | (nlo < 8 ? (unsigned __int128)hi << (8 * nlo) : (unsigned __int128)hi << 64);
    __m128i x = *T;
    for (uint32_t k = 0; k < n; k += 4) {
        const __m128i act = _mm_cmpgt_epi32(_mm_set1_epi32((int)(n - k)), _mm_setr_epi32(0, 1, 2, 3));
        const __m128i f0 = _mm_i32gather_epi32(
            (const int *)D->SF, _mm_cvtepu8_epi32(_mm_cvtsi32_si128((int)(uint32_t)(ctx >> (8 * k)))), 4);
        const __m128i slot = _mm_and_si128(x, _mm_set1_epi32(C4_M - 1));
        const __m128i B = _mm_cmpgt_epi32(slot, _mm_sub_epi32(f0, _mm_set1_epi32(1))); /* bit 1: negative */
        const __m128i fr = _mm_blendv_epi8(f0, _mm_sub_epi32(_mm_set1_epi32(C4_M), f0), B);
        __m128i y =
            _mm_add_epi32(_mm_mullo_epi32(fr, _mm_srli_epi32(x, C4_PBITS)), _mm_sub_epi32(slot, _mm_and_si128(f0, B)));
        const __m128i R = _mm_and_si128(_mm_cmpeq_epi32(_mm_srli_epi32(y, 16), _mm_setzero_si128()), act);
        const uint32_t rm = (uint32_t)_mm_movemask_ps(_mm_castsi128_ps(R));
        __m128i W = _mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(D->w + *pos)));
        W = _mm_castps_si128(_mm_permutevar_ps(_mm_castsi128_ps(W), _mm_load_si128((const __m128i *)c4_perm[rm])));
        y = _mm_blendv_epi8(y, _mm_or_si128(_mm_slli_epi32(y, 16), W), R);
        x = _mm_blendv_epi8(x, y, act);
        *pos += (size_t)_mm_popcnt_u32(rm);
        sb |= ((uint32_t)_mm_movemask_ps(_mm_castsi128_ps(B)) & 15u) << k;
    }
    *T = x;
    sb = _pdep_u32(sb & ((1u << n) - 1), m); /* n <= 16 */
    {
        const __m256i sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        for (size_t i = 0; i < glen; i += 8) {
            const __m256i N = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32((int)(sb >> i)), sel), sel);
            const __m256i v = _mm256_loadu_si256((const __m256i *)(c + i));
            _mm256_storeu_si256((__m256i *)(c + i), _mm256_sub_epi32(_mm256_xor_si256(v, N), N));
        }
    }
}

/* As c4v_signs with eight sign states (T8: t0 .. t7), for streams coded with sign_states = 8:
 * a group's 16 signs in two steps. */
C4_AVX2_INLINE void c4v_signs8(const c4_dec *D, __m256i *T8, const uint8_t *sg, uint32_t m, int32_t *c, size_t glen,
                               size_t *pos)
{
    const uint64_t ones = 0x0101010101010101ull;
    const uint32_t mlo = m & 255, mhi = m >> 8 & 255, nlo = (uint32_t)_mm_popcnt_u32(mlo);
    const uint32_t n = nlo + (uint32_t)_mm_popcnt_u32(mhi);
    const __m256i sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    uint64_t lo, hi;
    unsigned __int128 ctx;
    uint32_t sb = 0;
    __m256i x = *T8;
    memcpy(&lo, sg, 8);
    memcpy(&hi, sg + 8, 8);
    lo = _pext_u64(lo, _pdep_u64(mlo, ones) * 255);
    hi = glen > 8 ? _pext_u64(hi, _pdep_u64(mhi, ones) * 255) : 0;
    ctx = (unsigned __int128)lo | (nlo < 8 ? (unsigned __int128)hi << (8 * nlo) : (unsigned __int128)hi << 64);
    for (uint32_t k = 0; k < n; k += 8) {
        const __m256i act = _mm256_cmpgt_epi32(_mm256_set1_epi32((int)(n - k)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        const __m256i f0 = _mm256_i32gather_epi32(
            (const int *)D->SF, _mm256_cvtepu8_epi32(_mm_cvtsi64_si128((long long)(uint64_t)(ctx >> (8 * k)))), 4);
        const __m256i slot = _mm256_and_si256(x, _mm256_set1_epi32(C4_M - 1));
        const __m256i B = _mm256_cmpgt_epi32(slot, _mm256_sub_epi32(f0, _mm256_set1_epi32(1))); /* 1: negative */
        const __m256i fr = _mm256_blendv_epi8(f0, _mm256_sub_epi32(_mm256_set1_epi32(C4_M), f0), B);
        __m256i y = _mm256_add_epi32(_mm256_mullo_epi32(fr, _mm256_srli_epi32(x, C4_PBITS)),
                                     _mm256_sub_epi32(slot, _mm256_and_si256(f0, B)));
        const __m256i R = _mm256_and_si256(_mm256_cmpeq_epi32(_mm256_srli_epi32(y, 16), _mm256_setzero_si256()), act);
        const uint32_t rm = (uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(R));
        __m256i W = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(D->w + *pos)));
        W = _mm256_permutevar8x32_epi32(W, _mm256_load_si256((const __m256i *)c4_perm[rm]));
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

/* c4_row_prep in one pass of eight-lane vectors, for the rows the engine decodes: extents that
 * are multiples of 8 up to 64, groups of 16, the parent row at least half as long (else the
 * generic pass). The contexts are the same numbers (the x neighbours shifted in across lanes). */
C4_AVX2_INLINE __m256i c4v_abs16(__m256i v) { return _mm256_min_epu32(_mm256_abs_epi32(v), _mm256_set1_epi32(65535)); }
/* lanes i -> i - 1 (lane 0 from p's lane 7) and i -> i + 1 (lane 7 from n's lane 0) */
C4_AVX2_INLINE __m256i c4v_left(__m256i v, __m256i p)
{
    return _mm256_permutevar8x32_epi32(_mm256_blend_epi32(v, p, 0x80), _mm256_setr_epi32(7, 0, 1, 2, 3, 4, 5, 6));
}
C4_AVX2_INLINE __m256i c4v_right(__m256i v, __m256i n)
{
    return _mm256_permutevar8x32_epi32(_mm256_blend_epi32(v, n, 0x01), _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 0));
}
/* (v > 0) + 2 (v < 0) */
C4_AVX2_INLINE __m256i c4v_sgn3(__m256i v)
{
    const __m256i z = _mm256_setzero_si256();
    return _mm256_sub_epi32(_mm256_sub_epi32(z, _mm256_cmpgt_epi32(v, z)),
                            _mm256_add_epi32(_mm256_cmpgt_epi32(z, v), _mm256_cmpgt_epi32(z, v)));
}
/* the low bytes of the eight lanes */
C4_AVX2_INLINE void c4v_bytes(uint8_t *d, __m256i v)
{
    const __m256i sh = _mm256_setr_epi8(0, 4, 8, 12, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0, 4, 8, 12, -1,
                                        -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1);
    v = _mm256_permutevar8x32_epi32(_mm256_shuffle_epi8(v, sh), _mm256_setr_epi32(0, 4, 1, 1, 1, 1, 1, 1));
    _mm_storel_epi64((__m128i *)d, _mm256_castsi256_si128(v));
}

C4_AVX2_INLINE int c4v_row_prep(const c4_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                                size_t z, const int32_t *zrow, int signs, int comp)
{
    const size_t sy = p[0], sz = p[0] * p[1], ex = b->ext[0], nv = ex / 8;
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const int32_t *N = y > 0 ? c - sy : zrow, *U = z > 0 ? c - sz : zrow;
    const int32_t *UN = z > 0 && y > 0 ? c - sz - sy : zrow, *US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    const int32_t *pr = NULL;
    const __m256i zero = _mm256_setzero_si256(), one = _mm256_set1_epi32(1);
    __m256i S[8], Nv[8];
    if (ex % 8 || ex > 64 || (comp & ~1) || (b->has_parent && b->pext[0] < ex / 2)) return 0;
    if (z > 0 && y + 4 < b->ext[1]) /* the plane above is far back (a plane of the pyramid): fetch ahead */
        for (size_t x = 0; x < ex; x += 16) __builtin_prefetch(c - sz + 4 * sy + x);
    if (b->has_parent) {
        size_t pj = y >> 1, pk = z >> 1;
        if (pj >= b->pext[1]) pj = b->pext[1] - 1;
        if (pk >= b->pext[2]) pk = b->pext[2] - 1;
        pr = Q + b->poff[0] + sy * (b->poff[1] + pj) + sz * (b->poff[2] + pk);
    }
    for (size_t v = 0; v < nv; v++) {
        Nv[v] = _mm256_loadu_si256((const __m256i *)(N + 8 * v));
        S[v] = _mm256_add_epi32(c4v_abs16(Nv[v]), c4v_abs16(_mm256_loadu_si256((const __m256i *)(U + 8 * v))));
    }
    for (size_t v = 0; v < nv; v++) {
        const size_t x = 8 * v;
        const __m256i l = c4v_left(S[v], v ? S[v - 1] : zero), r = c4v_right(S[v], v + 1 < nv ? S[v + 1] : zero);
        __m256i A = _mm256_add_epi32(_mm256_add_epi32(_mm256_add_epi32(S[v], S[v]), _mm256_add_epi32(l, r)),
                                     _mm256_add_epi32(c4v_abs16(_mm256_loadu_si256((const __m256i *)(UN + x))),
                                                      c4v_abs16(_mm256_loadu_si256((const __m256i *)(US + x)))));
        __m256i PC = zero, n;
        _mm256_storeu_si256((__m256i *)(w->A + x), A);
        if (pr) {
            const __m256i a = _mm256_abs_epi32(
                _mm256_permutevar8x32_epi32(_mm256_castsi128_si256(_mm_loadu_si128((const __m128i *)(pr + x / 2))),
                                            _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3)));
            PC = _mm256_sub_epi32(
                _mm256_sub_epi32(zero, _mm256_cmpgt_epi32(a, zero)),
                _mm256_add_epi32(_mm256_cmpgt_epi32(a, one), _mm256_cmpgt_epi32(a, _mm256_set1_epi32(3))));
        }
        c4v_bytes(w->PC + x, PC);
        /* bit length through float's exponent (A < 2^24), capped at C4_NA - 1 */
        n = _mm256_sub_epi32(_mm256_srli_epi32(_mm256_castps_si256(_mm256_cvtepi32_ps(A)), 23), _mm256_set1_epi32(126));
        n = _mm256_andnot_si256(_mm256_cmpeq_epi32(A, zero), n);
        n = _mm256_min_epi32(n, _mm256_set1_epi32(C4_NA - 1));
        c4v_bytes(w->CX + x, _mm256_add_epi32(_mm256_slli_epi32(n, 2), PC));
        if (signs) {
            const __m256i U8 = _mm256_loadu_si256((const __m256i *)(U + x));
            __m256i sg = _mm256_add_epi32(
                _mm256_set1_epi32(9 * (b->band - 1)),
                _mm256_add_epi32(_mm256_mullo_epi32(c4v_sgn3(U8), _mm256_set1_epi32(3)), c4v_sgn3(Nv[v])));
            if (comp & 1) /* sign(N[x - 1]), none at x = 0 */
                sg = _mm256_add_epi32(
                    sg, _mm256_mullo_epi32(c4v_sgn3(c4v_left(Nv[v], v ? Nv[v - 1] : zero)), _mm256_set1_epi32(C4_NSG)));
            c4v_bytes(w->SG + x, sg);
        }
    }
    for (size_t g = 0; g < ex / 16 + (ex % 16 != 0); g++) { /* the group flags' contexts, as c4_row_prep */
        const size_t x0 = 16 * g, x1 = x0 + 16 < ex ? x0 + 16 : ex;
        uint32_t s = 0, pm = 0, n;
        for (size_t x = x0; x < x1; x++) s += w->A[x], pm |= w->PC[x];
        n = c4_bitlen(s);
        pm = pm > 3 ? 3 : pm;
        w->GX[g] = (uint8_t)((n < C4_NGA - 1 ? n : C4_NGA - 1) * C4_NP + pm);
    }
    return 1;
}

C4_AVX2_INLINE uint32_t c4v_get0(__m256i X) { return (uint32_t)_mm256_cvtsi256_si32(X); }
C4_AVX2_INLINE __m256i c4v_set0(__m256i X, uint32_t s0)
{
    return _mm256_blend_epi32(X, _mm256_castsi128_si256(_mm_cvtsi32_si128((int)s0)), 1);
}

/* As c4_band for extents and groups that are multiples of 8: the flags on lane 0 (s0) taken
 * out of the register and put back, the modelled signs on the scalar states t0 .. t3. */
C4_AVX2_INLINE int c4_band_v(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const c4_row *w,
                             const int32_t *zrow, int gs, int raw_signs, int vsg, int nst, int nss, int vprep,
                             uint32_t xs[C4_NX], size_t *pos, uint64_t *bp, size_t nwords, size_t rawbytes,
                             uint64_t *count, const char **why)
{
    const size_t ex = b->ext[0];
    const __m256i qmax = _mm256_set1_epi32(WVC_QMAX);
    __m256i X = _mm256_loadu_si256((const __m256i *)xs), X1 = _mm256_loadu_si256((const __m256i *)(xs + 8));
    __m256i amax = _mm256_setzero_si256();
    __m128i T = _mm_loadu_si128((const __m128i *)(xs + C4_TS));
    __m256i T8 = _mm256_loadu_si256((const __m256i *)(xs + C4_TS));
    size_t ps = *pos;
    uint64_t bits = *bp, nzc = 0;
    uint32_t plast = 0;
    int r = 0;
    for (size_t z = 0; z < b->ext[2] && !r; z++)
        for (size_t y = 0; y < b->ext[1]; y++) {
            int32_t *c = Q + wvc_index(p, b, 0, y, z);
            uint32_t any = 0, rowz, m, s0 = c4v_get0(X);
            const size_t ng = (ex + (size_t)gs - 1) / (size_t)gs;
            rowz = c4_row_flag(D, Q, p, b, y, z, &plast, &s0, &ps);
            X = c4v_set0(X, s0);
            if (!rowz) {
                if (ps > nwords) {
                    *why = "coded data ends early";
                    r = -1;
                    break;
                }
                continue;
            }
            if (!vprep || gs != 16 || !c4v_row_prep(w, Q, p, b, y, z, zrow, !raw_signs, D->comp))
                c4_row_prep(w, Q, p, b, y, z, zrow, gs, !raw_signs, D->comp);
            for (size_t g = 0, g0 = 0; g0 < ex; g++, g0 += (size_t)gs) {
                const size_t g1 = g0 + (size_t)gs < ex ? g0 + (size_t)gs : ex;
                uint32_t nz = 1;
                if (ng > 1 && (g + 1 < ng || any)) {
                    s0 = c4v_get0(X);
                    nz = c4_bin(&s0, D->GF[w->GX[g]]);
                    s0 = c4_renorm(s0, D->w, &ps);
                    X = c4v_set0(X, s0);
                }
                any |= nz;
                if (!nz) continue;
                m = 0;
                /* with 16 states the two halves of a group are independent (each branch names its
                 * register, so that the states stay in registers) */
                for (size_t x = g0; x < g1; x += 8)
                    if (nst == 16 && (x & 8))
                        m |= c4v_eight(D, &X1, w->CX + x, &ps, &bits, c + x, raw_signs, &amax) << (x - g0);
                    else
                        m |= c4v_eight(D, &X, w->CX + x, &ps, &bits, c + x, raw_signs, &amax) << (x - g0);
                nzc += (uint64_t)_mm_popcnt_u32(m);
                if (!raw_signs && nss == 8) { /* groups of 16 (checked by the caller) */
                    if (m) c4v_signs8(D, &T8, w->SG + g0, m, c + g0, g1 - g0, &ps);
                } else if (!raw_signs && vsg && g1 - g0 <= 16) {
                    if (m) c4v_signs(D, &T, w->SG + g0, m, c + g0, g1 - g0, &ps);
                } else if (!raw_signs) {
                    uint32_t t0 = (uint32_t)_mm_extract_epi32(T, 0), t1 = (uint32_t)_mm_extract_epi32(T, 1);
                    uint32_t t2 = (uint32_t)_mm_extract_epi32(T, 2), t3 = (uint32_t)_mm_extract_epi32(T, 3);
                    while (m) {
                        C4_SIGNS4(t0, t1, t2, t3);
                    }
                    T = _mm_setr_epi32((int)t0, (int)t1, (int)t2, (int)t3);
                }
            }
            {
                const uint32_t ok = (uint32_t)_mm256_movemask_ps(
                    _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_max_epu32(amax, qmax), qmax)));
                if (ok != 0xFF || ps > nwords || bits > 8 * (uint64_t)rawbytes) {
                    *why = ok != 0xFF ? "magnitude out of range or a context without a table" : "coded data ends early";
                    r = -1;
                    break;
                }
            }
        }
    _mm256_storeu_si256((__m256i *)xs, X);
    _mm256_storeu_si256((__m256i *)(xs + 8), X1);
    if (nss == 8)
        _mm256_storeu_si256((__m256i *)(xs + C4_TS), T8);
    else
        _mm_storeu_si128((__m128i *)(xs + C4_TS), T);
    *pos = ps;
    *bp = bits;
    *count += nzc;
    return r;
}

#define C4_BAND_AVX2(NAME, RAW, VSG, NST, NSS, PREP)                                                                        \
    C4_AVX2 static int NAME(const c4_dec *D, int32_t *Q, const size_t p[3], const wvc_band *b, const c4_row *w,        \
                            const int32_t *zrow, int gs, uint32_t xs[C4_NX], size_t *pos, uint64_t *bp, size_t nwords, \
                            size_t rawbytes, uint64_t *count, const char **why)                                        \
    {                                                                                                                  \
        return c4_band_v(D, Q, p, b, w, zrow, gs, RAW, VSG, NST, NSS, PREP, xs, pos, bp, nwords, rawbytes, count, why);     \
    }
C4_BAND_AVX2(c4_band_avx2_raw8, 1, 0, 8, 4, 0)
C4_BAND_AVX2(c4_band_avx2_sgn8, 0, 0, 8, 4, 0)
C4_BAND_AVX2(c4_band_avx2_vsg8, 0, 1, 8, 4, 0)
C4_BAND_AVX2(c4_band_avx2_raw16, 1, 0, 16, 4, 0)
C4_BAND_AVX2(c4_band_avx2_sgn16, 0, 0, 16, 4, 0)
C4_BAND_AVX2(c4_band_avx2_vsg16, 0, 1, 16, 4, 0)
C4_BAND_AVX2(c4_band_avx2_raw8p, 1, 0, 8, 4, 1)
C4_BAND_AVX2(c4_band_avx2_vsg8p, 0, 1, 8, 4, 1)
C4_BAND_AVX2(c4_band_avx2_raw16p, 1, 0, 16, 4, 1)
C4_BAND_AVX2(c4_band_avx2_vsg16p, 0, 1, 16, 4, 1)
C4_BAND_AVX2(c4_band_avx2_vsg16s8p, 0, 1, 16, 8, 1)
#endif

static int c4_cpu_avx2(void)
{
#ifdef C4_HAVE_AVX2
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("popcnt");
#else
    return 0;
#endif
}

int c4_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[], const uint8_t *buf,
              size_t size, const c4_opts *o, uint64_t *nonzero, const char **why)
{
    static int init;
    const size_t ex = b[0]->ext[0];
    const int gs = o->group;
    uint32_t xs[C4_NX], nw, nraw;
    const int nst = o->states == 16 ? 16 : 8, nss = o->sign_states == 8 ? 8 : 4;
    const size_t nhead = 4 * ((size_t)nst + (size_t)nss);
    uint16_t freq[C4_NS];
    uint32_t *flat = NULL;
    uint16_t *w = NULL;
    uint8_t *raw = NULL;
    c4_dec D;
    c4_row row = {0};
    int32_t *zrow = NULL;
    size_t pos = nhead, wpos = 0;
    uint64_t bp = 0;
    int r = -1;
    /* the AVX2 engine where the CPU has it and every group is whole vectors of 8 */
    const int vec = o->simd && ex % 8 == 0 && gs % 8 == 0 && (nss == 4 || gs == 16) && c4_cpu_avx2();
    *nonzero = 0;
    if (!init) c4_symtab_init(), init = 1; /* single-threaded benchmark */
    memset(&D, 0, sizeof D);
    if (nss == 8 && nst != 16) {
        *why = "eight sign states need sixteen magnitude states (prototype)";
        return -1;
    }
    if (size < nhead) {
        *why = "truncated";
        return -1;
    }
    for (int l = 0; l < C4_NX; l++) xs[l] = C4_L; /* the magnitude states a stream of 8 does not use */
    for (int l = 0; l < nst; l++) memcpy(&xs[l], buf + 4 * l, 4);
    for (int l = 0; l < nss; l++) memcpy(&xs[C4_TS + l], buf + 4 * (nst + l), 4);
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
    raw = calloc((size_t)nraw + ((C4_RAWMAX + 2) * ex + 7) / 8 + 16, 1);
    D.rnz = malloc(b[0]->ext[1] * b[0]->ext[2] + 1);
    if (!D.rnz || !w || !raw || c4_row_alloc(&row, &zrow, ex)) goto done;
    memcpy(w, buf + pos, 2 * (size_t)nw);
    memcpy(raw, buf + pos + 2 * (size_t)nw, nraw);
    D.flat = flat;
    D.w = w;
    D.raw = raw;
    for (int l = 0; l < C4_NX; l++)
        if (xs[l] < C4_L) {
            *why = "rANS state out of range";
            goto done;
        }
    for (int i = 0; i < n; i++) {
        int e;
#ifdef C4_HAVE_AVX2
        if (vec) {
            /* simd 1: magnitudes; 2: and the signs; 3: and the row's contexts */
            static int (*const vb[2][5])(const c4_dec *, int32_t *, const size_t[3], const wvc_band *, const c4_row *,
                                         const int32_t *, int, uint32_t[C4_NX], size_t *, uint64_t *, size_t, size_t,
                                         uint64_t *, const char **) = {
                {c4_band_avx2_raw8, c4_band_avx2_sgn8, c4_band_avx2_vsg8, c4_band_avx2_raw8p, c4_band_avx2_vsg8p},
                {c4_band_avx2_raw16, c4_band_avx2_sgn16, c4_band_avx2_vsg16, c4_band_avx2_raw16p, c4_band_avx2_vsg16p}};
            if (nss == 8 && !o->raw_signs)
                e = c4_band_avx2_vsg16s8p(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why);
            else
            e = vb[nst == 16][o->simd == 3   ? (o->raw_signs ? 3 : 4)
                              : o->raw_signs ? 0
                              : o->simd == 2 ? 2
                                             : 1](&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw,
                                                  nonzero, why);
            if (e) goto done;
            continue;
        }
#endif
        if (nss == 8 && !o->raw_signs)
            e = c4_band_sgn16s8(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why);
        else if (nst == 16)
            e = o->raw_signs
                    ? c4_band_raw16(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why)
                    : c4_band_sgn16(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why);
        else
            e = o->raw_signs
                    ? c4_band_raw8(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why)
                    : c4_band_sgn8(&D, Q[i], p[i], b[i], &row, zrow, gs, xs, &wpos, &bp, nw, nraw, nonzero, why);
        if (e) goto done;
    }
    for (int l = 0; l < C4_NX; l++)
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
