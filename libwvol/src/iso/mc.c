/* SPDX-License-Identifier: MIT */
/* Marching cubes on a dense grid, organised as flying edges: every x-row of
 * samples becomes a bit mask (sample >= iso), and everything after that is bit
 * arithmetic on masks until vertices and triangles are written once each into
 * arrays sized in advance.
 *   pass 1  classify: one bit per sample, rows of 64-bit words (SIMD compares)
 *   pass 2  count: per row, intersected x/y/z edges (popcount of XOR-ed masks)
 *           and triangles of the row's active cells (cells whose 8 corner bits
 *           are not all equal: found word-wise, visited with count-trailing-zeros)
 *   prefix  row offsets of vertices and triangles
 *   pass 3  generate: a vertex per intersected edge owned by the row (x, then y,
 *           then z edges, increasing i); each active cell's triangles index those
 *           vertices by rank (popcount of the mask below the cell), so vertices
 *           are shared with no hashing and no duplicates.
 * Rows are independent in passes 1-3, so OpenMP splits them; the output does not
 * depend on the thread count.
 * Based on: Lorensen & Cline 1987 (marching cubes); Schroeder, Maynard & Geveci
 * 2015 (flying edges: edge-based passes, precomputed output sizes). */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/alloc.h"
#include "core/clock.h"
#include "iso/iso_internal.h"
#include "iso/mc_tables.h"

static inline int popc(uint64_t x) { return __builtin_popcountll(x); }

/* ---- pass 1 ---------------------------------------------------------------- */

WVOL__CLONES
static void classify_row(uint64_t *bits, const float *row, size_t n, float iso)
{
    size_t nw = (n + 63) >> 6, w;
    for (w = 0; w < nw; w++) {
        const float *p = row + (w << 6);
        size_t cnt = n - (w << 6), q;
        uint64_t m = 0;
        if (cnt >= 64) {
#if defined(__SSE2__)
            __m128 t = _mm_set1_ps(iso);
            for (q = 0; q < 16; q++)
                m |= (uint64_t)_mm_movemask_ps(_mm_cmpge_ps(_mm_loadu_ps(p + 4 * q), t)) << (4 * q);
#else
            for (q = 0; q < 64; q++) m |= (uint64_t)(p[q] >= iso) << q;
#endif
        } else {
            for (q = 0; q < cnt; q++) m |= (uint64_t)(p[q] >= iso) << q;
        }
        bits[w] = m;
    }
}

/* ---- shared row geometry ----------------------------------------------------- */

typedef struct mc_ctx {
    const wvol__mc_job *job;
    size_t nx, ny, nz, nw;     /* region size, words per row */
    const uint64_t *bits;      /* (ny * nz) rows of nw words */
    uint64_t last_mask;        /* valid x-edge / cell bits of the last word (i < nx - 1) */
    uint32_t *cnt;             /* per row: x, y, z vertices, triangles, active cells */
    uint64_t *vbase, *tbase;   /* per row offsets */
    float isof;
    wvol_mesh *mesh;
    uint64_t *keys;
    unsigned char *vflags;
    int bad;                   /* non-finite sample met */
    size_t bad_at[3];
} mc_ctx;

static inline uint64_t next_word(const uint64_t *row, size_t w, size_t nw)
{
    return w + 1 < nw ? row[w + 1] : 0;
}

/* cells / x-edges valid in word w: i < nx - 1 */
static inline uint64_t valid_mask(const mc_ctx *c, size_t w)
{
    return w + 1 < c->nw ? ~(uint64_t)0 : c->last_mask;
}

/* ---- pass 2 ---------------------------------------------------------------- */

WVOL__CLONES
static void count_row(mc_ctx *c, size_t r)
{
    const size_t nw = c->nw, ny = c->ny;
    const size_t j = r % ny, k = r / ny;
    const uint64_t *B = c->bits + r * nw;
    uint32_t nxv = 0, nyv = 0, nzv = 0, ntri = 0, nact = 0;
    size_t w;
    for (w = 0; w < nw; w++) {
        uint64_t R = B[w], S = (R >> 1) | (next_word(B, w, nw) << 63);
        nxv += (uint32_t)popc((R ^ S) & valid_mask(c, w));
    }
    if (j + 1 < ny) {
        const uint64_t *B1 = B + nw;
        for (w = 0; w < nw; w++) nyv += (uint32_t)popc(B[w] ^ B1[w]);
    }
    if (k + 1 < c->nz) {
        const uint64_t *B2 = B + ny * nw;
        for (w = 0; w < nw; w++) nzv += (uint32_t)popc(B[w] ^ B2[w]);
    }
    if (j + 1 < ny && k + 1 < c->nz) {
        const uint64_t *B10 = B + nw, *B01 = B + ny * nw, *B11 = B01 + nw;
        for (w = 0; w < nw; w++) {
            uint64_t R00 = B[w], R10 = B10[w], R01 = B01[w], R11 = B11[w];
            uint64_t S00 = (R00 >> 1) | (next_word(B, w, nw) << 63);
            uint64_t S10 = (R10 >> 1) | (next_word(B10, w, nw) << 63);
            uint64_t S01 = (R01 >> 1) | (next_word(B01, w, nw) << 63);
            uint64_t S11 = (R11 >> 1) | (next_word(B11, w, nw) << 63);
            uint64_t all = R00 & S00 & R10 & S10 & R01 & S01 & R11 & S11;
            uint64_t any = R00 | S00 | R10 | S10 | R01 | S01 | R11 | S11;
            uint64_t act = any & ~all & valid_mask(c, w);
            nact += (uint32_t)popc(act);
            while (act) {
                int b = __builtin_ctzll(act);
                unsigned cs = (unsigned)(((R00 >> b) & 1) | (((S00 >> b) & 1) << 1) |
                                         (((R10 >> b) & 1) << 2) | (((S10 >> b) & 1) << 3) |
                                         (((R01 >> b) & 1) << 4) | (((S01 >> b) & 1) << 5) |
                                         (((R11 >> b) & 1) << 6) | (((S11 >> b) & 1) << 7));
                ntri += wvol__mc_ntri[cs];
                act &= act - 1;
            }
        }
    }
    c->cnt[5 * r + 0] = nxv;
    c->cnt[5 * r + 1] = nyv;
    c->cnt[5 * r + 2] = nzv;
    c->cnt[5 * r + 3] = ntri;
    c->cnt[5 * r + 4] = nact;
}

/* ---- pass 3 ---------------------------------------------------------------- */

/* Sample at region-local (i, j, k). */
static inline float sample(const mc_ctx *c, long i, long j, long k)
{
    const wvol__mc_job *jb = c->job;
    size_t ia = jb->lo[0] + (size_t)i, ja = jb->lo[1] + (size_t)j, ka = jb->lo[2] + (size_t)k;
    return jb->data[ia + jb->adims[0] * (ja + jb->adims[1] * ka)];
}

/* Gradient (index units) at region-local sample (i, j, k), from the whole array:
 * central differences, one-sided at the array's border. */
static void grad_at(const mc_ctx *c, size_t i, size_t j, size_t k, double g[3])
{
    const wvol__mc_job *jb = c->job;
    size_t p[3] = {jb->lo[0] + i, jb->lo[1] + j, jb->lo[2] + k};
    size_t st[3] = {1, jb->adims[0], jb->adims[0] * jb->adims[1]};
    const float *v = jb->data + p[0] + st[1] * p[1] + st[2] * p[2];
    int a;
    for (a = 0; a < 3; a++) {
        size_t n = jb->adims[a];
        if (n < 2)
            g[a] = 0.0;
        else if (p[a] == 0)
            g[a] = (double)v[st[a]] - (double)v[0];
        else if (p[a] == n - 1)
            g[a] = (double)v[0] - (double)v[-(ptrdiff_t)st[a]];
        else
            g[a] = 0.5 * ((double)v[st[a]] - (double)v[-(ptrdiff_t)st[a]]);
    }
}

static void put_vertex(mc_ctx *c, uint64_t id, size_t i, size_t j, size_t k, int axis)
{
    const wvol__mc_job *jb = c->job;
    size_t q[3] = {i, j, k};
    float a = sample(c, (long)i, (long)j, (long)k);
    float b = sample(c, (long)i + (axis == 0), (long)j + (axis == 1), (long)k + (axis == 2));
    double t, pos[3], idx[3];
    float *vp = c->mesh->verts + 3 * id;
    int d;
    if (!isfinite(a) || !isfinite(b)) {
#ifdef _OPENMP
#pragma omp critical(wvol_mc_bad)
#endif
        if (!c->bad) {
            c->bad = 1;
            c->bad_at[0] = (size_t)((long long)(jb->lo[0] + i) + jb->gofs[0]);
            c->bad_at[1] = (size_t)((long long)(jb->lo[1] + j) + jb->gofs[1]);
            c->bad_at[2] = (size_t)((long long)(jb->lo[2] + k) + jb->gofs[2]);
        }
        vp[0] = vp[1] = vp[2] = 0.0f;
        if (c->mesh->normals) c->mesh->normals[3 * id] = c->mesh->normals[3 * id + 1] =
            c->mesh->normals[3 * id + 2] = 0.0f;
        return;
    }
    if (c->keys) {
        uint64_t gi = (uint64_t)((long long)(jb->lo[0] + i) + jb->gofs[0]);
        uint64_t gj = (uint64_t)((long long)(jb->lo[1] + j) + jb->gofs[1]);
        uint64_t gk = (uint64_t)((long long)(jb->lo[2] + k) + jb->gofs[2]);
        const int key_only = (jb->key_only[0] && i == c->nx - 1) || (jb->key_only[1] && j == c->ny - 1) ||
                             (jb->key_only[2] && k == c->nz - 1);
        c->keys[id] = wvol__edge_key(jb->gdims, gi, gj, gk, axis);
        if (c->vflags)
            c->vflags[id] = (unsigned char)((key_only ? WVOL__MC_KEY_ONLY : 0) |
                                            (((jb->first_shared[0] && i == 0) || (jb->first_shared[1] && j == 0) ||
                                              (jb->first_shared[2] && k == 0))
                                                 ? WVOL__MC_FIRST
                                                 : 0));
        if (key_only) return; /* another mesh places this vertex */
    }
    t = ((double)c->isof - (double)a) / ((double)b - (double)a);
    for (d = 0; d < 3; d++) {
        idx[d] = (double)((long long)(jb->lo[d] + q[d]) + jb->gofs[d]) + (d == axis ? t : 0.0);
        pos[d] = jb->origin[d] + jb->spacing[d] * idx[d];
        vp[d] = (float)pos[d];
    }
    if (c->mesh->normals) {
        double g[3], g0[3], g1[3], len;
        float *np = c->mesh->normals + 3 * id;
        if (jb->normals == WVOL_ISO_NORMALS_ANALYTIC) {
            jb->gradient(jb->gradient_user, pos, g);
        } else {
            grad_at(c, i, j, k, g0);
            grad_at(c, i + (axis == 0), j + (axis == 1), k + (axis == 2), g1);
            for (d = 0; d < 3; d++) g[d] = ((1.0 - t) * g0[d] + t * g1[d]) / jb->spacing[d];
        }
        len = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        if (len > 0.0 && isfinite(len)) {
            for (d = 0; d < 3; d++) np[d] = (float)(-g[d] / len);
        } else {
            np[0] = np[1] = np[2] = 0.0f;
        }
    }
}

static void vertices_row(mc_ctx *c, size_t r)
{
    const size_t nw = c->nw, ny = c->ny;
    const size_t j = r % ny, k = r / ny;
    const uint64_t *B = c->bits + r * nw;
    uint64_t id = c->vbase[r];
    size_t w;
    for (w = 0; w < nw; w++) {
        uint64_t R = B[w], S = (R >> 1) | (next_word(B, w, nw) << 63);
        uint64_t X = (R ^ S) & valid_mask(c, w);
        while (X) {
            put_vertex(c, id++, (w << 6) + (size_t)__builtin_ctzll(X), j, k, 0);
            X &= X - 1;
        }
    }
    if (j + 1 < ny) {
        const uint64_t *B1 = B + nw;
        for (w = 0; w < nw; w++) {
            uint64_t Y = B[w] ^ B1[w];
            while (Y) {
                put_vertex(c, id++, (w << 6) + (size_t)__builtin_ctzll(Y), j, k, 1);
                Y &= Y - 1;
            }
        }
    }
    if (k + 1 < c->nz) {
        const uint64_t *B2 = B + ny * nw;
        for (w = 0; w < nw; w++) {
            uint64_t Z = B[w] ^ B2[w];
            while (Z) {
                put_vertex(c, id++, (w << 6) + (size_t)__builtin_ctzll(Z), j, k, 2);
                Z &= Z - 1;
            }
        }
    }
}

WVOL__CLONES
static void triangles_row(mc_ctx *c, size_t r)
{
    const size_t nw = c->nw, ny = c->ny;
    const uint64_t *B = c->bits + r * nw, *B10 = B + nw, *B01 = B + ny * nw, *B11 = B01 + nw;
    const uint32_t *cn = c->cnt;
    const size_t r10 = r + 1, r01 = r + ny, r11 = r + ny + 1;
    uint32_t cx00 = (uint32_t)c->vbase[r], cx10 = (uint32_t)c->vbase[r10];
    uint32_t cx01 = (uint32_t)c->vbase[r01], cx11 = (uint32_t)c->vbase[r11];
    uint32_t cy00 = cx00 + cn[5 * r], cy01 = cx01 + cn[5 * r01];
    uint32_t cz00 = cx00 + cn[5 * r] + cn[5 * r + 1];
    uint32_t cz10 = cx10 + cn[5 * r10] + cn[5 * r10 + 1];
    uint32_t *out = c->mesh->tris + 3 * c->tbase[r];
    size_t w;
    for (w = 0; w < nw; w++) {
        uint64_t vm = valid_mask(c, w);
        uint64_t R00 = B[w], R10 = B10[w], R01 = B01[w], R11 = B11[w];
        uint64_t S00 = (R00 >> 1) | (next_word(B, w, nw) << 63);
        uint64_t S10 = (R10 >> 1) | (next_word(B10, w, nw) << 63);
        uint64_t S01 = (R01 >> 1) | (next_word(B01, w, nw) << 63);
        uint64_t S11 = (R11 >> 1) | (next_word(B11, w, nw) << 63);
        uint64_t X00 = (R00 ^ S00) & vm, X10 = (R10 ^ S10) & vm;
        uint64_t X01 = (R01 ^ S01) & vm, X11 = (R11 ^ S11) & vm;
        uint64_t Y00 = R00 ^ R10, Y01 = R01 ^ R11, Z00 = R00 ^ R01, Z10 = R10 ^ R11;
        uint64_t all = R00 & S00 & R10 & S10 & R01 & S01 & R11 & S11;
        uint64_t any = R00 | S00 | R10 | S10 | R01 | S01 | R11 | S11;
        uint64_t act = any & ~all & vm;
        while (act) {
            int b = __builtin_ctzll(act);
            uint64_t low = (((uint64_t)1) << b) - 1;
            unsigned cs = (unsigned)(((R00 >> b) & 1) | (((S00 >> b) & 1) << 1) |
                                     (((R10 >> b) & 1) << 2) | (((S10 >> b) & 1) << 3) |
                                     (((R01 >> b) & 1) << 4) | (((S01 >> b) & 1) << 5) |
                                     (((R11 >> b) & 1) << 6) | (((S11 >> b) & 1) << 7));
            uint32_t id[12], y0, y1, z0, z1;
            const uint8_t *tt = wvol__mc_tris[cs];
            int t, nt = wvol__mc_ntri[cs];
            id[0] = cx00 + (uint32_t)popc(X00 & low);
            id[1] = cx10 + (uint32_t)popc(X10 & low);
            id[2] = cx01 + (uint32_t)popc(X01 & low);
            id[3] = cx11 + (uint32_t)popc(X11 & low);
            y0 = cy00 + (uint32_t)popc(Y00 & low);
            y1 = cy01 + (uint32_t)popc(Y01 & low);
            z0 = cz00 + (uint32_t)popc(Z00 & low);
            z1 = cz10 + (uint32_t)popc(Z10 & low);
            id[4] = y0;
            id[5] = y0 + (uint32_t)((Y00 >> b) & 1);
            id[6] = y1;
            id[7] = y1 + (uint32_t)((Y01 >> b) & 1);
            id[8] = z0;
            id[9] = z0 + (uint32_t)((Z00 >> b) & 1);
            id[10] = z1;
            id[11] = z1 + (uint32_t)((Z10 >> b) & 1);
            for (t = 0; t < nt; t++) {
                out[0] = id[tt[0]];
                out[1] = id[tt[1]];
                out[2] = id[tt[2]];
                out += 3;
                tt += 3;
            }
            act &= act - 1;
        }
        cx00 += (uint32_t)popc(X00);
        cx10 += (uint32_t)popc(X10);
        cx01 += (uint32_t)popc(X01);
        cx11 += (uint32_t)popc(X11);
        cy00 += (uint32_t)popc(Y00);
        cy01 += (uint32_t)popc(Y01);
        cz00 += (uint32_t)popc(Z00);
        cz10 += (uint32_t)popc(Z10);
    }
}

/* ---- driver ------------------------------------------------------------------ */

static void empty_stats(wvol_iso_stats *st, const wvol__mc_job *jb, const char *why)
{
    size_t i, j, k;
    double lo = INFINITY, hi = -INFINITY;
    if (!st) return;
    for (k = 0; k < jb->n[2]; k++)
        for (j = 0; j < jb->n[1]; j++) {
            const float *row =
                jb->data + jb->lo[0] + jb->adims[0] * ((jb->lo[1] + j) + jb->adims[1] * (jb->lo[2] + k));
            for (i = 0; i < jb->n[0]; i++) {
                double x = row[i];
                if (x < lo) lo = x;
                if (x > hi) hi = x;
            }
        }
    st->empty = 1;
    st->data_min = lo;
    st->data_max = hi;
    if (why)
        snprintf(st->message, sizeof st->message, "%s: empty mesh", why);
    else if (jb->iso <= lo || jb->iso > hi)
        snprintf(st->message, sizeof st->message,
                 "iso-value %.9g is outside the data range [%.9g, %.9g]: empty mesh", jb->iso, lo, hi);
    else
        snprintf(st->message, sizeof st->message, "the surface at iso-value %.9g crosses no cell: empty mesh",
                 jb->iso);
}

wvol_status wvol__mc_run(wvol_mesh **out, const wvol__mc_job *jb, wvol_iso_stats *st, wvol_error *err)
{
    mc_ctx c;
    size_t rows, r, nw, bits_words, cnt_bytes;
    uint64_t *bits = NULL, nv = 0, nt = 0, active = 0;
    wvol_status s = WVOL_OK;
    int nth = jb->threads > 0 ? jb->threads : 1;
    double t0 = wvol__now(), t1, t2, t3;
    wvol_mesh *m = NULL;

    *out = NULL;
    if (jb->keys) *jb->keys = NULL;
    if (jb->vflags) *jb->vflags = NULL;
    memset(&c, 0, sizeof c);
    c.job = jb;
    c.nx = jb->n[0];
    c.ny = jb->n[1];
    c.nz = jb->n[2];
    c.isof = (float)jb->iso;
    if (c.nx < 2 || c.ny < 2 || c.nz < 2) {
        WVOL_FORWARD(wvol_mesh_create(out, 0, 0, 0, err));
        empty_stats(st, jb, "the volume has fewer than 2 samples along an axis (no cells)");
        return WVOL_OK;
    }
    if (!isfinite(jb->iso) || !isfinite((double)c.isof))
        return wvol_error_set(err, WVOL_ERR_ARG, "iso-value %g is not a finite float", jb->iso);

    nw = c.nw = (c.nx + 63) >> 6;
    rows = c.ny * c.nz;
    /* nx - 1 valid cell/x-edge bits in all; the last word holds (nx - 1) - 64 (nw - 1)
     * of them, between 0 and 63 */
    c.last_mask = (((uint64_t)1) << ((c.nx - 1) - 64 * (nw - 1))) - 1;
    /* one block for the mask, the row offsets and the row counts, each filled whole: in huge
     * pages, and the last extraction's block again where extractions follow one another
     * (core/alloc.h): in 4 KiB pages their first touches were paid anew on every extraction
     * (bench/results/iso_topology.md) */
    if (!wvol_size_mul3(rows, nw + 2, 1, sizeof(uint64_t), &bits_words) ||
        !wvol_size_mul3(rows, 5, 1, sizeof *c.cnt, &cnt_bytes) || bits_words > SIZE_MAX - cnt_bytes - 16)
        return wvol_error_set(err, WVOL_ERR_NOMEM, "marching cubes: mask size overflows");
    bits = wvol__reuse_get(bits_words + 16 + cnt_bytes);
    if (!bits) return wvol_error_set(err, WVOL_ERR_NOMEM, "marching cubes: out of memory for %zu rows", rows);
    c.vbase = bits + rows * nw;
    c.tbase = c.vbase + rows + 1;
    c.cnt = (uint32_t *)(c.tbase + rows + 1);
    c.bits = bits;

    /* pass 1 */
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nth) if (nth > 1)
#endif
    for (r = 0; r < rows; r++) {
        size_t j = r % c.ny, k = r / c.ny;
        const float *row =
            jb->data + jb->lo[0] + jb->adims[0] * ((jb->lo[1] + j) + jb->adims[1] * (jb->lo[2] + k));
        classify_row(bits + r * nw, row, c.nx, c.isof);
    }
    t1 = wvol__now();

    /* pass 2 */
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nth) if (nth > 1)
#endif
    for (r = 0; r < rows; r++) count_row(&c, r);

    for (r = 0; r < rows; r++) {
        c.vbase[r] = nv;
        c.tbase[r] = nt;
        nv += (uint64_t)c.cnt[5 * r] + c.cnt[5 * r + 1] + c.cnt[5 * r + 2];
        nt += c.cnt[5 * r + 3];
    }
    c.vbase[rows] = nv;
    c.tbase[rows] = nt;
    t2 = wvol__now();
    if (nv > UINT32_MAX) {
        s = wvol_error_set(err, WVOL_ERR_DIMS,
                           "marching cubes: %llu vertices exceed 32-bit indices; mesh a smaller region",
                           (unsigned long long)nv);
        goto done;
    }
    s = wvol_mesh_create(&m, (size_t)nv, (size_t)nt, jb->normals != WVOL_ISO_NORMALS_NONE, err);
    if (s != WVOL_OK) goto done;
    if (jb->keys && nv) {
        c.keys = wvol__malloc_large(nv * sizeof *c.keys);
        if (jb->vflags) c.vflags = malloc(nv);
        if (!c.keys || (jb->vflags && !c.vflags)) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "marching cubes: out of memory for edge keys");
            goto done;
        }
    }
    c.mesh = m;

    /* pass 3 */
    if (nv) {
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 64) num_threads(nth) if (nth > 1)
#endif
        for (r = 0; r < rows; r++) {
            size_t j = r % c.ny, k = r / c.ny;
            if (c.cnt[5 * r] + c.cnt[5 * r + 1] + c.cnt[5 * r + 2])
                vertices_row(&c, r);
            if (j + 1 < c.ny && k + 1 < c.nz && c.cnt[5 * r + 3]) triangles_row(&c, r);
        }
    }
    t3 = wvol__now();
    if (c.bad) {
        s = wvol_error_set(err, WVOL_ERR_NONFINITE,
                           "marching cubes: non-finite sample next to the surface near voxel (%zu, %zu, %zu)",
                           c.bad_at[0], c.bad_at[1], c.bad_at[2]);
        goto done;
    }
    if (st) {
        for (r = 0; r < rows; r++) active += c.cnt[5 * r + 4];
        st->cells_active += (size_t)active;
        st->seconds[0] += t1 - t0;
        st->seconds[1] += t2 - t1;
        st->seconds[2] += t3 - t2;
        st->seconds[3] += t3 - t0;
    }
    if (nt == 0) empty_stats(st, jb, NULL);
    *out = m;
    m = NULL;
    if (jb->keys) {
        *jb->keys = c.keys;
        c.keys = NULL;
        if (jb->vflags) *jb->vflags = c.vflags;
        c.vflags = NULL;
    }
done:
    wvol_mesh_destroy(m);
    free(c.keys);
    free(c.vflags);
    wvol__reuse_put(bits);
    return s;
}

wvol_status wvol__iso_params_check(const wvol_iso_params *p, wvol_error *err)
{
    WVOL_RETURN_IF(p->normals < WVOL_ISO_NORMALS_NONE || p->normals > WVOL_ISO_NORMALS_ANALYTIC, err, WVOL_ERR_ARG,
                   "iso: unknown normals %d (0: none, 1: gradient, 2: analytic)", (int)p->normals);
    WVOL_RETURN_IF(p->normals == WVOL_ISO_NORMALS_ANALYTIC && !p->gradient, err, WVOL_ERR_ARG,
                   "iso: analytic normals requested without a gradient function");
    return wvol__threads_check(p->threads, "iso", err);
}

wvol_status wvol__iso_vertex_range_check(const double origin[3], const double spacing[3], const size_t n[3],
                                         wvol_error *err)
{
    double reach = 0.0, finest = INFINITY;
    for (int a = 0; a < 3; a++) {
        const double hi = origin[a] + spacing[a] * (double)(n[a] ? n[a] - 1 : 0);
        reach = fmax(reach, fmax(fabs(origin[a]), fabs(hi)));
        finest = fmin(finest, spacing[a]);
    }
    WVOL_RETURN_IF(!(reach <= FLT_MAX), err, WVOL_ERR_ARG,
                   "iso: the volume reaches %g in world units, beyond float32's range (%g): the mesh's float32 "
                   "vertices cannot hold it; give a smaller spacing or origin",
                   reach, (double)FLT_MAX);
    /* float32's spacing at |x| is at most |x| 2^-23 */
    WVOL_RETURN_IF(ldexp(reach, -23) > finest / 8, err, WVOL_ERR_ARG,
                   "iso: the volume reaches %g in world units, where float32 vertices are %g apart, more than an "
                   "eighth of its voxel spacing %g: the mesh would be snapped out of shape; move the origin nearer "
                   "0 (the mesh can be placed back with its world offset)",
                   reach, ldexp(reach, -23), finest);
    return WVOL_OK;
}

void wvol_iso_params_default(wvol_iso_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->threads = 0;
    p->normals = WVOL_ISO_NORMALS_GRADIENT;
    p->brick = 32;
}

wvol_status wvol_iso_extract(wvol_mesh **out, const wvol_volume *v, double iso, const wvol_iso_params *p,
                             wvol_iso_stats *st, wvol_error *err)
{
    wvol__mc_job jb;
    wvol_iso_params def;
    int a;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "iso: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "iso: volume is NULL or has no data");
    if (!p) {
        wvol_iso_params_default(&def);
        p = &def;
    }
    WVOL_FORWARD(wvol__iso_params_check(p, err));
    if (st) memset(st, 0, sizeof *st);
    memset(&jb, 0, sizeof jb);
    jb.data = v->data;
    jb.adims[0] = jb.n[0] = jb.gdims[0] = v->nx;
    jb.adims[1] = jb.n[1] = jb.gdims[1] = v->ny;
    jb.adims[2] = jb.n[2] = jb.gdims[2] = v->nz;
    for (a = 0; a < 3; a++) {
        jb.origin[a] = v->origin[a];
        jb.spacing[a] = v->spacing[a];
        WVOL_RETURN_IF(!(v->spacing[a] > 0.0) || !isfinite(v->spacing[a]) || !isfinite(v->origin[a]), err,
                       WVOL_ERR_ARG, "iso: spacing/origin along axis %d is invalid", a);
    }
    WVOL_FORWARD(wvol__iso_vertex_range_check(jb.origin, jb.spacing, jb.n, err));
    jb.iso = iso;
#ifdef _OPENMP
    jb.threads = p->threads > 0 ? p->threads : omp_get_max_threads();
#else
    jb.threads = 1;
#endif
    jb.normals = p->normals;
    jb.gradient = p->gradient;
    jb.gradient_user = p->gradient_user;
    return wvol__mc_run(out, &jb, st, err);
}
