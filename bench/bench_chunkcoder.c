/* SPDX-License-Identifier: MIT
 * The chunk coders by themselves, in process, on a .wvc file's own quantised
 * coefficients (decoded exactly from its chunks): every chunk below the coarsest level
 * (whose chunks also hold the low-pass cube) coded level by level, coarse to fine, as the
 * writer codes them (its non-zero detail bands, the parents from the level above), with
 * chunk mode 2 (CABAC with block flags), mode 3 (static-model rANS), mode 4 (rANS with
 * contexts from the rows before; its AVX2 engine where the CPU has it, and its scalar
 * decoder), and the file's own choice ("auto": the payloads as written; encode timed
 * through the codec's chunk coder with --coder auto).
 * Then decoded into a pyramid holding only the coarsest level, and compared with the
 * file's coefficients. Prints one JSON line per coder: bytes (payloads with their mode
 * and mask bytes), best encode and decode seconds of the repetitions, round trip.
 * No file I/O or page faults of the input in the timed part.
 *   bench_chunkcoder FILE.wvc [REPS]
 * Uses the codec's internal interfaces: a benchmark of the coders, not of the API. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "codec/wvc2_read.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t); /* CPU time: the machine is shared */
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

typedef struct chunk {
    size_t id;
    int m, n, nb, bands[8];
    wvc_band b[8];
    wvc2_qbox child[8], parent[8];
    size_t ext[3], boff[8][3], bpoff[8][3]; /* every band of the level */
    uint64_t nonzero, count;
} chunk;

enum { C_AUTO, C_MODE2, C_MODE3, C_MODE4 };

typedef struct coder {
    const char *name;
    int kind;
    int engine; /* mode 4's decoder: WVC_RANS4_AUTO or WVC_RANS4_SCALAR */
} coder;

static size_t level_bytes[3][WVOL_WVC_MAX_LEVELS + 1];

static int code_one(const coder *cd, const chunk *c, int32_t *Q, int32_t *D, const size_t *p, const wvc2_geom *g,
                    const uint8_t *file, const wvc2_index *x, double *te, double *td, size_t *bytes)
{
    int32_t *Qs[8], *Ds[8];
    const size_t *Ps[8];
    const wvc_band *Bs[8];
    uint8_t *buf = NULL;
    size_t sz = 0;
    uint64_t nz = 0;
    const char *why = "?";
    double t0;
    int e;
    for (int k = 0; k < c->n; k++) Qs[k] = Q, Ds[k] = D, Ps[k] = p, Bs[k] = &c->b[k];
    if (cd->kind == C_AUTO) {
        wvc2_coded out;
        wvc2_direct dv;
        const wvc2_chunk *fc = &x->chunks[c->id];
        t0 = now();
        if (wvol__wvc2_chunk_encode(&out, g, c->m, c->ext, c->child, c->parent, NULL, WVOL_WVC_CODER_AUTO, 3, NULL, NULL))
            return -1;
        *te += now() - t0;
        free(out.payload);
        dv.Q = D;
        memcpy(dv.p, p, sizeof dv.p);
        memset(dv.off, 0, sizeof dv.off);
        memset(dv.poff, 0, sizeof dv.poff);
        for (int k = 0; k < c->nb; k++) {
            memcpy(dv.off[k], c->boff[k], sizeof dv.off[k]);
            memcpy(dv.poff[k], c->bpoff[k], sizeof dv.poff[k]);
        }
        t0 = now();
        e = wvol__wvc2_chunk_decode(g, c->m, c->ext, NULL, NULL, &dv, NULL, file + fc->offset, fc->bytes, &nz, &why);
        *td += now() - t0;
        if (e || nz != c->nonzero) {
            fprintf(stderr, "auto: chunk %zu: %s\n", c->id, e ? why : "count");
            return -1;
        }
        *bytes += fc->bytes;
        level_bytes[0][c->m] += fc->bytes;
        return 0;
    }
    t0 = now();
    e = cd->kind == C_MODE2   ? wvol__wvc_cabac_encode_multi(&buf, &sz, c->n, Qs, Ps, Bs, 1)
        : cd->kind == C_MODE3 ? wvol__wvc_rans_encode(&buf, &sz, c->n, Qs, Ps, Bs, NULL)
                              : wvol__wvc_rans4_encode(&buf, &sz, 0, c->n, Qs, Ps, Bs, NULL);
    *te += now() - t0;
    if (e) return -1;
    t0 = now();
    e = cd->kind == C_MODE2   ? wvol__wvc_cabac_decode_multi(c->n, Ds, Ps, Bs, buf, sz, 1, &nz, &why)
        : cd->kind == C_MODE3 ? wvol__wvc_rans_decode(c->n, Ds, Ps, Bs, buf, sz, &nz, &why)
                              : wvol__wvc_rans4_decode(c->n, Ds, Ps, Bs, buf, sz, cd->engine, &nz, &why);
    *td += now() - t0;
    free(buf);
    if (e || nz != c->nonzero) {
        fprintf(stderr, "%s: chunk %zu: %s\n", cd->name, c->id, e ? why : "non-zero count");
        return -1;
    }
    *bytes += sz + 2;
    if (cd->kind <= C_MODE3) level_bytes[cd->kind][c->m] += sz + 2;
    return 0;
}

int main(int argc, char **argv)
{
    int reps = argc > 2 ? atoi(argv[2]) : 3;
    FILE *f;
    uint8_t *file;
    long fsize;
    wvol_wvc_info I;
    wvol_error err;
    wvc2_index *x = NULL;
    const wvc2_geom *g;
    size_t n, nch = 0;
    int32_t *Q, *D, *D0;
    chunk *ch;
    static const coder coders[] = {
        {"auto", C_AUTO, 0},
        {"mode2", C_MODE2, 0},
        {"mode3", C_MODE3, 0},
        {"mode4", C_MODE4, WVC_RANS4_AUTO},
        {"mode4_scalar", C_MODE4, WVC_RANS4_SCALAR},
    };
    const char *only = getenv("CODERS");
    if (argc < 2 || reps < 1) {
        fprintf(stderr, "usage: bench_chunkcoder FILE.wvc [REPS]\n");
        return 2;
    }
    f = fopen(argv[1], "rb");
    if (!f || fseek(f, 0, SEEK_END) || (fsize = ftell(f)) <= 0 || fseek(f, 0, SEEK_SET)) return 1;
    file = malloc((size_t)fsize);
    if (!file || fread(file, 1, (size_t)fsize, f) != (size_t)fsize) return 1;
    fclose(f);
    if (wvol__wvc_parse_prefix(&I, file, (size_t)fsize, (uint64_t)fsize, &err) != WVOL_OK ||
        wvol__wvc2_parse(&I, &x, file, (size_t)fsize, (uint64_t)fsize, &err) != WVOL_OK || !x) {
        fprintf(stderr, "bench_chunkcoder: %s (a version-2 file is needed)\n", err.message);
        return 1;
    }
    g = &x->g;
    n = g->p[0] * g->p[1] * g->p[2];
    Q = calloc(n, sizeof *Q);
    D = malloc(n * sizeof *D);
    D0 = calloc(n, sizeof *D0);
    ch = calloc(g->nchunks, sizeof *ch);
    if (!Q || !D || !D0 || !ch) return 1;
    if (wvol__wvc2_decode_dense(Q, g->p, x, file, (size_t)fsize, 0, NULL, NULL, &err) != WVOL_OK) {
        fprintf(stderr, "bench_chunkcoder: %s\n", err.message);
        return 1;
    }
    /* D0: the coarsest level's chunks (all bands there) only */
    {
        const wvc2_level *Lv = &g->lv[g->levels];
        for (size_t z = 0; z < 2 * Lv->e[2] && z < g->p[2]; z++)
            for (size_t y = 0; y < 2 * Lv->e[1] && y < g->p[1]; y++)
                memcpy(D0 + g->p[0] * (y + g->p[1] * z), Q + g->p[0] * (y + g->p[1] * z),
                       (2 * Lv->e[0] < g->p[0] ? 2 * Lv->e[0] : g->p[0]) * sizeof *Q);
    }
    for (int m = g->levels - 1; m >= 1; m--) {
        const wvc2_level *Lv = &g->lv[m];
        for (size_t i = 0; i < Lv->count; i++) {
            chunk *c = &ch[nch];
            size_t id = Lv->first + i, t[3], off[3], poff[3], pext[3];
            if (!x->chunks[id].bytes) continue;
            wvol__wvc2_chunk_coords(g, id, t);
            wvc2_tile_box(g, m, t, off, c->ext);
            wvc2_parent_box(g, off, c->ext, poff, pext);
            c->id = id;
            c->m = m;
            c->nb = Lv->nb;
            for (int k = 0; k < Lv->nb; k++) {
                const int band = Lv->bands[k];
                wvc_band *b = &c->b[c->n];
                uint64_t nz = 0;
                memset(b, 0, sizeof *b);
                b->level = m;
                b->band = band;
                b->has_parent = 1;
                c->bands[k] = band;
                for (int a = 0; a < 3; a++) {
                    const int hi = ((band >> a) & 1) && g->tr[a];
                    b->off[a] = off[a] + (hi ? Lv->e[a] : 0);
                    b->ext[a] = c->ext[a];
                    b->poff[a] = poff[a] + (hi ? g->lv[m + 1].e[a] : 0);
                    b->pext[a] = pext[a];
                    c->boff[k][a] = b->off[a];
                    c->bpoff[k][a] = b->poff[a];
                }
                b->count = (uint64_t)c->ext[0] * c->ext[1] * c->ext[2];
                c->child[k].q = Q + b->off[0] + g->p[0] * (b->off[1] + g->p[1] * b->off[2]);
                c->parent[k].q = Q + b->poff[0] + g->p[0] * (b->poff[1] + g->p[1] * b->poff[2]);
                c->child[k].sy = c->parent[k].sy = g->p[0];
                c->child[k].sz = c->parent[k].sz = g->p[0] * g->p[1];
                c->count += b->count;
                for (size_t z = 0; z < b->ext[2]; z++)
                    for (size_t y = 0; y < b->ext[1]; y++) {
                        const int32_t *r = Q + wvc_index(g->p, b, 0, y, z);
                        for (size_t xx = 0; xx < b->ext[0]; xx++) nz += r[xx] != 0;
                    }
                if (nz) c->n++;
                c->nonzero += nz;
            }
            if (c->n) nch++;
        }
    }
    for (size_t k = 0; k < sizeof coders / sizeof *coders; k++) {
        const coder *cd = &coders[k];
        double be = INFINITY, bd = INFINITY;
        size_t bytes = 0;
        uint64_t coefs = 0, nonzero = 0;
        int bad = 0;
        if (only && !strstr(only, cd->name)) continue;
        for (int r = 0; r < reps; r++) {
            double te = 0, td = 0;
            memcpy(D, D0, n * sizeof *D);
            bytes = 0;
            coefs = nonzero = 0;
            if (cd->kind <= C_MODE3) memset(level_bytes[cd->kind], 0, sizeof level_bytes[cd->kind]);
            for (size_t i = 0; i < nch; i++) {
                if (code_one(cd, &ch[i], Q, D, g->p, g, file, x, &te, &td, &bytes)) return 1;
                coefs += ch[i].count;
                nonzero += ch[i].nonzero;
            }
            be = te < be ? te : be;
            bd = td < bd ? td : bd;
        }
        bad = memcmp(Q, D, n * sizeof *Q) != 0;
        printf("{\"file\":\"%s\",\"coder\":\"%s\",\"chunks\":%zu,\"coefficients\":%llu,\"nonzero\":%llu,"
               "\"bytes\":%zu,\"encode_s\":%.5f,\"decode_s\":%.5f,\"decode_ns_coef\":%.2f,\"roundtrip\":%s}\n",
               argv[1], cd->name, nch, (unsigned long long)coefs, (unsigned long long)nonzero, bytes, be, bd,
               1e9 * bd / (double)coefs, bad ? "false" : "true");
        fflush(stdout);
    }
    if (getenv("LEVELS"))
        for (int m = g->levels - 1; m >= 1; m--)
            fprintf(stderr, "level %d: auto %zu mode2 %zu mode3 %zu\n", m, level_bytes[0][m], level_bytes[1][m],
                    level_bytes[2][m]);
    free(Q);
    free(D);
    free(D0);
    free(ch);
    free(file);
    wvol__wvc2_index_free(x);
    return 0;
}
