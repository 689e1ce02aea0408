/* SPDX-License-Identifier: MIT
 * Chunk mode 4's encoder (docs/wvc-format.md, "Chunk mode 4"): a first pass records every
 * event (row flag, group flag, magnitude, modelled sign) with its rANS state and counts it in
 * its context, writing the raw bits as it goes; the counts become the payload's tables; a
 * second pass codes the events in reverse with the division-free step of rans_common.h. */
#include <stdlib.h>
#include <string.h>

#include "rans_common.h"
#include "wvc2_internal.h"
#include "wvc_rans4.h"

/* event numbers: magnitudes ctx * NS + sym, then the group flags, the signs, the row flags */
#define R4_EV_FLAG (R4_NC * R4_NS)
#define R4_EV_SIGN (R4_EV_FLAG + 2 * R4_NG)
#define R4_EV_ROW (R4_EV_SIGN + 2 * R4_NSGW)
#define R4_NEV (R4_EV_ROW + 2 * R4_NR)

/* A binary context's frequency from its counts and its encoder symbols; returns the value the
 * payload holds (f0 + 1, 0 for a context never used). */
static uint32_t r4_binary(const uint64_t cnt[2], wvc_rans_esym *e)
{
    const int used = (cnt[0] | cnt[1]) != 0;
    const uint32_t f = used ? wvol__wvc_rans_binary_f(cnt[0], cnt[1], R4_M) : 0;
    e[0] = wvc_rans_esym_make(f, 0);
    e[1] = wvc_rans_esym_make(R4_M - f, f);
    return used ? f + 1 : 0;
}

int wvol__wvc_rans4_encode_stream(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                                  const wvc_band *const b[], const wvc_rans4_opts *o)
{
    const size_t ex = b[0]->ext[0], ng = (ex + R4_GROUP - 1) / R4_GROUP;
    const int raw_signs = o->raw_signs;
    size_t total = 0, nev = 0, head = 0, cap;
    uint16_t *ev = NULL, *words = NULL, *wp;
    uint8_t *lane = NULL, *raw = NULL, *rp, *out = NULL, *rnz = NULL;
    uint32_t(*H)[R4_NS] = calloc(R4_NC, sizeof *H), F[R4_NS], xs[R4_NX];
    uint64_t G[R4_NG][2], S[R4_NSGW][2], R[R4_NR][2], acc = 0;
    uint32_t plast = 0;
    wvc_rans_esym *E = calloc(R4_NEV, sizeof *E);
    r4_row w = {0};
    int32_t *zrow = NULL;
    int nacc = 0, ok = 0;
    memset(G, 0, sizeof G);
    memset(S, 0, sizeof S);
    memset(R, 0, sizeof R);
    *buf = NULL;
    *size = 0;
    for (int i = 0; i < n; i++) total += (size_t)b[i]->count;
    /* events: a magnitude and a sign per coefficient, a flag per group and per row at most */
    cap = 2 * total + total / 4 + (size_t)n * b[0]->ext[1] * b[0]->ext[2] + 64;
    ev = malloc(cap * sizeof *ev);
    lane = malloc(cap);
    raw = malloc(4 * total + 64);
    words = malloc((cap + 8) * sizeof *words);
    rnz = malloc(b[0]->ext[1] * b[0]->ext[2] + 1);
    if (!rnz || !H || !E || !ev || !lane || !raw || !words || wvol__wvc_rans4_row_alloc(&w, &zrow, ex)) goto done;
    rp = raw;
    for (int i = 0; i < n; i++)
        for (size_t z = 0; z < b[i]->ext[2]; z++)
            for (size_t y = 0; y < b[i]->ext[1]; y++) {
                const int32_t *c = Q[i] + wvc_index(p[i], b[i], 0, y, z);
                const uint32_t rc = r4_row_ctx(rnz, Q[i], p[i], b[i], y, z, &plast);
                int rowz = 0, any = 0;
                for (size_t x = 0; x < ex; x++) rowz |= c[x] != 0;
                R[rc][rowz]++;
                ev[nev] = (uint16_t)(R4_EV_ROW + 2 * rc + (uint32_t)rowz);
                lane[nev++] = 0;
                rnz[z * b[i]->ext[1] + y] = (uint8_t)rowz;
                if (!rowz) continue;
                wvol__wvc_rans4_row_prep(&w, Q[i], p[i], b[i], y, z, zrow, !raw_signs);
                for (size_t g = 0, x0 = 0; x0 < ex; g++, x0 += R4_GROUP) {
                    const size_t x1 = x0 + R4_GROUP < ex ? x0 + R4_GROUP : ex;
                    int nz = 0;
                    for (size_t x = x0; x < x1; x++) nz |= c[x] != 0;
                    if (ng > 1 && (g + 1 < ng || any)) { /* else implied: the row is non-zero */
                        G[w.GX[g]][nz]++;
                        ev[nev] = (uint16_t)(R4_EV_FLAG + 2 * w.GX[g] + (uint32_t)nz);
                        lane[nev++] = 0;
                    }
                    any |= nz;
                    if (!nz) continue;
                    for (size_t x = x0; x < x1; x++) {
                        const int32_t v = c[x];
                        const uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
                        const uint32_t nb = 31 - (uint32_t)__builtin_clz(a | 1);
                        const int sym = (int)(a < 2 ? a : 2 * nb + ((a >> (nb - 1)) & 1));
                        const int k = wvc_rans_nraw(sym);
                        H[w.CX[x]][sym]++;
                        ev[nev] = (uint16_t)(w.CX[x] * R4_NS + sym);
                        lane[nev++] = (uint8_t)(x & (R4_STATES - 1));
                        acc |= (uint64_t)(a & ((1u << k) - 1)) << nacc;
                        nacc += k;
                        if (a && raw_signs) {
                            acc |= (uint64_t)(v < 0) << nacc;
                            nacc++;
                        }
                        if (nacc >= 32) {
                            const uint32_t lo = (uint32_t)acc;
                            memcpy(rp, &lo, 4);
                            rp += 4;
                            acc >>= 32;
                            nacc -= 32;
                        }
                    }
                    /* the group's signs after its magnitudes, the k-th non-zero on sign state k mod 8 */
                    if (!raw_signs)
                        for (size_t x = x0, k = 0; x < x1; x++)
                            if (c[x]) {
                                S[w.SG[x]][c[x] < 0]++;
                                ev[nev] = (uint16_t)(R4_EV_SIGN + 2 * w.SG[x] + (c[x] < 0));
                                lane[nev++] = (uint8_t)(R4_TS + (k++ & (R4_SSTATES - 1)));
                            }
                }
            }
    while (nacc > 0) {
        *rp++ = (uint8_t)acc;
        acc >>= 8;
        nacc -= 8;
    }
    out = malloc((size_t)R4_NC * (1 + 2 * R4_NS) + 3 * (R4_NG + R4_NSGW + R4_NR) + R4_HEAD + 16 + 2 * nev +
                 (size_t)(rp - raw));
    if (!out) goto done;
    head = R4_HEAD;
    for (int c = 0; c < R4_NC; c++) {
        uint32_t any = 0, cum = 0;
        int ns = 0;
        for (int s = 0; s < R4_NS; s++) any |= H[c][s];
        if (any) wvol__wvc_rans_normalise(H[c], R4_NS, F, R4_M);
        for (int s = 0; s < R4_NS; s++) {
            if (!any) F[s] = 0;
            if (F[s]) ns = s + 1;
            E[c * R4_NS + s] = wvc_rans_esym_make(F[s], cum), cum += F[s];
        }
        head += wvc2_put_varint(out + head, (uint32_t)ns);
        for (int s = 0; s < ns; s++) head += wvc2_put_varint(out + head, F[s]);
    }
    for (int c = 0; c < R4_NG; c++) head += wvc2_put_varint(out + head, r4_binary(G[c], E + R4_EV_FLAG + 2 * c));
    if (!raw_signs)
        for (int c = 0; c < R4_NSGW; c++) head += wvc2_put_varint(out + head, r4_binary(S[c], E + R4_EV_SIGN + 2 * c));
    for (int c = 0; c < R4_NR; c++) head += wvc2_put_varint(out + head, r4_binary(R[c], E + R4_EV_ROW + 2 * c));
    /* the rANS pass, in reverse: at most a word per event, written downwards */
    for (int l = 0; l < R4_NX; l++) xs[l] = R4_L;
    wp = words + nev + 8;
    {
        uint16_t *end = wp;
        for (size_t j = nev; j-- > 0;) xs[lane[j]] = wvc_rans_enc_put(xs[lane[j]], &E[ev[j]], &wp, R4_PBITS);
        memcpy(out, xs, R4_HEAD); /* little-endian hosts only, as the rest of the codec */
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
    wvol__wvc_rans4_row_free(&w, zrow);
    return ok ? 0 : -1;
}

/* The per-chunk choice of the signs' coding: modelled where they take at least 1% fewer
 * bytes than raw ones (on noise they save nothing and cost the decoder their steps).
 * Returns which stream to keep (1: raw) given both sizes. */
static int r4_keep_raw_signs(size_t modelled, size_t raw) { return (double)modelled > 0.99 * (double)raw; }

int wvol__wvc_rans4_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                           const wvc_band *const b[])
{
    const wvc_rans4_opts om = {0}, orw = {1};
    uint8_t *bm = NULL, *br = NULL, *keep, *out;
    size_t sm = 0, sr = 0, s;
    int raw;
    *buf = NULL;
    *size = 0;
    if (wvol__wvc_rans4_encode_stream(&bm, &sm, n, Q, p, b, &om) ||
        wvol__wvc_rans4_encode_stream(&br, &sr, n, Q, p, b, &orw)) {
        free(bm);
        free(br);
        return -1;
    }
    raw = r4_keep_raw_signs(sm, sr);
    keep = raw ? br : bm;
    s = raw ? sr : sm;
    out = malloc(s + 1);
    if (out) {
        out[0] = raw ? 0 : R4_SIGNS_MODELLED;
        memcpy(out + 1, keep, s);
        *buf = out;
        *size = s + 1;
    }
    free(bm);
    free(br);
    return out ? 0 : -1;
}
