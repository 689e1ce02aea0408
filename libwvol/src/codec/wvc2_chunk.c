/* SPDX-License-Identifier: MIT
 * The .wvc version-2 chunk coder: one level's bands over one spatial tile, each band
 * coded by the version-1 band coders (wvc_cabac.c, wvc_zstd.c) on a small local grid
 * that holds the tile and its parent region, so that a chunk depends on nothing but
 * its parent chunk (the coarser level's tile whose half-size region holds its parents,
 * which every read of the chunk's region needs anyway). Neighbours outside the tile
 * count as zero, as at a band's edge in version 1. */
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "wvc2_internal.h"

int wvol__wvc2_geom(wvc2_geom *g, const size_t p[3], int levels, int tile)
{
    size_t first = 0;
    memset(g, 0, sizeof *g);
    g->levels = levels;
    g->tile = tile;
    for (int a = 0; a < 3; a++) {
        g->p[a] = p[a];
        g->tr[a] = p[a] > 1;
    }
    for (int m = levels; m >= 1; m--) {
        wvc2_level *L = &g->lv[m];
        size_t n = 1;
        for (int a = 0; a < 3; a++) {
            L->e[a] = g->tr[a] ? p[a] >> m : 1;
            L->nt[a] = (L->e[a] + (size_t)tile - 1) / (size_t)tile;
            if (L->nt[a] && n > SIZE_MAX / L->nt[a]) return -1;
            n *= L->nt[a];
        }
        L->first = first;
        L->count = n;
        if (first > SIZE_MAX - n) return -1;
        first += n;
        L->nb = 0;
        for (int b = m == levels ? 0 : 1; b < 8; b++) {
            int ok = 1;
            for (int a = 0; a < 3; a++)
                if (((b >> a) & 1) && !g->tr[a]) ok = 0;
            if (ok) L->bands[L->nb++] = b;
        }
    }
    g->nchunks = first;
    return 0;
}

int wvol__wvc2_chunk_coords(const wvc2_geom *g, size_t id, size_t t[3])
{
    for (int m = g->levels; m >= 1; m--) {
        const wvc2_level *L = &g->lv[m];
        if (id >= L->first && id < L->first + L->count) {
            size_t k = id - L->first;
            t[0] = k % L->nt[0];
            k /= L->nt[0];
            t[1] = k % L->nt[1];
            t[2] = k / L->nt[1];
            return m;
        }
    }
    return 0;
}

/* The local grid of one band: the tile at (0, 0, 0), its parent region beside it
 * along x at (ext0, 0, 0); dims (ext0 + pext0) x ext1 x ext2 (pext <= ext). */
typedef struct local_grid {
    int32_t *q;
    size_t p[3];
    wvc_band b;
} local_grid;

static int local_make(local_grid *lg, const wvc2_geom *g, int m, int band, const size_t ext[3])
{
    size_t off0[3] = {0, 0, 0}, poff[3], pext[3], n;
    int has_parent = m < g->levels && band != 0;
    wvc2_parent_box(g, off0, ext, poff, pext);
    memset(lg, 0, sizeof *lg);
    lg->p[0] = ext[0] + (has_parent ? pext[0] : 0);
    lg->p[1] = ext[1];
    lg->p[2] = ext[2];
    lg->b.level = m;
    lg->b.band = band;
    lg->b.has_parent = has_parent;
    for (int a = 0; a < 3; a++) {
        lg->b.ext[a] = ext[a];
        lg->b.pext[a] = has_parent ? pext[a] : 0;
    }
    lg->b.poff[0] = has_parent ? ext[0] : 0;
    lg->b.count = (uint64_t)ext[0] * ext[1] * ext[2];
    n = lg->p[0] * lg->p[1] * lg->p[2];
    lg->q = calloc(n ? n : 1, sizeof *lg->q);
    return lg->q ? 0 : -1;
}

static void box_copy_in(local_grid *lg, size_t x0, const wvc2_qbox *src, const size_t ext[3])
{
    for (size_t z = 0; z < ext[2]; z++)
        for (size_t y = 0; y < ext[1]; y++)
            memcpy(lg->q + x0 + lg->p[0] * (y + lg->p[1] * z), src->q + y * src->sy + z * src->sz,
                   ext[0] * sizeof(int32_t));
}

static void parent_in(local_grid *lg, const wvc2_qbox *parent)
{
    if (lg->b.has_parent) box_copy_in(lg, lg->b.ext[0], parent, lg->b.pext);
}

int wvol__wvc2_chunk_encode(wvc2_coded *out, const wvc2_geom *g, int m, const size_t ext[3],
                            const wvc2_qbox child[8], const wvc2_qbox parent[8], int coder, int zstd_level)
{
    const wvc2_level *L = &g->lv[m];
    uint8_t *pay[8] = {0}, kind[8] = {0};
    size_t len[8] = {0}, head = 0, total;
    int i, failed = 0;
    memset(out, 0, sizeof *out);
    for (i = 0; i < L->nb && !failed; i++) {
        local_grid lg;
        uint64_t nz = 0;
        uint8_t *a = NULL, *z = NULL;
        size_t na = 0, nzs = 0;
        for (size_t zz = 0; zz < ext[2]; zz++)
            for (size_t y = 0; y < ext[1]; y++) {
                const int32_t *r = child[i].q + y * child[i].sy + zz * child[i].sz;
                for (size_t x = 0; x < ext[0]; x++) nz += r[x] != 0;
            }
        if (nz == 0) continue;
        out->nonzero += nz;
        if (local_make(&lg, g, m, L->bands[i], ext)) {
            failed = 1;
            break;
        }
        box_copy_in(&lg, 0, &child[i], ext);
        parent_in(&lg, &parent[i]);
        if (coder != WVOL_WVC_CODER_ZSTD) {
            if (wvol__wvc_cabac_encode(&a, &na, lg.q, lg.p, &lg.b)) failed = 1;
            out->alt_cabac += na;
        }
        if (coder != WVOL_WVC_CODER_CABAC && !failed) {
            if (wvol__wvc_zstd_encode(&z, &nzs, lg.q, lg.p, &lg.b, zstd_level)) failed = 1;
            out->alt_zstd += nzs;
        }
        free(lg.q);
        if (a && (!z || na <= nzs)) {
            pay[i] = a, len[i] = na, kind[i] = WVOL_WVC_CODER_CABAC;
            free(z);
        } else {
            pay[i] = z, len[i] = nzs, kind[i] = WVOL_WVC_CODER_ZSTD;
            free(a);
        }
        if (!pay[i] || !len[i]) failed = 1;
    }
    if (!failed && out->nonzero) {
        uint8_t *p, hdr[8 + 8 * 10];
        head = (size_t)L->nb;
        for (i = 0; i < L->nb; i++) hdr[i] = kind[i];
        for (i = 0; i < L->nb; i++)
            if (kind[i]) head += wvc2_put_varint(hdr + head, len[i]);
        total = head;
        for (i = 0; i < L->nb; i++) total += len[i];
        p = malloc(total);
        if (!p) {
            failed = 1;
        } else {
            memcpy(p, hdr, head);
            total = head;
            for (i = 0; i < L->nb; i++)
                if (len[i]) memcpy(p + total, pay[i], len[i]), total += len[i];
            out->payload = p;
            out->bytes = total;
            out->crc = (uint32_t)crc32(0L, p, (uInt)total);
            for (i = 0; i < L->nb; i++) out->band_bytes[i] = len[i];
        }
    }
    for (i = 0; i < 8; i++) free(pay[i]);
    if (failed) {
        free(out->payload);
        memset(out, 0, sizeof *out);
        return -1;
    }
    return 0;
}

static void box_zero(const wvc2_qbox *b, const size_t ext[3])
{
    for (size_t z = 0; z < ext[2]; z++)
        for (size_t y = 0; y < ext[1]; y++) memset(b->q + y * b->sy + z * b->sz, 0, ext[0] * sizeof(int32_t));
}

int wvol__wvc2_chunk_decode(const wvc2_geom *g, int m, const size_t ext[3], const wvc2_qbox child[8],
                            const wvc2_qbox parent[8], const uint8_t *payload, size_t bytes, uint64_t *nonzero,
                            const char **why)
{
    const wvc2_level *L = &g->lv[m];
    size_t len[8] = {0}, pos, sum = 0;
    int i;
    *nonzero = 0;
    for (i = 0; i < L->nb; i++) box_zero(&child[i], ext);
    if (bytes == 0) return 0;
    if (bytes < (size_t)L->nb) {
        *why = "chunk header truncated";
        return -1;
    }
    pos = (size_t)L->nb;
    for (i = 0; i < L->nb; i++) {
        uint64_t v = 0;
        int shift = 0;
        if (payload[i] > WVOL_WVC_CODER_ZSTD) {
            *why = "unknown band coder";
            return -1;
        }
        if (!payload[i]) continue;
        for (;;) {
            uint8_t c;
            if (pos >= bytes || shift > 56) {
                *why = "malformed band length";
                return -1;
            }
            c = payload[pos++];
            v |= (uint64_t)(c & 0x7F) << shift;
            shift += 7;
            if (!(c & 0x80)) break;
        }
        if (v == 0 || v > bytes) {
            *why = "band length out of range";
            return -1;
        }
        len[i] = (size_t)v;
        sum += len[i];
    }
    if (sum != bytes - pos) {
        *why = "band lengths do not add up to the chunk";
        return -1;
    }
    for (i = 0; i < L->nb; i++) {
        local_grid lg;
        int r;
        if (!payload[i]) {
            pos += 0;
            continue;
        }
        if (local_make(&lg, g, m, L->bands[i], ext)) {
            *why = "out of memory";
            return -1;
        }
        parent_in(&lg, &parent[i]);
        if (payload[i] == WVOL_WVC_CODER_CABAC)
            r = wvol__wvc_cabac_decode(lg.q, lg.p, &lg.b, payload + pos, len[i], why);
        else
            r = wvol__wvc_zstd_decode(lg.q, lg.p, &lg.b, payload + pos, len[i], why);
        if (r) {
            free(lg.q);
            return -1;
        }
        pos += len[i];
        for (size_t z = 0; z < ext[2]; z++)
            for (size_t y = 0; y < ext[1]; y++) {
                const int32_t *s = lg.q + lg.p[0] * (y + lg.p[1] * z);
                int32_t *d = child[i].q + y * child[i].sy + z * child[i].sz;
                for (size_t x = 0; x < ext[0]; x++) *nonzero += (d[x] = s[x]) != 0;
            }
        free(lg.q);
    }
    return 0;
}
