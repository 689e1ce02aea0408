/* SPDX-License-Identifier: MIT
 * .wvc version 2: the header, band table and chunk index checks (one CRC-32 covers
 * the three), and the decoding of whole levels of chunks into a dense quantised
 * pyramid (coarse to fine, the chunks of a level in parallel). Every field is checked
 * before it is used (docs/wvc-format.md lists the checks). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "wvc2_read.h"
#include "wvc_format.h"

static int finite_nonneg(double v) { return isfinite(v) && v >= 0; }

void wvol__wvc2_index_free(wvc2_index *x)
{
    if (!x) return;
    free(x->chunks);
    free(x);
}

uint64_t wvol__wvc2_prefix_bytes(const uint8_t *h, size_t avail)
{
    uint64_t nsec, nchunks;
    if (avail < WVC2_HEADER_SIZE) return 0;
    nsec = wvc_get_u32(h + 12);
    nchunks = wvc_get_u64(h + 208);
    if (nsec > WVOL_WVC_MAX_SECTIONS || nchunks > ((uint64_t)1 << 40)) return 0;
    return WVC2_HEADER_SIZE + nsec * WVC2_BAND_SIZE + nchunks * WVC2_CHUNK_SIZE + 4;
}

wvol_status wvol__wvc2_parse(wvol_wvc_info *I, wvc2_index **out, const uint8_t *h, size_t avail, uint64_t file_size,
                             wvol_error *err)
{
    uint64_t nsec = wvc_get_u32(h + 12), nchunks, hbytes, payload, off, nz_sum = 0;
    uint64_t lev_nz[WVOL_WVC_MAX_LEVELS + 1] = {0}, band_nz[WVOL_WVC_MAX_LEVELS + 1] = {0};
    wvc2_index *x;
    size_t p[3] = {I->px, I->py, I->pz};
    int tl, tlz, s;
    if (out) *out = NULL;
    WVOL_RETURN_IF(avail < WVC2_HEADER_SIZE || file_size < WVC2_HEADER_SIZE, err, WVOL_ERR_FORMAT,
                   ".wvc file truncated: %llu bytes, the version-2 header alone needs %d",
                   (unsigned long long)(file_size < avail ? file_size : avail), WVC2_HEADER_SIZE);
    nchunks = wvc_get_u64(h + 208);
    tl = h[33];
    tlz = h[34];
    WVOL_RETURN_IF(nchunks > ((uint64_t)1 << 40), err, WVOL_ERR_FORMAT, ".wvc index: %llu chunks is not valid",
                   (unsigned long long)nchunks);
    hbytes = WVC2_HEADER_SIZE + nsec * WVC2_BAND_SIZE + nchunks * WVC2_CHUNK_SIZE + 4;
    WVOL_RETURN_IF(file_size < hbytes || avail < hbytes, err, WVOL_ERR_FORMAT,
                   ".wvc index truncated: %llu bytes, the header and index need %llu",
                   (unsigned long long)(file_size < avail ? file_size : avail), (unsigned long long)hbytes);
    WVOL_RETURN_IF(wvc_get_u32(h + hbytes - 4) != (uint32_t)crc32(0L, h, (uInt)(hbytes - 4)), err,
                   WVOL_ERR_FORMAT, ".wvc header or index checksum mismatch: the file is corrupt");
    WVOL_RETURN_IF(h[35] || wvc_get_u32(h + 36) || wvc_get_u64(h + 216), err, WVOL_ERR_FORMAT,
                   ".wvc header: reserved bytes are not zero");
    WVOL_RETURN_IF(tl < 3 || tl > 8 || tlz < 3 || tlz > 8, err, WVOL_ERR_FORMAT,
                   ".wvc header: tile 2^%d x 2^%d outside 8..256", tl, tlz);
    x = calloc(1, sizeof *x);
    WVOL_RETURN_IF(!x, err, WVOL_ERR_NOMEM, "wvc: out of memory");
    if (wvol__wvc2_geom(&x->g, p, I->levels, 1 << tl, 1 << tlz) || x->g.nchunks != nchunks) {
        size_t have = x->g.nchunks;
        wvol__wvc2_index_free(x);
        return wvol_error_set(err, WVOL_ERR_FORMAT, ".wvc index: %llu chunks, the grid has %zu",
                              (unsigned long long)nchunks, have);
    }
    x->chunks = malloc((nchunks ? nchunks : 1) * sizeof *x->chunks);
    if (!x->chunks) {
        wvol__wvc2_index_free(x);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc: out of memory for the chunk index");
    }
    x->step = I->step;
    x->hbytes = hbytes;
    I->nsections = (int)nsec;
    I->tile = 1 << tl;
    I->tile_z = 1 << tlz;
    I->chunks = nchunks;
    payload = wvc_get_u64(h + 200);
    for (s = 0; s < (int)nsec; s++) {
        const uint8_t *e = h + WVC2_HEADER_SIZE + (size_t)s * WVC2_BAND_SIZE;
        wvol_wvc_section *S = &I->sections[s];
        int level = s == 0 ? I->levels : I->levels - (s - 1) / 7, band = s == 0 ? 0 : 1 + (s - 1) % 7, k;
        S->level = e[0];
        S->band = e[1];
        for (k = 2; k < 8; k++)
            if (e[k]) break;
        S->nonzero = wvc_get_u64(e + 8);
        S->delta1 = wvc_get_f32(e + 16);
        S->delta2 = wvc_get_f32(e + 20);
        S->energy = wvc_get_f64(e + 24);
        S->error = wvc_get_f64(e + 32);
        S->bytes = wvc_get_u64(e + 40);
        S->count = 1;
        for (int a = 0; a < 3; a++) {
            int high = (band >> a) & 1;
            S->count *= p[a] == 1 ? (high ? 0 : 1) : p[a] >> level;
        }
        S->coder = S->nonzero ? WVOL_WVC_CODER_CABAC : WVOL_WVC_CODER_EMPTY;
        x->d1[s] = S->delta1;
        x->d2[s] = S->delta2;
        if (S->level != level || S->band != band || k < 8 || S->nonzero > S->count || S->bytes > payload ||
            !(fabsf(S->delta1) <= 1.0f) || !(fabsf(S->delta2) <= 1.0f) || !finite_nonneg(S->energy) ||
            !finite_nonneg(S->error)) {
            wvol__wvc2_index_free(x);
            return wvol_error_set(err, WVOL_ERR_FORMAT, ".wvc band table: entry %d (level %d band %d) is not valid",
                                  s, level, band);
        }
        band_nz[level] += S->nonzero;
    }
    off = hbytes;
    for (uint64_t id = 0; id < nchunks; id++) {
        const uint8_t *e = h + WVC2_HEADER_SIZE + nsec * WVC2_BAND_SIZE + id * WVC2_CHUNK_SIZE;
        wvc2_chunk *c = &x->chunks[id];
        size_t t[3], o[3], ext[3];
        int m = wvol__wvc2_chunk_coords(&x->g, (size_t)id, t);
        uint64_t cap;
        c->offset = wvc_get_u64(e);
        c->bytes = wvc_get_u32(e + 8);
        c->crc = wvc_get_u32(e + 12);
        c->maxabs = wvc_get_f32(e + 16);
        c->nonzero = wvc_get_u32(e + 20);
        c->energy = wvc_get_f64(e + 24);
        wvc2_tile_box(&x->g, m, t, o, ext);
        cap = (uint64_t)ext[0] * ext[1] * ext[2] * (uint64_t)x->g.lv[m].nb;
        if ((c->bytes ? c->offset != off : (c->offset || c->crc || c->nonzero)) || c->nonzero > cap ||
            (c->nonzero == 0) != (c->bytes == 0) || c->bytes > file_size - off || !(c->maxabs >= 0) ||
            !isfinite(c->maxabs) || !finite_nonneg(c->energy)) {
            wvol__wvc2_index_free(x);
            return wvol_error_set(err, WVOL_ERR_FORMAT,
                                  ".wvc index: chunk %llu (level %d, tile %zu,%zu,%zu) is not valid",
                                  (unsigned long long)id, m, t[0], t[1], t[2]);
        }
        off += c->bytes;
        nz_sum += c->nonzero;
        lev_nz[m] += c->nonzero;
    }
    for (int m = 1; m <= I->levels; m++)
        if (lev_nz[m] != band_nz[m]) {
            wvol__wvc2_index_free(x);
            return wvol_error_set(err, WVOL_ERR_FORMAT,
                                  ".wvc index: level %d's chunks hold %llu non-zeros, its bands %llu", m,
                                  (unsigned long long)lev_nz[m], (unsigned long long)band_nz[m]);
        }
    if (off - hbytes != payload || off != file_size || nz_sum != I->nonzero) {
        wvol__wvc2_index_free(x);
        return wvol_error_set(err, WVOL_ERR_FORMAT,
                              ".wvc file is %llu bytes but its index declares %llu: truncated or extended",
                              (unsigned long long)file_size, (unsigned long long)off);
    }
    I->header_bytes = hbytes;
    I->file_bytes = file_size;
    if (out) *out = x;
    else wvol__wvc2_index_free(x);
    return WVOL_OK;
}

int wvol__wvc2_chunk_check(const wvc2_index *x, size_t id, const uint8_t *payload, const char **why)
{
    const wvc2_chunk *c = &x->chunks[id];
    if (c->bytes && (uint32_t)crc32(0L, payload, (uInt)c->bytes) != c->crc) {
        *why = "checksum mismatch: the chunk is corrupt";
        return -1;
    }
    return 0;
}

/* Where a box at off of band `band` of level m starts in the dense pyramid (padded grid p). */
static void band_origin(size_t o[3], const size_t p[3], const wvc2_geom *g, int m, int band, const size_t off[3])
{
    (void)p;
    for (int a = 0; a < 3; a++) o[a] = off[a] + ((((band >> a) & 1) && g->tr[a]) ? g->lv[m].e[a] : 0);
}

/* The box of band `band` of chunk t at level m inside a dense pyramid Q (padded grid p). */
static wvc2_qbox dense_box(int32_t *Q, const size_t p[3], const wvc2_geom *g, int m, int band, const size_t off[3])
{
    wvc2_qbox b = {NULL, 0, 0, NULL};
    size_t o[3];
    for (int a = 0; a < 3; a++) o[a] = off[a] + ((((band >> a) & 1) && g->tr[a]) ? g->lv[m].e[a] : 0);
    b.q = Q + o[0] + p[0] * (o[1] + p[1] * o[2]);
    b.sy = p[0];
    b.sz = p[0] * p[1];
    return b;
}

void wvol__wvc2_describe(char *buf, size_t n, const wvc2_index *x, size_t id)
{
    size_t t[3];
    int m = wvol__wvc2_chunk_coords(&x->g, id, t);
    snprintf(buf, n, "chunk %zu (level %d, tile %zu,%zu,%zu)", id, m, t[0], t[1], t[2]);
}

wvol_status wvol__wvc2_decode_dense(int32_t *Q, const size_t p[3], const wvc2_index *x, const uint8_t *buf,
                                    size_t avail, int stop_level, wvc2_tile_done_fn done, void *ctx,
                                    wvol_error *err)
{
    const wvc2_geom *g = &x->g;
    /* the low-pass cube shares its chunks with the coarsest details: decoded even for
     * stop_level == levels, the details then cleared */
    for (int m = g->levels; m >= 1 && (m > stop_level || m == g->levels); m--) {
        const wvc2_level *G = &g->lv[m];
        long i;
        size_t bad = SIZE_MAX;
        const char *why = NULL;
#pragma omp parallel for schedule(dynamic, 1) if (G->count > 1)
        for (i = 0; i < (long)G->count; i++) {
            size_t id = G->first + (size_t)i, t[3], off[3], ext[3], poff[3], pext[3];
            const wvc2_chunk *c = &x->chunks[id];
            wvc2_direct dv;
            uint64_t nz;
            const char *w = NULL;
            int r = 0;
            wvol__wvc2_chunk_coords(g, id, t);
            wvc2_tile_box(g, m, t, off, ext);
            wvc2_parent_box(g, off, ext, poff, pext);
            /* in place: the pyramid holds the tile and its parent region with one set of strides */
            dv.Q = Q;
            memcpy(dv.p, p, sizeof dv.p);
            memset(dv.poff, 0, sizeof dv.poff);
            for (int k = 0; k < G->nb; k++) {
                band_origin(dv.off[k], p, g, m, G->bands[k], off);
                if (m < g->levels) band_origin(dv.poff[k], p, g, m + 1, G->bands[k], poff);
            }
            if (c->bytes && c->offset + c->bytes > avail) {
                w = "chunk lies past the end of the data read";
                r = -1;
            } else if (wvol__wvc2_chunk_check(x, id, buf + c->offset, &w)) {
                r = -1;
            } else if (wvol__wvc2_chunk_decode(g, m, ext, NULL, NULL, &dv, NULL, buf + c->offset, c->bytes, &nz, &w)) {
                r = -1;
            } else if (nz != c->nonzero) {
                w = "decoded non-zero count does not match the index";
                r = -1;
            } else if (done && m == stop_level + 1) {
                done(ctx, m, off, ext);
            }
            if (r) {
#pragma omp critical(wvc2_decode_error)
                if (id < bad) {
                    bad = id;
                    why = w;
                }
            }
        }
        if (bad != SIZE_MAX) {
            char d[96];
            wvol__wvc2_describe(d, sizeof d, x, bad);
            return wvol_error_set(err, WVOL_ERR_FORMAT, ".wvc %s: %s", d, why ? why : "malformed");
        }
    }
    if (stop_level >= g->levels) {
        const wvc2_level *G = &g->lv[g->levels];
        const size_t zero[3] = {0, 0, 0};
        for (int k = 0; k < G->nb; k++) {
            wvc2_qbox b;
            if (G->bands[k] == 0) continue;
            b = dense_box(Q, p, g, g->levels, G->bands[k], zero);
            for (size_t z = 0; z < G->e[2]; z++)
                for (size_t y = 0; y < G->e[1]; y++) memset(b.q + y * b.sy + z * b.sz, 0, G->e[0] * sizeof(int32_t));
        }
    }
    return WVOL_OK;
}
