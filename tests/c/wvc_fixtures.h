/* SPDX-License-Identifier: MIT */
/* Helpers the .wvc tests share. */
#ifndef WVOL_TEST_WVC_FIXTURES_H
#define WVOL_TEST_WVC_FIXTURES_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* Chunk payload modes, byte 0 of each non-empty chunk of a version-2 file (count[0..3]). */
static inline int wvc_chunk_modes(const uint8_t *b, size_t n, int count[5])
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
        uint32_t bytes;
        memcpy(&off, e, 8);
        memcpy(&bytes, e + 8, 4);
        if (!bytes) continue;
        if (off >= n || b[off] > 4) return 0;
        count[b[off]]++;
    }
    return 1;
}

#endif
