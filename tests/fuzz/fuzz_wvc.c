/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the .wvc reader (versions 1 and 2). Each input is decoded twice:
 * as it is (the checksums must catch damage), and "resealed", with the header (and
 * index) checksum and every section's or chunk's checksum recomputed, so that the fuzzer reaches the field checks and
 * the entropy decoders behind them (a crafted file can carry valid checksums). A resealed
 * version-2 input is also read as a file, by region and level through the chunk cache
 * (wvol_wvc_open: codec/wvc2_file.c), with a budget small enough to evict, where its volume is
 * small.
 * Build and run: scripts/fuzz.sh. */
#include "fuzz_file.h" /* first: it sets the feature macros */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "wvol/volume.h"
#include "wvol/wvc.h"

#define HDR 208
#define SEC 48

static uint32_t get32(const uint8_t *d) { return d[0] | (d[1] << 8) | (d[2] << 16) | ((uint32_t)d[3] << 24); }
static uint64_t get64(const uint8_t *d) { return (uint64_t)get32(d) | ((uint64_t)get32(d + 4) << 32); }
static void put32(uint8_t *d, uint32_t v)
{
    for (int i = 0; i < 4; i++) d[i] = (uint8_t)(v >> (8 * i));
}

static void decode(const uint8_t *data, size_t size)
{
    wvol_wvc_read_options o;
    wvol_coeffs *c = NULL;
    wvol_wvc_info *info = malloc(sizeof *info);
    wvol_wvc_read_options_default(&o);
    o.max_voxels = (uint64_t)1 << 16;
    if (info) {
        wvol_wvc_parse_info(info, data, size, NULL);
        free(info);
    }
    if (wvol_wvc_decode(&c, data, size, &o, NULL, NULL) == WVOL_OK) wvol_coeffs_destroy(c);
    o.stop_level = 1;
    c = NULL;
    if (wvol_wvc_decode(&c, data, size, &o, NULL, NULL) == WVOL_OK) wvol_coeffs_destroy(c);
}

/* The box [lo, hi) of `level`'s grid, read through the file's cache (and into an array). */
static void read_box(wvol_wvc_file *f, const size_t lo[3], const size_t hi[3], int level)
{
    wvol_volume *v = NULL;
    if (wvol_wvc_read_region(&v, f, lo, hi, level, NULL) == WVOL_OK) wvol_volume_destroy(v);
}

/* The input as a file: opened, its chunk modes read, and a few boxes of small volumes. */
static void file_reads(const uint8_t *t, size_t size)
{
    wvol_wvc_file *f = NULL;
    if (wvol_wvc_open(&f, fuzz_write("in.wvc", t, size), (size_t)1 << 16, NULL) != WVOL_OK) return;
    {
        const wvol_wvc_info *in = wvol_wvc_file_info(f);
        uint64_t counts[WVOL_WVC_MAX_LEVELS + 1][WVOL_WVC_CHUNK_MODES];
        size_t grid[3], lo[3] = {0, 0, 0}, mid[3], hi[3], n;
        wvol_wvc_file_chunk_modes(f, counts, NULL);
        /* small volumes only, and no whole read at full resolution (decode() has it): every
         * read decodes its chunks again, which under the sanitizers is what a run costs */
        if (wvol_size_mul3(in->nx, in->ny, in->nz, 1, &n) && n <= (size_t)1 << 12) {
            for (int a = 0; a < 3; a++) {
                const size_t n = a == 0 ? in->nx : a == 1 ? in->ny : in->nz;
                mid[a] = n / 3, hi[a] = n / 3 + (n > 6 ? 5 : 1);
            }
            read_box(f, mid, hi, 0);
            if (wvol_wvc_level_geometry(in, in->levels, grid, NULL, NULL, NULL) == WVOL_OK)
                read_box(f, lo, grid, in->levels);
        }
    }
    wvol_wvc_close(f);
}

/* Version 2: header 224 bytes, band table 48 x S, chunk index 32 x C, one CRC. */
static void reseal_v2(uint8_t *t, size_t size)
{
    uint32_t nsec;
    uint64_t nchunks, h;
    if (size < 224) return;
    nsec = get32(t + 12);
    nchunks = get64(t + 208);
    if (nsec > WVOL_WVC_MAX_SECTIONS || nchunks > ((uint64_t)1 << 20)) return;
    h = 224 + (uint64_t)nsec * 48 + nchunks * 32;
    if (h + 4 > size) return;
    for (uint64_t k = 0; k < nchunks; k++) {
        uint8_t *e = t + 224 + (size_t)nsec * 48 + (size_t)k * 32;
        uint64_t off = get64(e), n = get32(e + 8);
        if (n && off <= size && n <= size - off) put32(e + 12, (uint32_t)crc32(0L, t + off, (uInt)n));
    }
    put32(t + h, (uint32_t)crc32(0L, t, (uInt)h));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint8_t *t;
    uint32_t nsec;
    size_t h, s, off;
    decode(data, size);
    if (size >= 10 && data[8] == 2 && data[9] == 0) {
        t = malloc(size);
        if (!t) return 0;
        memcpy(t, data, size);
        reseal_v2(t, size);
        decode(t, size);
        file_reads(t, size);
        free(t);
        return 0;
    }
    if (size < HDR + 4) return 0;
    nsec = get32(data + 12);
    if (nsec > WVOL_WVC_MAX_SECTIONS) return 0;
    h = HDR + (size_t)nsec * SEC;
    if (size < h + 4) return 0;
    t = malloc(size);
    if (!t) return 0;
    memcpy(t, data, size);
    off = h + 4;
    for (s = 0; s < nsec; s++) {
        uint8_t *e = t + HDR + s * SEC;
        uint64_t n = get64(e + 8);
        if (n > size - off) break;
        put32(e + 4, (uint32_t)crc32(0L, t + off, (uInt)n));
        off += (size_t)n;
    }
    put32(t + h, (uint32_t)crc32(0L, t, (uInt)h));
    decode(t, size);
    free(t);
    return 0;
}
