/* SPDX-License-Identifier: MIT */
/* Helpers the .wvc tests share. */
#ifndef WVOL_TEST_WVC_FIXTURES_H
#define WVOL_TEST_WVC_FIXTURES_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* Chunk payload modes, byte 0 of each non-empty chunk of a version-2 file (count[0..4]);
 * only the chunks with at least min_nonzero non-zeros (the index's count) are counted. */
static inline int wvc_chunk_modes_from(const uint8_t *b, size_t n, uint32_t min_nonzero, int count[5])
{
    uint32_t nsec;
    uint64_t nchunks;
    memset(count, 0, 5 * sizeof *count);
    if (n < 224) return 0;
    memcpy(&nsec, b + 12, 4);
    memcpy(&nchunks, b + 208, 8);
    for (uint64_t i = 0; i < nchunks; i++) {
        const uint8_t *e = b + 224 + (size_t)nsec * 48 + i * 32;
        uint64_t off;
        uint32_t bytes, nz;
        memcpy(&off, e, 8);
        memcpy(&bytes, e + 8, 4);
        memcpy(&nz, e + 20, 4);
        if (!bytes || nz < min_nonzero) continue;
        if (off >= n || b[off] > 4) return 0;
        count[b[off]]++;
    }
    return 1;
}

static inline int wvc_chunk_modes(const uint8_t *b, size_t n, int count[5])
{
    return wvc_chunk_modes_from(b, n, 0, count);
}

#endif
