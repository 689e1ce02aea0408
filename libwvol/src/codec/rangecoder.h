/* SPDX-License-Identifier: MIT
 * Adaptive binary range coder (the .wvc entropy coder's engine).
 * Based on: G. N. N. Martin 1979 (range coding); the carry-less byte output with a
 * cached byte of LZMA (I. Pavlov); two-rate probability estimation as in
 * H.266/VVC's CABAC (an average of a fast and a slow exponential estimator).
 *
 * Everything is inline: the band coder calls it once or twice per coefficient.
 * The decoder never reads outside [buf, buf+size): past the end it feeds zero
 * bytes and counts them, and the caller refuses the section if that happened. */
#ifndef WVOL_CODEC_RANGECODER_H
#define WVOL_CODEC_RANGECODER_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Probability that the next bit is 0, 16-bit fixed point, as two estimators. */
typedef struct rc_ctx {
    uint16_t fast, slow;
} rc_ctx;

#define RC_FAST_SHIFT 4
#define RC_SLOW_SHIFT 6
#define RC_TOP (1u << 24)

static inline void rc_ctx_init(rc_ctx *c, int n)
{
    int i;
    for (i = 0; i < n; i++) c[i].fast = c[i].slow = 32768;
}

static inline uint32_t rc_ctx_p0(const rc_ctx *c)
{
    return ((uint32_t)c->fast + c->slow) >> 1; /* in [8, 65528]: never 0 or 1 */
}

/* Both outcomes computed, one selected: no branch on a bit that is hard to predict. */
static inline void rc_ctx_update(rc_ctx *c, int bit)
{
    uint32_t f = c->fast, s = c->slow;
    uint32_t f1 = f - (f >> RC_FAST_SHIFT), s1 = s - (s >> RC_SLOW_SHIFT);
    uint32_t f0 = f + ((65536u - f) >> RC_FAST_SHIFT), s0 = s + ((65536u - s) >> RC_SLOW_SHIFT);
    c->fast = (uint16_t)(bit ? f1 : f0);
    c->slow = (uint16_t)(bit ? s1 : s0);
}

/* ---- encoder: output into a growing heap buffer ---- */
typedef struct rc_enc {
    uint64_t low;
    uint32_t range;
    uint8_t cache;
    uint64_t cache_size;
    uint8_t *buf;
    size_t size, cap;
    int oom; /* 1 after an allocation failure: the output is invalid */
} rc_enc;

static inline void rc_enc_init(rc_enc *e)
{
    memset(e, 0, sizeof *e);
    e->range = 0xFFFFFFFFu;
    e->cache_size = 1;
}

static inline void rc_enc_byte(rc_enc *e, uint8_t b)
{
    if (e->size == e->cap) {
        size_t nc = e->cap ? e->cap * 2 : 4096;
        uint8_t *nb = realloc(e->buf, nc);
        if (!nb) {
            e->oom = 1;
            return;
        }
        e->buf = nb;
        e->cap = nc;
    }
    e->buf[e->size++] = b;
}

static inline void rc_enc_shift_low(rc_enc *e)
{
    if ((uint32_t)e->low < 0xFF000000u || (e->low >> 32) != 0) {
        uint8_t carry = (uint8_t)(e->low >> 32);
        uint8_t temp = e->cache;
        do {
            rc_enc_byte(e, (uint8_t)(temp + carry));
            temp = 0xFF;
        } while (--e->cache_size != 0);
        e->cache = (uint8_t)(e->low >> 24);
    }
    e->cache_size++;
    e->low = (e->low & 0x00FFFFFFu) << 8;
}

static inline void rc_enc_bit(rc_enc *e, rc_ctx *c, int bit)
{
    uint32_t bound = (e->range >> 16) * rc_ctx_p0(c);
    if (bit) {
        e->low += bound;
        e->range -= bound;
    } else {
        e->range = bound;
    }
    rc_ctx_update(c, bit);
    while (e->range < RC_TOP) {
        e->range <<= 8;
        rc_enc_shift_low(e);
    }
}

/* Equiprobable bits (signs, exp-Golomb suffixes), most significant first. */
static inline void rc_enc_direct(rc_enc *e, uint32_t value, int nbits)
{
    while (nbits-- > 0) {
        e->range >>= 1;
        if ((value >> nbits) & 1u) e->low += e->range;
        while (e->range < RC_TOP) {
            e->range <<= 8;
            rc_enc_shift_low(e);
        }
    }
}

/* Flushes; the first output byte is always 0 (LZMA's cache start) and is dropped
 * by rc_enc_finish's caller through rc_enc_data. */
static inline void rc_enc_finish(rc_enc *e)
{
    int i;
    for (i = 0; i < 5; i++) rc_enc_shift_low(e);
}

/* The coded bytes without the leading always-zero byte. */
static inline const uint8_t *rc_enc_data(const rc_enc *e, size_t *n)
{
    *n = e->size ? e->size - 1 : 0;
    return e->size ? e->buf + 1 : e->buf;
}

static inline void rc_enc_free(rc_enc *e)
{
    free(e->buf);
    e->buf = NULL;
    e->size = e->cap = 0;
}

/* ---- decoder ---- */
typedef struct rc_dec {
    uint32_t range, code;
    const uint8_t *p, *end;
    size_t overrun; /* bytes requested past the end */
} rc_dec;

static inline uint8_t rc_dec_byte(rc_dec *d)
{
    if (d->p < d->end) return *d->p++;
    d->overrun++;
    return 0;
}

static inline void rc_dec_init(rc_dec *d, const uint8_t *buf, size_t size)
{
    int i;
    d->p = buf;
    d->end = buf + size;
    d->overrun = 0;
    d->range = 0xFFFFFFFFu;
    d->code = 0;
    for (i = 0; i < 4; i++) d->code = (d->code << 8) | rc_dec_byte(d);
}

static inline int rc_dec_bit(rc_dec *d, rc_ctx *c)
{
    uint32_t bound = (d->range >> 16) * rc_ctx_p0(c);
    int bit = d->code >= bound;
    uint32_t mask = 0u - (uint32_t)bit;
    d->code -= bound & mask;
    d->range = bit ? d->range - bound : bound;
    rc_ctx_update(c, bit);
    while (d->range < RC_TOP) {
        d->range <<= 8;
        d->code = (d->code << 8) | rc_dec_byte(d);
    }
    return bit;
}

static inline uint32_t rc_dec_direct(rc_dec *d, int nbits)
{
    uint32_t v = 0;
    while (nbits-- > 0) {
        d->range >>= 1;
        uint32_t b = d->code >= d->range;
        if (b) d->code -= d->range;
        v = (v << 1) | b;
        while (d->range < RC_TOP) {
            d->range <<= 8;
            d->code = (d->code << 8) | rc_dec_byte(d);
        }
    }
    return v;
}

#endif
