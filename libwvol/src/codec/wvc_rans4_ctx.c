/* SPDX-License-Identifier: MIT
 * Chunk mode 4's per-row contexts (wvc_rans4.h), for its encoder and its scalar decoder: the
 * magnitude context the bit length of 2(|N| + |U|) + |N(x+-1)| + |U(x+-1)| + |U(y+-1)| x the
 * parent's class, the sign context band x sign(U) x sign(N) x sign(N(x-1)), the group flag's
 * the bit length of the group's sums x the OR of its parent classes. */
#include <stdlib.h>
#include <string.h>

#include "core/clones.h"
#include "rans_common.h"
#include "wvc_rans4.h"

int wvol__wvc_rans4_row_alloc(r4_row *w, int32_t **zrow, size_t ex)
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

void wvol__wvc_rans4_row_free(r4_row *w, int32_t *zrow)
{
    free(w->A);
    free(w->CX);
    free(zrow);
    w->A = NULL;
    w->CX = NULL;
}

static inline uint32_t r4_bitlen(uint32_t t) { return 31 - (uint32_t)__builtin_clz(2 * t + 1); }

/* sign(v) as 0 (zero), 1 (positive), 2 (negative) */
static inline uint32_t r4_sgn3(int32_t v) { return (uint32_t)(v > 0) + 2 * (uint32_t)(v < 0); }

WVOL__CLONES void wvol__wvc_rans4_row_prep(const r4_row *w, const int32_t *Q, const size_t p[3], const wvc_band *b,
                                           size_t y, size_t z, const int32_t *zrow, int signs)
{
    const size_t sy = p[0], sz = p[0] * p[1], ex = b->ext[0];
    const int32_t *c = Q + wvc_index(p, b, 0, y, z);
    const int32_t *N = y > 0 ? c - sy : zrow, *U = z > 0 ? c - sz : zrow;
    const int32_t *UN = z > 0 && y > 0 ? c - sz - sy : zrow, *US = z > 0 && y + 1 < b->ext[1] ? c - sz + sy : zrow;
    const uint32_t sbase = 9 * (uint32_t)(b->band - 1);
    uint32_t *restrict A = w->A;
    uint8_t *restrict PC = w->PC, *restrict CX = w->CX, *restrict SG = w->SG;
    size_t x;
    wvc_rans_row_sum(A, N, U, UN, US, ex);
    if (signs) {
        for (x = 0; x < ex; x++) SG[x] = (uint8_t)(sbase + 3 * r4_sgn3(U[x]) + r4_sgn3(N[x]));
        for (x = 1; x < ex; x++) SG[x] = (uint8_t)(SG[x] + R4_NSG * r4_sgn3(N[x - 1]));
    }
    if (!b->has_parent)
        memset(PC, 0, ex);
    else
        wvc_rans_parent_classes(PC, wvc_rans_parent_row(Q, sy, sz, b, y, z), b->pext[0], ex);
    for (x = 0; x < ex; x++) {
        uint32_t n = wvc_rans_bitlen24(A[x]);
        CX[x] = (uint8_t)((n < R4_NA - 1 ? n : R4_NA - 1) * R4_NP + PC[x]);
    }
    for (size_t g = 0, x0 = 0; x0 < ex; g++, x0 += R4_GROUP) {
        const size_t x1 = x0 + R4_GROUP < ex ? x0 + R4_GROUP : ex;
        uint32_t s = 0, pm = 0, n;
        if (x1 - x0 == R4_GROUP) /* a fixed trip count, so that the sums vectorise */
            for (x = 0; x < R4_GROUP; x++) s += A[x0 + x], pm |= PC[x0 + x];
        else
            for (x = x0; x < x1; x++) s += A[x], pm |= PC[x];
        n = r4_bitlen(s);
        pm = pm > 3 ? 3 : pm; /* OR of classes 0..3: 3 when 1 and 2 meet, an upper bound */
        w->GX[g] = (uint8_t)((n < R4_NGA - 1 ? n : R4_NGA - 1) * R4_NP + pm);
    }
}
