/* SPDX-License-Identifier: MIT
 * Chunk mode 4 (docs/wvc-format.md, "Chunk mode 4"): what its encoder (wvc_rans4_enc.c) and
 * decoder (wvc_rans4_dec.c) share: the layout's constants, the per-row contexts (from the rows
 * decoded before only) and the row flag's context. Not installed. */
#ifndef WVOL_CODEC_WVC_RANS4_H
#define WVOL_CODEC_WVC_RANS4_H

#include <stddef.h>
#include <stdint.h>

#include "rans_common.h"
#include "wvc_internal.h"

#define R4_NA 13                /* magnitude context: bit length classes of the neighbour sum */
#define R4_NP 4                 /* x the parent's classes */
#define R4_NC (R4_NA * R4_NP)   /* magnitude contexts */
#define R4_NS 62                /* magnitude symbols (rans_common.h) */
#define R4_NGA 8                /* group flag: bit length classes of the group's sum */
#define R4_NG (R4_NGA * R4_NP)  /* group-flag contexts */
#define R4_NSG 63               /* sign contexts: band x sign(U) x sign(N) */
#define R4_NSGW (3 * R4_NSG)    /* x sign(N(x - 1)) */
#define R4_NR 12                /* row-flag contexts */
#define R4_PBITS 10             /* frequencies sum to 2^10 */
#define R4_M (1u << R4_PBITS)
#define R4_L (1u << 16)         /* rANS states in [2^16, 2^32) */
#define R4_GROUP 16             /* coefficients per group flag */
#define R4_STATES 16            /* magnitude states: coefficient x on state x mod 16 */
#define R4_SSTATES 8            /* sign states: the k-th non-zero of a group on state k mod 8 */
#define R4_TS 16                /* the sign states' index in a state array */
#define R4_NX (R4_TS + R4_SSTATES)
#define R4_HEAD (4 * R4_NX)     /* the final states at the stream's head */
#define R4_SIGNS_MODELLED 1     /* the flags byte before the stream: bit 0 */
#define R4_TABLES_PACKED 2      /* bit 1: the tables as packed bits (below), else LEB128 entries */

/* Packed tables (docs/wvc-format.md, "Packed tables"): bits, most significant first, from the
 * byte after the states; the byte holding the last bit ends them. A magnitude table: Elias-gamma
 * ns + 1 (0: unused), then R4_PFIELD bits of its precision P - R4_PMIN, then frequencies
 * F_0 .. F_{ns-2} of a total 2^P as Elias-gamma F + 1 (the last is what the total leaves, at
 * least 1); each frequency is F << (10 - P). A binary entry: R4_BKIND bits of kind, and for
 * R4_BIN_EXPLICIT R4_BPFIELD bits of P (R4_BPMIN .. 10) and P bits of f0 (1 .. 2^P - 1). */
#define R4_PMIN 3
#define R4_PFIELD 3
#define R4_BKIND 2
#define R4_BPFIELD 4
#define R4_BPMIN 2
#define R4_EG_MAXZ 10 /* Elias-gamma values below 2^11: every packed value */
/* binary kinds: f0 = 2^10 (no event, or zeros only), 0 (ones only), 2^9, given */
enum { R4_BIN_ZEROS = 0, R4_BIN_ONES = 1, R4_BIN_HALF = 2, R4_BIN_EXPLICIT = 3 };

/* Per row: A the neighbour sums, CX the magnitude contexts, PC the parent classes, SG the
 * sign contexts, GX the group-flag contexts (one block of 4 ex + 8 bytes after A). */
typedef struct r4_row {
    uint32_t *A;
    uint8_t *CX, *PC, *SG, *GX;
} r4_row;

int wvol__wvc_rans4_row_alloc(r4_row *w, int32_t **zrow, size_t ex);
void wvol__wvc_rans4_row_free(r4_row *w, int32_t *zrow);

/* Row (y, z)'s contexts into w (sign contexts when signs is set); zrow: ex zeros, for the
 * rows outside the band. */
void wvol__wvc_rans4_row_prep(const r4_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                              size_t z, const int32_t *zrow, int signs);

/* The context of row (y, z)'s flag: whether the rows N and U are non-zero, either diagonal
 * row above (U +- y), the parent row. rnz: the band's row flags so far, y fastest; *plast:
 * the parent row's flag, kept for the odd row after it (which has the same parent row). */
static inline uint32_t r4_row_ctx(const uint8_t *rnz, const int32_t *Q, const size_t p[3], const wvc_band *b, size_t y,
                                  size_t z, uint32_t *plast)
{
    const size_t ey = b->ext[1];
    uint32_t n = y ? rnz[z * ey + y - 1] : 0, up = z ? rnz[(z - 1) * ey + y] : 0, d = 0, pr = 0;
    if (z) d = (y ? rnz[(z - 1) * ey + y - 1] : 0) | (y + 1 < ey ? rnz[(z - 1) * ey + y + 1] : 0);
    if (y & 1) {
        pr = *plast;
    } else if (b->has_parent) {
        const int32_t *r = wvc_rans_parent_row(Q, p[0], p[0] * p[1], b, y, z);
        const size_t prow = b->pq ? b->psy : p[0];
        int32_t o = 0;
        if ((y >> 1) + 2 < b->pext[1]) /* the parent rows are a level decoded long before: fetch ahead */
            for (size_t x = 0; x < b->pext[0]; x += 16) __builtin_prefetch(r + 2 * prow + x);
        for (size_t x = 0; x < b->pext[0]; x++) o |= r[x];
        pr = o != 0;
    }
    *plast = pr;
    return ((n + up) * 2 + d) * 2 + pr;
}

#endif
