/* SPDX-License-Identifier: MIT
 * Chunk mode 3 of .wvc version 2: the detail bands of one chunk coded with a static,
 * per-chunk model and a table-driven rANS coder, for the high rates where the CABAC
 * chain of binary decisions (significance, unary length, second bit, sign: each waits
 * on the previous one's range and context update) is most of a decode.
 * Based on: J. Duda 2013 (asymmetric numeral systems); F. Giesen 2014 (rANS with byte
 * renormalisation, ryg_rans); the contexts are those of the CABAC band coder
 * (wvc_cabac.c: Wu 1997, Chrysafis & Ortega 2000).
 *
 * One symbol per coefficient: 0 for q = 0, 1 for |q| = 1, 2n + b for |q| of bit
 * length n + 1 >= 2 with b the bit below the leading one (so the first two bits of
 * a magnitude, which carry most of its information, are modelled). Its context is the
 * bit length of 2(|W|+|N|+|U|) + the six causal diagonals + 4|parent|, the CABAC
 * coder's magnitude class. The encoder makes two passes: contexts, symbols and
 * per-context histograms, then rANS in reverse with frequencies normalised to 2^12
 * (written in the payload). The n - 1 bits below the modelled two and the sign go
 * raw into a separate little-endian bit stream, read in bulk by the decoder.
 * The decoder's table per context gives a slot's symbol, frequency and offset in one
 * 32-bit word: one lookup and one multiply per coefficient.
 *
 * Payload (after the chunk's mode and band-mask bytes): per context, LEB128 n_sym
 * (0: the context is unused) then n_sym LEB128 frequencies summing to 2^12; LEB128
 * length of the rANS stream; the rANS stream (first 4 bytes: the final state); the
 * raw bit stream (the rest, every byte used). Bands in the mask's order, each in
 * raster order (x fastest). The decoder checks every table, that the rANS state ends
 * where the encoder began it with every byte read, and that the raw bits end in the
 * last byte. */
#include <stdlib.h>
#include <string.h>

#include "wvc_internal.h"

#define R3_NC 16        /* contexts: magnitude classes */
#define R3_NS 62        /* symbols: 0, 1, 2n + b for n = 1..30 */
#define R3_PBITS 12
#define R3_M (1u << R3_PBITS)
#define R3_L (1u << 23) /* rANS state lower bound: the state stays in [L, 256 L) */

#define FORCE_INLINE static inline __attribute__((always_inline))

static inline uint32_t r3_abs(int32_t v)
{
    uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
    return a > 65535 ? 65535 : a;
}

static inline int r3_class(uint32_t t)
{
    int n = t ? 32 - __builtin_clz(t) : 0;
    return n < R3_NC ? n : R3_NC - 1;
}

/* The rows a coefficient row's contexts read: W is the running previous value;
 * N (y - 1), U (z - 1), UN (z - 1, y - 1), US (z - 1, y + 1) point at x = 0 of their
 * row, or at a zero row when outside the tile; pr is the parent row (NULL: none). */
typedef struct r3_rows {
    const int32_t *N, *U, *UN, *US, *pr;
    size_t pe0;
} r3_rows;

/* Context at x, neighbours inside [0, ex) only (lo: x > 0, hi: x + 1 < ex). */
FORCE_INLINE int r3_ctx(const r3_rows *r, uint32_t aW, size_t x, int lo, int hi)
{
    uint32_t t = 2 * (aW + r3_abs(r->N[x]) + r3_abs(r->U[x])) + r3_abs(r->UN[x]) + r3_abs(r->US[x]);
    if (lo) t += r3_abs(r->N[x - 1]) + r3_abs(r->U[x - 1]);
    if (hi) t += r3_abs(r->N[x + 1]) + r3_abs(r->U[x + 1]);
    if (r->pr) {
        size_t px = x >> 1;
        t += 4 * r3_abs(r->pr[px < r->pe0 ? px : r->pe0 - 1]);
    }
    return r3_class(t);
}

/* Sets the rows for row (y, z) of band b in Q; zrow: ext[0] zeros. */
static void r3_rows_at(r3_rows *r, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y, size_t z,
                       const int32_t *zrow)
{
    const size_t sy = p[0], sz = p[0] * p[1];
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    r->N = y > 0 ? c - sy : zrow;
    r->U = z > 0 ? c - sz : zrow;
    r->UN = z > 0 && y > 0 ? c - sz - sy : zrow;
    r->US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    r->pr = NULL;
    r->pe0 = 1;
    if (b->has_parent) {
        size_t pj = y >> 1, pk = z >> 1;
        if (pj >= b->pext[1]) pj = b->pext[1] - 1;
        if (pk >= b->pext[2]) pk = b->pext[2] - 1;
        r->pr = Q + b->poff[0] + sy * (b->poff[1] + pj) + sz * (b->poff[2] + pk);
        r->pe0 = b->pext[0];
    }
}

/* Symbol of |q| >= 1 and the raw bits below its first two (count in *nraw). */
static inline int r3_symbol(uint32_t a, uint32_t *raw, int *nraw)
{
    int n;
    if (a == 1) {
        *nraw = 0;
        *raw = 0;
        return 1;
    }
    n = 31 - __builtin_clz(a);
    *nraw = n - 1;
    *raw = a & ((1u << (n - 1)) - 1);
    return 2 * n + (int)((a >> (n - 1)) & 1);
}

/* ---- frequency tables ---- */

/* Normalises counts cnt[0..ns) (sum > 0) to frequencies summing to R3_M, each present
 * symbol at least 1: scaled and rounded, the difference taken from or given to the
 * largest ones. */
static void r3_normalise(const uint32_t *cnt, int ns, uint32_t *f)
{
    uint64_t total = 0;
    int64_t sum = 0;
    int s, big = 0;
    for (s = 0; s < ns; s++) total += cnt[s];
    for (s = 0; s < ns; s++) {
        if (!cnt[s]) {
            f[s] = 0;
            continue;
        }
        f[s] = (uint32_t)(((uint64_t)cnt[s] * R3_M + total / 2) / total);
        if (f[s] == 0) f[s] = 1;
        sum += f[s];
        if (f[s] > f[big] || !cnt[big]) big = s;
    }
    if (sum < (int64_t)R3_M) {
        f[big] += (uint32_t)((int64_t)R3_M - sum);
        return;
    }
    while (sum > (int64_t)R3_M) {
        /* take one from the largest frequency above 1 (it loses least), repeatedly */
        int m = -1;
        for (s = 0; s < ns; s++)
            if (f[s] > 1 && (m < 0 || f[s] > f[m])) m = s;
        {
            uint32_t d = (uint32_t)(sum - (int64_t)R3_M), room = f[m] - 1;
            uint32_t take = d < room ? d : room;
            if (take > f[m] / 8 + 1 && take < d) take = f[m] / 8 + 1;
            if (take > d) take = d;
            f[m] -= take;
            sum -= take;
        }
    }
}

/* ---- raw bit stream (little-endian, LSB first) ---- */

typedef struct r3_bitw {
    uint8_t *p;
    uint64_t acc;
    int n;
} r3_bitw;

static inline void r3_put(r3_bitw *w, uint32_t v, int k)
{
    w->acc |= (uint64_t)v << w->n;
    w->n += k;
    if (w->n >= 32) {
        uint32_t lo = (uint32_t)w->acc;
        memcpy(w->p, &lo, 4);
        w->p += 4;
        w->acc >>= 32;
        w->n -= 32;
    }
}

typedef struct r3_bitr {
    const uint8_t *p, *end;
    uint64_t acc;
    int n;
    size_t past; /* bytes fed past the end (zeros) */
} r3_bitr;

static inline void r3_fill(r3_bitr *r)
{
    if (r->n < 32) {
        uint32_t v = 0;
        if (r->end - r->p >= 4) {
            memcpy(&v, r->p, 4);
            r->p += 4;
        } else {
            for (int i = 0; i < 4; i++)
                if (r->p < r->end) v |= (uint32_t)*r->p++ << (8 * i);
                else r->past++;
        }
        r->acc |= (uint64_t)v << r->n;
        r->n += 32;
    }
}

static inline uint32_t r3_get(r3_bitr *r, int k)
{
    uint32_t v;
    r3_fill(r);
    v = (uint32_t)(r->acc & ((1ull << k) - 1));
    r->acc >>= k;
    r->n -= k;
    return v;
}

/* ---- encoder ---- */

static size_t r3_put_varint(uint8_t *d, uint32_t v)
{
    size_t n = 0;
    while (v >= 0x80) {
        d[n++] = (uint8_t)(v | 0x80);
        v >>= 7;
    }
    d[n++] = (uint8_t)v;
    return n;
}

/* Pass 1 over one band: context and symbol of every coefficient into ctx/sym (at
 * *k), counts into H, raw bits into w. */
static void r3_scan_band(const int32_t *Q, const size_t p[3], const wvc_band *b, const int32_t *zrow, uint8_t *ctx,
                         uint8_t *sym, size_t *k, uint32_t (*H)[R3_NS], r3_bitw *w)
{
    const size_t ex = b->ext[0];
    size_t i = *k;
    for (size_t z = 0; z < b->ext[2]; z++)
        for (size_t y = 0; y < b->ext[1]; y++) {
            const int32_t *c = Q + wvc_index(p, b, 0, y, z);
            r3_rows r;
            uint32_t aW = 0;
            r3_rows_at(&r, Q, p, b, y, z, zrow);
            for (size_t x = 0; x < ex; x++, i++) {
                int cx = r3_ctx(&r, aW, x, x > 0, x + 1 < ex), s = 0;
                int32_t v = c[x];
                if (v) {
                    uint32_t a = v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v, raw;
                    int nraw;
                    s = r3_symbol(a, &raw, &nraw);
                    r3_put(w, (raw << 1) | (uint32_t)(v < 0), nraw + 1);
                }
                ctx[i] = (uint8_t)cx;
                sym[i] = (uint8_t)s;
                H[cx][s]++;
                aW = r3_abs(v);
            }
        }
    *k = i;
}

int wvol__wvc_rans_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                          const wvc_band *const b[])
{
    uint32_t (*H)[R3_NS] = NULL, (*F)[R3_NS] = NULL, (*C)[R3_NS] = NULL;
    uint8_t *ctx = NULL, *sym = NULL, *raw = NULL, *rs = NULL, *out = NULL;
    int32_t *zrow = NULL;
    size_t total = 0, maxex = 1, k = 0, rawlen, rslen, head = 0;
    r3_bitw w;
    int i, ok = 0;
    *buf = NULL;
    *size = 0;
    for (i = 0; i < n; i++) {
        total += (size_t)b[i]->count;
        if (b[i]->ext[0] > maxex) maxex = b[i]->ext[0];
    }
    H = calloc(R3_NC, sizeof *H);
    F = calloc(R3_NC, sizeof *F);
    C = calloc(R3_NC, sizeof *C);
    ctx = malloc(total ? total : 1);
    sym = malloc(total ? total : 1);
    raw = malloc(4 * total + 8);          /* at most 31 raw bits per coefficient */
    rs = malloc(2 * total + 8);           /* at most 2 bytes per symbol (frequency >= 1 of 2^12) */
    zrow = calloc(maxex, sizeof *zrow);
    if (!H || !F || !C || !ctx || !sym || !raw || !rs || !zrow) goto done;
    w.p = raw;
    w.acc = 0;
    w.n = 0;
    for (i = 0; i < n; i++) r3_scan_band(Q[i], p[i], b[i], zrow, ctx, sym, &k, H, &w);
    while (w.n > 0) { /* the last partial word, byte by byte */
        *w.p++ = (uint8_t)w.acc;
        w.acc >>= 8;
        w.n -= 8;
    }
    rawlen = (size_t)(w.p - raw);
    for (int c = 0; c < R3_NC; c++) {
        uint32_t any = 0, cum = 0;
        for (int s = 0; s < R3_NS; s++) any |= H[c][s];
        if (!any) continue;
        r3_normalise(H[c], R3_NS, F[c]);
        for (int s = 0; s < R3_NS; s++) C[c][s] = cum, cum += F[c][s];
    }
    {
        /* rANS in reverse: the decoder reads forward */
        uint8_t *end = rs + 2 * total + 8, *ptr = end;
        uint32_t x = R3_L;
        for (size_t j = total; j-- > 0;) {
            const uint32_t f = F[ctx[j]][sym[j]], xmax = ((R3_L >> R3_PBITS) << 8) * f;
            while (x >= xmax) {
                *--ptr = (uint8_t)x;
                x >>= 8;
            }
            x = ((x / f) << R3_PBITS) + (x % f) + C[ctx[j]][sym[j]];
        }
        ptr -= 4;
        memcpy(ptr, &x, 4); /* little-endian hosts only, as the rest of the codec */
        rslen = (size_t)(end - ptr);
        memmove(rs, ptr, rslen);
    }
    out = malloc((size_t)R3_NC * (1 + R3_NS * 2) + 10 + rslen + rawlen);
    if (!out) goto done;
    for (int c = 0; c < R3_NC; c++) {
        int ns = 0;
        for (int s = 0; s < R3_NS; s++)
            if (F[c][s]) ns = s + 1;
        head += r3_put_varint(out + head, (uint32_t)ns);
        for (int s = 0; s < ns; s++) head += r3_put_varint(out + head, F[c][s]);
    }
    head += r3_put_varint(out + head, (uint32_t)rslen);
    memcpy(out + head, rs, rslen);
    memcpy(out + head + rslen, raw, rawlen);
    *buf = out;
    *size = head + rslen + rawlen;
    ok = 1;
done:
    free(H);
    free(F);
    free(C);
    free(ctx);
    free(sym);
    free(raw);
    free(rs);
    free(zrow);
    return ok ? 0 : -1;
}

/* ---- decoder ---- */

typedef struct r3_dec {
    uint32_t x;
    const uint8_t *p, *end;
    size_t past;
} r3_dec;

static int r3_get_varint(const uint8_t *buf, size_t size, size_t *pos, uint32_t *v)
{
    uint32_t r = 0;
    for (int shift = 0; shift < 32; shift += 7) {
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

/* One band: decodes its coefficients into Q (which holds zeros there). tab[c] is NULL
 * for an unused context. Returns 0, or -1 with *why. */
static int r3_decode_band(int32_t *Q, const size_t p[3], const wvc_band *b, const int32_t *zrow,
                          uint32_t *const tab[R3_NC], r3_dec *d, r3_bitr *br, uint64_t *nz, const char **why)
{
    const size_t ex = b->ext[0];
    uint32_t x = d->x;
    const uint8_t *ptr = d->p, *end = d->end;
    uint64_t count = 0;
    int bad = 0;
    for (size_t z = 0; z < b->ext[2] && !bad; z++)
        for (size_t y = 0; y < b->ext[1] && !bad; y++) {
            int32_t *c = Q + wvc_index(p, b, 0, y, z);
            r3_rows r;
            uint32_t aW = 0;
            r3_rows_at(&r, Q, p, b, y, z, zrow);
            for (size_t xx = 0; xx < ex; xx++) {
                int cx = r3_ctx(&r, aW, xx, xx > 0, xx + 1 < ex), s;
                const uint32_t *t = tab[cx];
                uint32_t e;
                if (!t) {
                    bad = 1;
                    *why = "symbol in a context without a table";
                    break;
                }
                e = t[x & (R3_M - 1)];
                s = (int)(e & 63);
                x = (e >> 6 & 0x1FFF) * (x >> R3_PBITS) + (e >> 19);
                while (x < R3_L) {
                    if (ptr < end) x = (x << 8) | *ptr++;
                    else x <<= 8, d->past++;
                }
                if (s == 0) {
                    aW = 0;
                    continue;
                }
                {
                    uint32_t a, bits;
                    if (s == 1) {
                        bits = r3_get(br, 1);
                        a = 1;
                    } else {
                        int nb = s >> 1;
                        bits = r3_get(br, nb);
                        a = (2u | (uint32_t)(s & 1)) << (nb - 1) | (bits >> 1);
                        if (a > WVC_QMAX) {
                            bad = 1;
                            *why = "magnitude out of range";
                            break;
                        }
                    }
                    c[xx] = (bits & 1) ? -(int32_t)a : (int32_t)a;
                    aW = a > 65535 ? 65535 : a;
                    count++;
                }
            }
        }
    d->x = x;
    d->p = ptr;
    *nz += count;
    return bad ? -1 : 0;
}

int wvol__wvc_rans_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                          const uint8_t *buf, size_t size, uint64_t *nonzero, const char **why)
{
    uint32_t *tab[R3_NC] = {0}, *store = NULL;
    int32_t *zrow = NULL;
    size_t pos = 0, maxex = 1, used = 0;
    uint32_t rslen;
    uint16_t freq[R3_NC][R3_NS];
    int ns[R3_NC];
    r3_dec d;
    r3_bitr br;
    int r = -1;
    *nonzero = 0;
    for (int c = 0; c < R3_NC; c++) {
        uint32_t v, sum = 0;
        if (r3_get_varint(buf, size, &pos, &v) || v > R3_NS) {
            *why = "malformed frequency table";
            return -1;
        }
        ns[c] = (int)v;
        for (int s = 0; s < ns[c]; s++) {
            if (r3_get_varint(buf, size, &pos, &v) || v > R3_M) {
                *why = "malformed frequency table";
                return -1;
            }
            freq[c][s] = (uint16_t)v;
            sum += v;
        }
        if (ns[c] && (sum != R3_M || freq[c][ns[c] - 1] == 0)) {
            *why = "frequency table does not sum to 4096";
            return -1;
        }
        if (ns[c]) used++;
    }
    if (r3_get_varint(buf, size, &pos, &rslen) || rslen < 4 || rslen > size - pos) {
        *why = "malformed rANS stream length";
        return -1;
    }
    store = malloc((used ? used : 1) * R3_M * sizeof *store);
    for (int i = 0; i < n; i++)
        if (b[i]->ext[0] > maxex) maxex = b[i]->ext[0];
    zrow = calloc(maxex, sizeof *zrow);
    if (!store || !zrow) {
        *why = "out of memory";
        goto done;
    }
    used = 0;
    for (int c = 0; c < R3_NC; c++) {
        uint32_t cum = 0;
        if (!ns[c]) continue;
        tab[c] = store + used++ * R3_M;
        for (int s = 0; s < ns[c]; s++) {
            /* slot -> symbol | frequency << 6 | (slot - cumulative) << 19 */
            for (uint32_t k = 0; k < freq[c][s]; k++) tab[c][cum + k] = (uint32_t)s | (uint32_t)freq[c][s] << 6 | k << 19;
            cum += freq[c][s];
        }
    }
    memcpy(&d.x, buf + pos, 4);
    d.p = buf + pos + 4;
    d.end = buf + pos + rslen;
    d.past = 0;
    br.p = buf + pos + rslen;
    br.end = buf + size;
    br.acc = 0;
    br.n = 0;
    br.past = 0;
    if (d.x < R3_L) {
        *why = "rANS state out of range";
        goto done;
    }
    for (int i = 0; i < n; i++)
        if (r3_decode_band(Q[i], p[i], b[i], zrow, tab, &d, &br, nonzero, why)) goto done;
    if (d.past || d.p != d.end || d.x != R3_L) {
        *why = d.past ? "coded data ends early" : "rANS stream does not end where it should";
        goto done;
    }
    {
        /* every raw byte used: what the reader loaded (zeros past the end included)
         * minus what it holds unread is the bits consumed */
        size_t loaded = (size_t)(br.p - (buf + pos + rslen)) + br.past;
        size_t consumed = 8 * loaded - (size_t)br.n, have = 8 * (size - pos - rslen);
        if (consumed > have || have - consumed >= 8) {
            *why = consumed > have ? "coded data ends early" : "raw bits do not end where they should";
            goto done;
        }
    }
    r = 0;
done:
    free(store);
    free(zrow);
    return r;
}
