/* SPDX-License-Identifier: MIT
 * A piece of an open .wvc file (version 2) that spans the grid along x and y: a z slab,
 * or the whole volume, as a parallel reader's rank asks for it. Its coefficients are
 * decoded straight into the caller's work array, in the Mallat layout of the slab's
 * coefficient windows, and the inverse transform runs in place there: the working memory
 * beyond the output is a few planes of filter margins, one chain of decoded chunks and the
 * chunks in flight, whatever the piece's size.
 *
 * Windows: R_s = [z0, z1) in the output level s's grid; R_m (m > s) the level-m positions
 * k whose synthesis taps reach R_{m-1} (0 <= i - 2k <= L - 1), the whole period once they
 * cover it (then taken modulo it). Layout of level m in the work array (x, y strides of the
 * level-s grid): bands with a low z half at planes [0, n_m), those with a high z half at
 * planes [S_m, S_m + n_m), the x and y halves as in the in-place transform; S_m leaves room
 * below for level m + 1's data, which occupies planes [0, S_{m+1} + n_{m+1}) of the low x-y
 * quadrant and whose synthesis writes level m's low-pass band at planes [0, n_m). Each level's
 * synthesis is a windowed z pass (column blocks copied first, so in place), then the
 * in-place transform's own y and x passes plane by plane (wavelet_bricks.h).
 *
 * Chunks are decoded depth first from the coarsest level (a chunk's children need it as
 * their coder's context): each chunk once, the cache holding one chain of parents and the
 * finest level's chunks in flight. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/clock.h"
#include "core/clones.h"
#include "wvc2_read.h"
#include "wvc_source.h"

#define ZBLOCK 64 /* columns per z-pass block: 2 n_m rows of them stay in L2 */
#define MAX_TAPS 256

typedef struct piece_plan {
    int s, M, L;
    size_t PX, PY;                       /* the level-s grid's x and y (padded >> s) */
    ptrdiff_t k0[WVOL_WVC_MAX_LEVELS + 1];
    size_t n[WVOL_WVC_MAX_LEVELS + 1];   /* window length */
    size_t S[WVOL_WVC_MAX_LEVELS + 1];   /* first plane of the high z half */
    int full[WVOL_WVC_MAX_LEVELS + 1];   /* the window is the whole period */
    size_t ez[WVOL_WVC_MAX_LEVELS + 1];  /* the level's z extent */
    size_t planes;                       /* of the work array */
} piece_plan;

static ptrdiff_t floor_div2(ptrdiff_t a) { return a >= 0 ? a / 2 : -((-a + 1) / 2); }

static ptrdiff_t pmod(ptrdiff_t a, ptrdiff_t n)
{
    ptrdiff_t r = a % n;
    return r < 0 ? r + n : r;
}

/* The plan of the box [lo, hi) of level s's grid; 0 when it is not a piece this reader
 * serves (see wvol_wvc_piece_samples). */
static int plan_piece(piece_plan *P, const wvol_wvc_file *f, int s, const size_t lo[3], const size_t hi[3])
{
    const wvc2_index *x = wvol__wvc_file_index(f);
    const wvol_wvc_info *I = wvol_wvc_file_info(f);
    const wvol_filter *flt;
    size_t p[3], dims[3];
    if (!x || !lo || !hi || s < 0 || s >= I->levels || wvol_filter_get(&flt, I->filter, NULL) != WVOL_OK ||
        flt->length > MAX_TAPS)
        return 0;
    p[0] = I->px, p[1] = I->py, p[2] = I->pz;
    dims[0] = I->nx, dims[1] = I->ny, dims[2] = I->nz;
    for (int a = 0; a < 3; a++) {
        if (p[a] < 2) return 0; /* every axis transformed */
        dims[a] = (dims[a] + ((size_t)1 << s) - 1) >> s;
    }
    /* x and y: the whole level grid, which must be the padded one (nothing to crop) */
    for (int a = 0; a < 2; a++)
        if (lo[a] != 0 || hi[a] != (p[a] >> s) || dims[a] != (p[a] >> s)) return 0;
    if (lo[2] >= hi[2] || hi[2] > dims[2]) return 0;
    /* a level whose grid starts after the first coarse samples (wvol_level_shift) is read as a
     * region, which rolls them into place */
    if (s > 0 && wvol_level_shift(flt, s) != 0) return 0;
    memset(P, 0, sizeof *P);
    P->s = s;
    P->M = I->levels;
    P->L = flt->length;
    P->PX = p[0] >> s;
    P->PY = p[1] >> s;
    P->k0[s] = (ptrdiff_t)lo[2];
    P->n[s] = hi[2] - lo[2];
    P->ez[s] = p[2] >> s;
    P->full[s] = P->n[s] == P->ez[s];
    for (int m = s + 1; m <= P->M; m++) {
        ptrdiff_t l0 = P->k0[m - 1], h0 = l0 + (ptrdiff_t)P->n[m - 1];
        ptrdiff_t kl = -floor_div2(P->L - 1 - l0), kh = floor_div2(h0 - 1) + 1, e = (ptrdiff_t)(p[2] >> m);
        P->ez[m] = (size_t)e;
        if (P->full[m - 1] || kh - kl >= e) kl = 0, kh = e, P->full[m] = 1;
        P->k0[m] = kl;
        P->n[m] = (size_t)(kh - kl);
    }
    P->S[P->M] = P->n[P->M];
    for (int m = P->M - 1; m > s; m--) {
        size_t below = P->S[m + 1] + P->n[m + 1];
        P->S[m] = P->n[m] > below ? P->n[m] : below;
    }
    P->planes = P->S[s + 1] + P->n[s + 1];
    if (P->planes < P->n[s]) P->planes = P->n[s];
    return 1;
}

size_t wvol_wvc_piece_samples(const wvol_wvc_file *f, int level, const size_t lo[3], const size_t hi[3])
{
    piece_plan P;
    if (!f || !plan_piece(&P, f, level, lo, hi)) return 0;
    return P.PX * P.PY * P.planes;
}

size_t wvol_wvc_piece_budget(const wvol_wvc_file *f, int threads)
{
    if (!f || !wvol__wvc_file_index(f)) return 0;
    return wvol__wvc_file_pin_need(f, threads > 0 ? threads : 1);
}

/* ---- decoding into the layout ------------------------------------------------------ */

typedef struct piece_ctx {
    wvol_wvc_file *f;
    const wvc2_index *x;
    const piece_plan *P;
    float *work;
    double o1[WVOL_WVC_MAX_SECTIONS], d2[WVOL_WVC_MAX_SECTIONS];
    unsigned char *own[WVOL_WVC_MAX_LEVELS + 1];  /* per z tile: meets the level's window */
    unsigned char *need[WVOL_WVC_MAX_LEVELS + 1]; /* ... or a descendant's */
    int threads;
    wvc2_read_errors *E; /* this read's */
} piece_ctx;

/* Dequantises (q NULL: zeros) the part of chunk (m, t) inside level m's window into the
 * layout: the full decoder's arithmetic, so values are bit-equal to it. */
static void scatter(const piece_ctx *C, int m, const size_t t[3], void *const *q, int es)
{
    const wvc2_geom *g = &C->x->g;
    const wvc2_level *G = &g->lv[m];
    const piece_plan *P = C->P;
    size_t off[3], ext[3], plane = P->PX * P->PY;
    double step = C->x->step;
    wvc2_tile_box(g, m, t, off, ext);
    for (int k = 0; k < G->nb; k++) {
        int b = G->bands[k], sec = wvc2_section(g->levels, m, b);
        double o1 = C->o1[sec], d2 = C->d2[sec];
        size_t xo = off[0] + ((b & 1) ? G->e[0] : 0), yo = off[1] + ((b & 2) ? G->e[1] : 0);
        for (size_t z = 0; z < ext[2]; z++) {
            size_t w = (size_t)pmod((ptrdiff_t)(off[2] + z) - P->k0[m], (ptrdiff_t)P->ez[m]);
            if (w >= P->n[m]) continue;
            float *dz = C->work + (w + ((b & 4) ? P->S[m] : 0)) * plane;
            for (size_t y = 0; y < ext[1]; y++) {
                float *d = dz + (yo + y) * P->PX + xo;
                if (!q) {
                    memset(d, 0, ext[0] * sizeof *d);
                    continue;
                }
                (void)wvol__wvc_dequant_any(d, q[k], es, ext[0] * (y + ext[1] * z), ext[0], o1, d2, step);
            }
        }
    }
}

static int tile_meets(const piece_plan *P, int m, size_t tz, size_t T)
{
    size_t e = P->ez[m], z0 = tz * T, z1 = z0 + T < e ? z0 + T : e;
    if (P->full[m]) return 1;
    for (size_t z = z0; z < z1; z++)
        if ((size_t)pmod((ptrdiff_t)z - P->k0[m], (ptrdiff_t)e) < P->n[m]) return 1;
    return 0;
}

/* Chunk (m, t): decoded (pinned while its children are), its window part scattered, then
 * its needed children, in parallel at the finest level decoded. */
static void walk(const piece_ctx *C, int m, const size_t t[3])
{
    const wvc2_geom *g = &C->x->g;
    size_t id = wvc2_chunk_id(g, m, t);
    void *const *q = NULL;
    int es = (int)sizeof(int32_t);
    void *pin = NULL;
    if (C->x->chunks[id].bytes) {
        pin = wvol__wvc_file_pin(C->f, C->E, id, &q, &es);
        if (!pin) return; /* recorded: the caller reports it */
    }
    if (C->own[m][t[2]]) scatter(C, m, t, pin ? q : NULL, es);
    if (m - 1 > C->P->s) {
        const wvc2_level *F = &g->lv[m - 1];
        size_t kids[8][3];
        int nk = 0;
        for (int c = 0; c < 8; c++) {
            size_t u[3];
            int ok = 1;
            for (int a = 0; a < 3; a++) {
                u[a] = 2 * t[a] + (size_t)((c >> a) & 1);
                if (u[a] >= F->nt[a]) ok = 0;
            }
            if (ok && C->need[m - 1][u[2]]) memcpy(kids[nk++], u, sizeof u);
        }
        if (m - 1 == C->P->s + 1 && C->threads > 1 && nk > 1) {
            int i;
#pragma omp parallel for schedule(dynamic, 1) num_threads(C->threads)
            for (i = 0; i < nk; i++) walk(C, m - 1, kids[i]);
        } else {
            for (int i = 0; i < nk; i++) walk(C, m - 1, kids[i]);
        }
    }
    if (pin) wvol__wvc_file_unpin(C->f, pin);
}

/* ---- synthesis ------------------------------------------------------------------------ */

/* The z pass of level m for the columns [x0, x0 + w) of row y (of the cx x cy corner):
 * planes [0, n_m) (low) and [S_m, S_m + n_m) (high) in, level m - 1's window out at planes
 * [0, n_{m-1}); tmp: 2 n_m ZBLOCK floats. */
WVOL__CLONES static void zpass_block(const piece_plan *P, int m, float *work, size_t y, size_t x0, size_t w,
                                     const float *h, const float *g, float *restrict tmp)
{
    const size_t plane = P->PX * P->PY, n = P->n[m];
    float *restrict ta = tmp, *restrict td = tmp + n * ZBLOCK;
    float *base = work + y * P->PX + x0;
    float acc[ZBLOCK];
    const ptrdiff_t L = P->L, e = (ptrdiff_t)P->ez[m];
    for (size_t k = 0; k < n; k++) {
        memcpy(ta + k * ZBLOCK, base + k * plane, w * sizeof *ta);
        memcpy(td + k * ZBLOCK, base + (P->S[m] + k) * plane, w * sizeof *td);
    }
    for (size_t i = 0; i < P->n[m - 1]; i++) {
        ptrdiff_t gi = P->k0[m - 1] + (ptrdiff_t)i, kmin = -floor_div2(L - 1 - gi), kmax = floor_div2(gi);
        for (size_t c = 0; c < w; c++) acc[c] = 0.0f;
        for (ptrdiff_t k = kmin; k <= kmax; k++) {
            ptrdiff_t r = P->full[m] ? pmod(k, e) : k - P->k0[m];
            const float *restrict a = ta + (size_t)r * ZBLOCK, *restrict d = td + (size_t)r * ZBLOCK;
            const float wh = h[gi - 2 * k], wg = g[gi - 2 * k];
            for (size_t c = 0; c < w; c++) acc[c] += wh * a[c] + wg * d[c];
        }
        memcpy(base + i * plane, acc, w * sizeof *acc);
    }
}

static size_t thread_id(void)
{
#ifdef _OPENMP
    return (size_t)omp_get_thread_num();
#else
    return 0;
#endif
}

/* Level m's synthesis: its window's layout in, level m - 1's low-pass window out (planes
 * [0, n_{m-1}) of the 2 e_x x 2 e_y corner). */
static wvol_status synth_level(const piece_plan *P, int m, float *work, const float *h, const float *g,
                               int threads, wvol_error *err)
{
    const size_t plane = P->PX * P->PY, cx = P->PX >> (m - 1 - P->s), cy = P->PY >> (m - 1 - P->s);
    const size_t nbx = (cx + ZBLOCK - 1) / ZBLOCK, xy = wvol__idwt_slice_xy_scratch(cx, cy, P->L);
    const size_t zt = 2 * P->n[m] * ZBLOCK, per = (zt > xy ? zt : xy) + 16;
    float *scratch = malloc(per * (size_t)threads * sizeof *scratch);
    long tasks = (long)(cy * nbx), t;
    long planes = (long)P->n[m - 1];
    WVOL_RETURN_IF(!scratch, err, WVOL_ERR_NOMEM, "wvc piece: out of memory for %zu scratch values",
                   per * (size_t)threads);
#pragma omp parallel for schedule(static) num_threads(threads) if (threads > 1)
    for (t = 0; t < tasks; t++) {
        size_t y = (size_t)t / nbx, x0 = ((size_t)t % nbx) * ZBLOCK, w = cx - x0 < ZBLOCK ? cx - x0 : ZBLOCK;
        zpass_block(P, m, work, y, x0, w, h, g, scratch + thread_id() * per);
    }
#pragma omp parallel for schedule(static) num_threads(threads) if (threads > 1)
    for (t = 0; t < planes; t++)
        wvol__idwt_slice_xy_f32(work + (size_t)t * plane, cx, cy, P->PX, h, g, P->L, scratch + thread_id() * per);
    free(scratch);
    return WVOL_OK;
}

/* ---- the read --------------------------------------------------------------------------- */

static void ctx_free(piece_ctx *C)
{
    for (int m = 0; m <= WVOL_WVC_MAX_LEVELS; m++) {
        free(C->own[m]);
        free(C->need[m]);
    }
}

wvol_status wvol_wvc_read_piece_into(float *work, size_t cap, wvol_wvc_file *f, const size_t lo[3],
                                     const size_t hi[3], int level, int threads, double spacing[3],
                                     double origin[3], wvol_error *err)
{
    piece_plan P;
    piece_ctx C;
    const wvol_filter *flt;
    const wvc2_geom *g;
    float h[MAX_TAPS], gg[MAX_TAPS];
    size_t need, T;
    float dc = 0.0f;
    double back = 0.0;
    wvc2_read_errors E = {0};
    wvol_status st = WVOL_OK;
    WVOL_RETURN_IF(!work || !f || !lo || !hi, err, WVOL_ERR_ARG, "wvc piece: missing argument");
    WVOL_FORWARD(wvol__threads_check(threads, "wvc piece", err));
    WVOL_RETURN_IF(!plan_piece(&P, f, level, lo, hi), err, WVOL_ERR_ARG,
                   "%s: wvc piece: the box must span level %d's grid along x and y (of a version-2 file whose "
                   "axes are all transformed, level below %d); read it with wvol_wvc_read_region_into",
                   wvol__wvc_file_path(f), level, wvol_wvc_file_info(f)->levels);
    WVOL_RETURN_IF(cap < P.PX * P.PY * P.planes, err, WVOL_ERR_ARG,
                   "wvc piece: work array of %zu samples, the piece needs %zu (wvol_wvc_piece_samples)", cap,
                   P.PX * P.PY * P.planes);
    WVOL_FORWARD(wvol_filter_get(&flt, wvol_wvc_file_info(f)->filter, err));
    threads = wvol__threads(threads);
    need = wvol_wvc_piece_budget(f, threads);
    WVOL_RETURN_IF(wvol__wvc_file_budget(f) < need, err, WVOL_ERR_NOMEM,
                   "%s: memory budget of %zu bytes is below the %zu bytes a piece read with %d threads pins at once "
                   "(wvol_wvc_piece_budget)",
                   wvol__wvc_file_path(f), wvol__wvc_file_budget(f), need, threads);
    WVOL_FORWARD(wvol__wvc_file_dc(f, &dc, err));
    for (int i = 0; i < flt->length; i++) {
        h[i] = (float)flt->h[i];
        gg[i] = (float)flt->g[i];
    }
    memset(&C, 0, sizeof C);
    C.f = f;
    C.x = wvol__wvc_file_index(f);
    C.P = &P;
    C.work = work;
    C.threads = threads;
    C.E = &E;
    g = &C.x->g;
    T = (size_t)g->tile[2];
    for (int sct = 0; sct < wvol_wvc_file_info(f)->nsections; sct++) {
        C.o1[sct] = (1.0 + (double)C.x->d1[sct]) * C.x->step;
        C.d2[sct] = C.x->d2[sct];
    }
    for (int m = P.s + 1; m <= P.M; m++) {
        size_t nt = g->lv[m].nt[2];
        C.own[m] = calloc(nt, 1);
        C.need[m] = calloc(nt, 1);
        if (!C.own[m] || !C.need[m]) {
            ctx_free(&C);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc piece: out of memory");
        }
        for (size_t tz = 0; tz < nt; tz++) C.own[m][tz] = (unsigned char)tile_meets(&P, m, tz, T);
    }
    /* a tile is needed for its own window part or as the parent of a needed one */
    for (int m = P.s + 1; m <= P.M; m++)
        for (size_t tz = 0; tz < g->lv[m].nt[2]; tz++) {
            if (C.own[m][tz]) C.need[m][tz] = 1;
            if (m > P.s + 1) {
                size_t c0 = 2 * tz, c1 = 2 * tz + 1, nc = g->lv[m - 1].nt[2];
                if ((c0 < nc && C.need[m - 1][c0]) || (c1 < nc && C.need[m - 1][c1])) C.need[m][tz] = 1;
            }
        }
    {
        const wvc2_level *G = &g->lv[P.M];
        size_t t[3];
        for (t[2] = 0; t[2] < G->nt[2]; t[2]++)
            for (t[1] = 0; t[1] < G->nt[1]; t[1]++)
                for (t[0] = 0; t[0] < G->nt[0]; t[0]++)
                    if (C.need[P.M][t[2]]) walk(&C, P.M, t);
    }
    ctx_free(&C);
    WVOL_FORWARD(wvol__wvc_file_read_error(f, &E, err));
    if (dc != 0.0f) { /* the band's offset out, back into the samples last, as every inverse does */
        const size_t ex = P.PX >> (P.M - P.s), ey = P.PY >> (P.M - P.s), pad[3] = {P.PX, P.PY, 2};
        for (size_t z = 0; z < P.n[P.M]; z++)
            for (size_t y = 0; y < ey; y++) {
                float *row = work + P.PX * (y + P.PY * z);
                for (size_t x = 0; x < ex; x++) row[x] -= dc;
            }
        back = (double)dc / wvol__dc_gain_f32(flt, P.M - P.s, pad);
    }
    for (int m = P.M; m > P.s && st == WVOL_OK; m--) st = synth_level(&P, m, work, h, gg, threads, err);
    if (st != WVOL_OK) return st;
    if (back != 0.0) {
        const size_t nv = P.PX * P.PY * P.n[P.s];
        for (size_t i = 0; i < nv; i++) work[i] = (float)((double)work[i] + back);
    }
    {
        /* wvol_idwt3_level's values: the level-s low-pass times 2^{-s/2} per axis */
        const wvol_wvc_info *I = wvol_wvc_file_info(f);
        double scale = pow(2.0, -1.5 * P.s);
        size_t nv = P.PX * P.PY * P.n[P.s];
        if (P.s > 0)
            for (size_t i = 0; i < nv; i++) work[i] = (float)(work[i] * scale);
        double sp[3], org[3];
        WVOL_FORWARD(wvol_wvc_level_geometry(I, P.s, NULL, sp, org, err));
        for (int a = 0; a < 3; a++) {
            if (spacing) spacing[a] = sp[a];
            if (origin) origin[a] = org[a] + sp[a] * (double)lo[a];
        }
    }
    return WVOL_OK;
}
