/* SPDX-License-Identifier: MIT */
#include "wvol/io.h"

#include <stdint.h>
#include <string.h>
#include <strings.h>

static const struct {
    const char *names[4];
    size_t size;
} sample_types[] = {
    [WVOL_SAMPLE_TYPE_F32] = {{"float32", "f32", "float", NULL}, 4},
    [WVOL_SAMPLE_TYPE_F64] = {{"float64", "f64", "double", NULL}, 8},
    [WVOL_SAMPLE_TYPE_U8] = {{"uint8", "u8", "uchar", NULL}, 1},
    [WVOL_SAMPLE_TYPE_I8] = {{"int8", "i8", "char", NULL}, 1},
    [WVOL_SAMPLE_TYPE_U16] = {{"uint16", "u16", "ushort", NULL}, 2},
    [WVOL_SAMPLE_TYPE_I16] = {{"int16", "i16", "short", NULL}, 2},
    [WVOL_SAMPLE_TYPE_U32] = {{"uint32", "u32", "uint", NULL}, 4},
    [WVOL_SAMPLE_TYPE_I32] = {{"int32", "i32", "int", NULL}, 4},
};

int wvol_sample_type_parse(const char *name)
{
    int t, k;
    if (!name) return -1;
    for (t = 0; t < (int)(sizeof sample_types / sizeof sample_types[0]); t++)
        for (k = 0; k < 4 && sample_types[t].names[k]; k++)
            if (strcasecmp(name, sample_types[t].names[k]) == 0) return t;
    return -1;
}

const char *wvol_sample_type_name(wvol_sample_type t)
{
    return (unsigned)t <= WVOL_SAMPLE_TYPE_I32 ? sample_types[t].names[0] : "unknown";
}

size_t wvol_sample_type_size(wvol_sample_type t)
{
    return (unsigned)t <= WVOL_SAMPLE_TYPE_I32 ? sample_types[t].size : 0;
}

static void load_bytes(unsigned char *dst, const unsigned char *src, size_t size, int swap)
{
    size_t b;
    if (!swap) {
        memcpy(dst, src, size);
        return;
    }
    for (b = 0; b < size; b++) dst[b] = src[size - 1 - b];
}

static int host_is_big_endian(void)
{
    const uint16_t one = 1;
    return *(const unsigned char *)&one == 0;
}

wvol_status wvol__inexact_integer(const char *path, unsigned long long index, const char *value, wvol_error *err)
{
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                          "%s: sample %llu holds the integer %s, which float32 cannot hold exactly (integers above "
                          "2^24 in magnitude lose digits); refused",
                          path, index, value);
}

void wvol_samples_to_float(float *dst, const void *src, size_t n, wvol_sample_type t, int big_endian)
{
    const unsigned char *s = src;
    size_t size = wvol_sample_type_size(t), i;
    int swap = big_endian != host_is_big_endian();
    unsigned char tmp[8];
    if (!swap) {
        /* native byte order: one loop per type that the compiler vectorises (the per-sample
         * switch below costs more than reading the file) */
        switch (t) {
        case WVOL_SAMPLE_TYPE_F32: memmove(dst, src, n * sizeof *dst); return;
        case WVOL_SAMPLE_TYPE_U8: for (i = 0; i < n; i++) dst[i] = (float)s[i]; return;
        case WVOL_SAMPLE_TYPE_U16: {
            uint16_t x;
            for (i = 0; i < n; i++) memcpy(&x, s + 2 * i, 2), dst[i] = (float)x;
            return;
        }
        case WVOL_SAMPLE_TYPE_I16: {
            int16_t x;
            for (i = 0; i < n; i++) memcpy(&x, s + 2 * i, 2), dst[i] = (float)x;
            return;
        }
        default: break;
        }
    }
    for (i = 0; i < n; i++, s += size) {
        load_bytes(tmp, s, size, swap);
        switch (t) {
        case WVOL_SAMPLE_TYPE_F32: { float x; memcpy(&x, tmp, 4); dst[i] = x; } break;
        case WVOL_SAMPLE_TYPE_F64: { double x; memcpy(&x, tmp, 8); dst[i] = (float)x; } break;
        case WVOL_SAMPLE_TYPE_U8: dst[i] = (float)tmp[0]; break;
        case WVOL_SAMPLE_TYPE_I8: dst[i] = (float)(int8_t)tmp[0]; break;
        case WVOL_SAMPLE_TYPE_U16: { uint16_t x; memcpy(&x, tmp, 2); dst[i] = (float)x; } break;
        case WVOL_SAMPLE_TYPE_I16: { int16_t x; memcpy(&x, tmp, 2); dst[i] = (float)x; } break;
        case WVOL_SAMPLE_TYPE_U32: { uint32_t x; memcpy(&x, tmp, 4); dst[i] = (float)x; } break;
        case WVOL_SAMPLE_TYPE_I32: { int32_t x; memcpy(&x, tmp, 4); dst[i] = (float)x; } break;
        }
    }
}
