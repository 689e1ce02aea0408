/* SPDX-License-Identifier: MIT
 * The alternative section coder: the same symbols as the CABAC coder (quantised
 * detail coefficients; Lorenzo residuals in the low-pass cube) as zigzag LEB128
 * varints, compressed by zstd. Kept for comparison and for the sections where it
 * wins; the decoder checks every length and never trusts the frame header. */
#include <stdlib.h>
#include <string.h>
#include <zstd.h>

#include "core/alloc.h"
#include "wvc_internal.h"

static inline uint64_t zigzag(int64_t v) { return ((uint64_t)v << 1) ^ (uint64_t)(v >> 63); }
static inline int64_t unzigzag(uint64_t u) { return (int64_t)(u >> 1) ^ -(int64_t)(u & 1); }

#define VARINT_MAX 10

void wvol__wvc_zstd_scratch_free(wvc_zstd_scratch *z)
{
    if (!z) return;
    ZSTD_freeCCtx(z->cctx);
    free(z->sym);
    z->cctx = NULL;
    z->sym = NULL;
    z->cap = 0;
}

int wvol__wvc_zstd_encode(uint8_t **buf, size_t *size, const int32_t *Q, const size_t p[3],
                          const wvc_band *b, int level, wvc_zstd_scratch *zs)
{
    size_t cap, n = 0, bound, x, y, z;
    uint8_t *sym, *out;
    *buf = NULL;
    *size = 0;
    if (b->count > SIZE_MAX / VARINT_MAX) return -1;
    cap = b->count ? (size_t)b->count * VARINT_MAX : 1;
    if (zs && cap > zs->cap) {
        size_t bytes = cap;
        free(zs->sym);
        zs->sym = wvol__malloc_pages(&bytes); /* kept: its first touches paid once */
        zs->cap = zs->sym ? bytes : 0;
    }
    if (zs && !zs->cctx) zs->cctx = ZSTD_createCCtx();
    sym = zs ? zs->sym : malloc(cap);
    if (!sym || (zs && !zs->cctx)) return -1;
    for (z = 0; z < b->ext[2]; z++)
        for (y = 0; y < b->ext[1]; y++) {
            const int32_t *row = Q + wvc_index(p, b, 0, y, z);
            for (x = 0; x < b->ext[0]; x++) {
                int64_t v = row[x];
                uint64_t u;
                if (b->band != 0 && !(x & 7) && x + 8 <= b->ext[0]) {
                    /* eight zeros at once (most detail symbols are one zero byte each) */
                    if (wvc_zero8(row + x)) {
                        memset(sym + n, 0, 8);
                        n += 8;
                        x += 7;
                        continue;
                    }
                }
                if (b->band == 0) v -= wvc_lorenzo(Q, p, b, x, y, z);
                else if (v == 0) { /* most detail symbols: one zero byte */
                    sym[n++] = 0;
                    continue;
                }
                u = zigzag(v);
                while (u >= 0x80) {
                    sym[n++] = (uint8_t)(u | 0x80);
                    u >>= 7;
                }
                sym[n++] = (uint8_t)u;
            }
        }
    bound = ZSTD_compressBound(n);
    out = malloc(bound);
    if (!out) {
        if (!zs) free(sym);
        return -1;
    }
    /* a kept context gives the bytes a fresh one does (the same parameters, reset per frame) */
    bound = zs ? ZSTD_compressCCtx(zs->cctx, out, bound, sym, n, level) : ZSTD_compress(out, bound, sym, n, level);
    if (!zs) free(sym);
    if (ZSTD_isError(bound)) {
        free(out);
        return -1;
    }
    *buf = out;
    *size = bound;
    return 0;
}

int wvol__wvc_zstd_decode(int32_t *Q, const size_t p[3], const wvc_band *b, const uint8_t *buf,
                          size_t size, const char **why)
{
    unsigned long long content = ZSTD_getFrameContentSize(buf, size);
    size_t cap, got, i = 0, x, y, z;
    uint8_t *sym;
    if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN) {
        *why = "malformed zstd frame";
        return -1;
    }
    /* Each symbol takes 1 to 5 bytes (|q| < 2^34 after zigzag fits 5 varint bytes). */
    if (content < b->count || content > (unsigned long long)b->count * 5) {
        *why = "zstd frame size does not match the band";
        return -1;
    }
    cap = (size_t)content;
    sym = malloc(cap ? cap : 1);
    if (!sym) {
        *why = "out of memory";
        return -1;
    }
    got = ZSTD_decompress(sym, cap, buf, size);
    if (ZSTD_isError(got) || got != cap) {
        free(sym);
        *why = "malformed zstd frame";
        return -1;
    }
    for (z = 0; z < b->ext[2]; z++)
        for (y = 0; y < b->ext[1]; y++)
            for (x = 0; x < b->ext[0]; x++) {
                uint64_t u = 0;
                int shift = 0;
                int64_t v;
                for (;;) {
                    uint8_t c;
                    if (i >= cap || shift > 35) {
                        free(sym);
                        *why = "malformed varint";
                        return -1;
                    }
                    c = sym[i++];
                    u |= (uint64_t)(c & 0x7F) << shift;
                    shift += 7;
                    if (!(c & 0x80)) break;
                }
                v = unzigzag(u);
                if (b->band == 0) v += wvc_lorenzo(Q, p, b, x, y, z);
                if (v > WVC_QMAX || v < -(int64_t)WVC_QMAX) {
                    free(sym);
                    *why = "coefficient out of range";
                    return -1;
                }
                Q[wvc_index(p, b, x, y, z)] = (int32_t)v;
            }
    free(sym);
    if (i != cap) {
        *why = "trailing symbols";
        return -1;
    }
    return 0;
}
