/* SPDX-License-Identifier: MIT
 * Marching cubes from wavelet coefficients, brick by brick: from dense coefficients
 * (wvol_iso_extract_coeffs) or from a store (wvol_iso_extract_store, through the store's
 * block-sparse view, store/store_blocks.h, as the bricked renderer reads it). The grid's
 * cells are cut into bricks of B^3 cells. For each brick a rigorous bound of the
 * reconstructed samples (its (B+1)^3 samples: owned cells plus the shared layer)
 * is computed from the coefficients alone; a brick whose bound does not straddle
 * the iso-value cannot hold a vertex and is skipped without reconstruction. The
 * others are reconstructed by the local inverse transform (wvol__idwt3_brick_src, plus a
 * one-sample halo for central-difference normals identical to the dense path), meshed by
 * the flying-edges kernel, and stitched: every vertex carries its global edge key,
 * the brick that owns an edge's lower sample writes its vertex, and the other
 * bricks' triangles find it by binary search among the owner's sorted keys, so
 * the stitched mesh has no duplicates and no cracks. Both sources give the same samples
 * bit for bit (the synthesis sums from +0, so a band read as absent and a band of zeros
 * add alike), hence the same mesh.
 *
 * The bound is wavelet/bounds.c (shared with the bricked renderer).
 * Based on: DESIGN.md section 9; Lorensen & Cline 1987. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/clock.h"
#include "iso/iso_internal.h"
#include "store/store_blocks.h"
#include "wvol/wavelet.h"
#include "wavelet/wavelet_bricks.h"

/* ---- bounds (wavelet/bounds.c) ------------------------------------------------------- */

static wvol_status bounds_from_coeffs(wvol__brick_bounds **out, const wvol_coeffs *c, wvol_error *err)
{
    wvol__coef_source src;
    wvol__coef_source_of_coeffs(&src, c);
    WVOL_FORWARD(wvol__bounds_create_src(out, &src, NULL, err));
    wvol__bounds_fill_coeffs(*out, c);
    wvol__bounds_finish(*out);
    return WVOL_OK;
}

/* Exposed for the tests: bound of the samples of box [s0, s1] (inclusive). */
wvol_status wvol__iso_box_bound(const wvol_coeffs *c, const long s0[3], const long s1[3], double *vmin,
                                double *vmax, wvol_error *err)
{
    wvol__brick_bounds *b;
    WVOL_FORWARD(bounds_from_coeffs(&b, c, err));
    wvol__bounds_box(b, s0, s1, vmin, vmax);
    wvol__bounds_free(b);
    return WVOL_OK;
}

/* The most bricks reconstructed as one box (a run along x). */
#define RUN_MAX 8

/* ---- per-brick meshing --------------------------------------------------------- */

typedef struct brick_out {
    wvol_mesh *mesh;
    uint64_t *keys;
    unsigned char *owned;   /* per local vertex */
    size_t nowned;
    uint64_t *owned_keys;   /* sorted */
    size_t base;            /* global id of the first owned vertex */
    int status;
    wvol_error err;
} brick_out;

typedef struct brick_grid {
    size_t n[3], nb[3];
    int B;
    wvol__coef_source cs;           /* what the bricks are reconstructed from */
    double origin[3], spacing[3];
    double inv_n[2], inv_b;         /* 1 / n[0], 1 / n[1], 1 / B: quotients without a division */
} brick_grid;

/* a / d for a < 2^52, from a's product with inv = 1 / d (off by at most one, corrected): the
 * edge keys of every vertex are decoded, and a hardware division per axis dominated that */
static inline uint64_t quot(uint64_t a, uint64_t d, double inv)
{
    uint64_t q = (uint64_t)((double)a * inv);
    if (q * d > a) q--;
    else if ((q + 1) * d <= a) q++;
    return q;
}

static size_t owner_axis(const brick_grid *g, int a, uint64_t p)
{
    size_t b = (size_t)quot(p, (uint64_t)g->B, g->inv_b);
    return b < g->nb[a] ? b : g->nb[a] - 1;
}

static void decode_key(const brick_grid *g, uint64_t key, uint64_t p[3], int *axis)
{
    uint64_t q = quot(key, g->n[0], g->inv_n[0]), r;
    p[0] = key - q * g->n[0];
    r = q / 3;
    *axis = (int)(q - 3 * r);
    p[2] = quot(r, g->n[1], g->inv_n[1]);
    p[1] = r - p[2] * g->n[1];
}

/* The grid coordinates of brick number i (x fastest). */
static void brick_coords(const brick_grid *g, size_t i, size_t bidx[3])
{
    bidx[0] = i % g->nb[0];
    bidx[1] = (i / g->nb[0]) % g->nb[1];
    bidx[2] = i / (g->nb[0] * g->nb[1]);
}

/* The cells [c0, c1) of brick bidx along each axis (c1: its last sample, shared with the next). */
static void brick_cells(const brick_grid *g, const size_t bidx[3], size_t c0[3], size_t c1[3])
{
    for (int a = 0; a < 3; a++) {
        c0[a] = bidx[a] * (size_t)g->B;
        c1[a] = c0[a] + (size_t)g->B < g->n[a] - 1 ? c0[a] + (size_t)g->B : g->n[a] - 1;
    }
}

/* The samples a brick's mesh reads: its cells' samples and a one-sample halo for the
 * central-difference normals, [lo, hi) per axis (clipped to the grid). */
static void brick_box(const brick_grid *g, const size_t bidx[3], size_t lo[3], size_t hi[3])
{
    size_t c0[3], c1[3];
    brick_cells(g, bidx, c0, c1);
    for (int a = 0; a < 3; a++) {
        lo[a] = c0[a] > 0 ? c0[a] - 1 : 0;
        hi[a] = c1[a] + 2 <= g->n[a] ? c1[a] + 2 : g->n[a];
    }
}

/* Meshes brick bidx from v, the reconstructed samples of the box [lo, hi) that holds the
 * brick's box (brick_box): a run of bricks along x shares one reconstruction. */
static void mesh_brick(brick_out *o, const brick_grid *g, const size_t bidx[3], const float *v, const size_t lo[3],
                       const size_t hi[3], double iso, wvol_iso_normals normals)
{
    size_t c0[3], c1[3];
    wvol__mc_job jb;
    size_t i;
    int a;
    wvol_error_clear(&o->err);
    brick_cells(g, bidx, c0, c1);
    memset(&jb, 0, sizeof jb);
    jb.data = v;
    for (a = 0; a < 3; a++) {
        jb.adims[a] = hi[a] - lo[a];
        jb.lo[a] = c0[a] - lo[a];
        jb.n[a] = c1[a] - c0[a] + 1;
        jb.gofs[a] = (long long)lo[a];
        jb.gdims[a] = g->n[a];
        jb.origin[a] = g->origin[a];
        jb.spacing[a] = g->spacing[a];
    }
    jb.iso = iso;
    jb.threads = 1;
    jb.normals = normals;
    jb.keys = &o->keys;
    o->status = wvol__mc_run(&o->mesh, &jb, NULL, &o->err);
    if (o->status != WVOL_OK) return;
    o->owned = malloc(o->mesh->nverts + 1);
    o->owned_keys = malloc((o->mesh->nverts + 1) * sizeof *o->owned_keys);
    if (!o->owned || !o->owned_keys) {
        o->status = wvol_error_set(&o->err, WVOL_ERR_NOMEM, "brick: out of memory");
        return;
    }
    for (i = 0; i < o->mesh->nverts; i++) {
        uint64_t p[3];
        int axis, own = 1;
        decode_key(g, o->keys[i], p, &axis);
        /* the edge's lower sample lies in [c0, c1]: another brick owns it only on this
         * brick's upper face, where the next brick starts */
        for (a = 0; a < 3; a++)
            if (p[a] == c1[a] && bidx[a] + 1 < g->nb[a]) own = 0;
        o->owned[i] = (unsigned char)own;
        if (own) o->owned_keys[o->nowned++] = o->keys[i];
    }
}

/* The index of key in the sorted keys[0 .. n), or -1. Branch-free halving (a conditional
 * move per step): the keys looked up land anywhere in the owner's array, and the branches
 * of a plain binary search mispredicted at every step. */
static long find_key(const uint64_t *keys, size_t n, uint64_t key)
{
    const uint64_t *b = keys;
    if (n == 0) return -1;
    while (n > 1) {
        size_t half = n / 2;
        b = b[half] <= key ? b + half : b; /* key, if there, stays in [b, b + n - half) */
        n -= half;
    }
    return *b == key ? (long)(b - keys) : -1;
}

/* The mesh of the reconstruction of coefficients c, or of store sto (the other NULL). */
static wvol_status extract_bricks(wvol_mesh **out, const wvol_coeffs *c, const wvol_store *sto, double iso,
                                  const wvol_iso_params *p, wvol_iso_stats *st, wvol_error *err)
{
    wvol_iso_params def;
    wvol_iso_stats local;
    wvol__brick_bounds *bb = NULL;  /* NULL (a store without the bound): every brick meshed */
    wvol__store_blocks *blocks = NULL;
    brick_grid g;
    size_t nbricks, nneed = 0, nrun = 0, i, *need = NULL, *slot = NULL, *run = NULL, nv = 0, nt = 0, misses = 0;
    size_t nomem = 0;
    brick_out *res = NULL;
    wvol_mesh *m = NULL;
    wvol_status s = WVOL_OK;
    double t0 = wvol__now(), t1, t2, gmin = INFINITY, gmax = -INFINITY;
    int nth, a;

    if (!p) {
        wvol_iso_params_default(&def);
        p = &def;
    }
    if (!st) st = &local;
    memset(st, 0, sizeof *st);
    WVOL_RETURN_IF(!isfinite(iso) || !isfinite((double)(float)iso), err, WVOL_ERR_ARG,
                   "iso-value %g is not a finite float", iso);
    WVOL_RETURN_IF(p->brick < 2 || p->brick > 4096, err, WVOL_ERR_ARG, "iso: brick size %d outside 2..4096",
                   p->brick);
    WVOL_RETURN_IF(p->normals == WVOL_ISO_NORMALS_ANALYTIC && !p->gradient, err, WVOL_ERR_ARG,
                   "iso: analytic normals requested without a gradient function");
    if (c) {
        g.n[0] = c->nx, g.n[1] = c->ny, g.n[2] = c->nz;
        for (a = 0; a < 3; a++) g.origin[a] = c->origin[a], g.spacing[a] = c->spacing[a];
    } else {
        wvol_store_info info;
        wvol_store_get_info(sto, &info);
        g.n[0] = info.nx, g.n[1] = info.ny, g.n[2] = info.nz;
        for (a = 0; a < 3; a++) g.origin[a] = info.origin[a], g.spacing[a] = info.spacing[a];
    }
    g.B = p->brick;
    if (g.n[0] < 2 || g.n[1] < 2 || g.n[2] < 2) {
        WVOL_FORWARD(wvol_mesh_create(out, 0, 0, 0, err));
        st->empty = 1;
        snprintf(st->message, sizeof st->message,
                 "the volume has fewer than 2 samples along an axis (no cells): empty mesh");
        return WVOL_OK;
    }
    for (a = 0; a < 3; a++) g.nb[a] = (g.n[a] - 1 + (size_t)g.B - 1) / (size_t)g.B;
    g.inv_n[0] = 1.0 / (double)g.n[0];
    g.inv_n[1] = 1.0 / (double)g.n[1];
    g.inv_b = 1.0 / (double)g.B;
    nbricks = g.nb[0] * g.nb[1] * g.nb[2];
#ifdef _OPENMP
    nth = p->threads > 0 ? p->threads : omp_get_max_threads();
#else
    nth = 1;
#endif
    if (c) {
        WVOL_FORWARD(wvol__coeffs_check(c, err));
        WVOL_FORWARD(bounds_from_coeffs(&bb, c, err));
        wvol__coef_source_of_coeffs(&g.cs, c);
    } else {
        int exact;
        /* a file's index bounds a tile of all bands by one maximum: the decoded chunks' own
         * maxima decide far more bricks, and the chunks are needed for the meshing */
        WVOL_FORWARD(wvol__store_blocks_create_exact(&blocks, &bb, sto, nth, &exact, err));
        wvol__store_blocks_source(&g.cs, blocks);
    }
    need = malloc(nbricks * sizeof *need);
    slot = malloc(nbricks * sizeof *slot);
    run = malloc((nbricks + 1) * sizeof *run);
    if (!need || !slot || !run) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nbricks);
        goto done;
    }
    /* bounds per brick: samples [c0, c1] (owned cells plus the shared layer) */
    for (i = 0; i < nbricks; i++) {
        size_t bidx[3], c0[3], c1[3];
        long s0[3], s1[3];
        double lo, hi;
        brick_coords(&g, i, bidx);
        brick_cells(&g, bidx, c0, c1);
        for (a = 0; a < 3; a++) {
            s0[a] = (long)c0[a];
            s1[a] = (long)c1[a];
        }
        if (bb) {
            wvol__bounds_box(bb, s0, s1, &lo, &hi);
        } else {
            lo = -INFINITY;
            hi = INFINITY;
        }
        if (lo < gmin) gmin = lo;
        if (hi > gmax) gmax = hi;
        slot[i] = (size_t)-1;
        /* a sample is positive when >= iso: skip when all are surely positive or negative */
        if (!(lo >= iso) && !(hi < iso)) {
            slot[i] = nneed;
            need[nneed++] = i;
        }
    }
    t1 = wvol__now();
    st->bricks_total = nbricks;
    st->bricks_meshed = nneed;
    st->bricks_skipped = nbricks - nneed;
    st->seconds_bounds = t1 - t0;
    res = calloc(nneed + 1, sizeof *res);
    if (!res) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nneed);
        goto done;
    }
    /* runs of consecutive needed bricks along x (need[] is in brick order, x fastest), each
     * reconstructed once as one box: neighbours share their apron, and the synthesis works
     * on longer rows; a run is capped so that the threads' work items stay small */
    for (i = 0; i < nneed; i++)
        if (i == 0 || need[i] != need[i - 1] + 1 || need[i] % g.nb[0] == 0 || i - run[nrun - 1] == RUN_MAX)
            run[nrun++] = i;
    run[nrun] = nneed;
#ifdef _OPENMP
#pragma omp parallel num_threads(nth) if (nth > 1)
#endif
    {
        wvol__brick_scratch scr; /* the thread's, reused from run to run */
        float *v = NULL;
        size_t vcap = 0;
        long r;
        memset(&scr, 0, sizeof scr);
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
        for (r = 0; r < (long)nrun; r++) {
            size_t q0 = run[r], q1 = run[r + 1], lo[3], hi[3], blo[3], bhi[3], q, cnt;
            size_t first[3], last[3];
            wvol_status rs;
            brick_coords(&g, need[q0], first);
            brick_coords(&g, need[q1 - 1], last); /* the same row: only x differs */
            brick_box(&g, first, lo, hi);
            brick_box(&g, last, blo, bhi);
            hi[0] = bhi[0];
            cnt = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
            if (cnt > vcap) {
                free(v);
                v = malloc(cnt * sizeof *v);
                vcap = v ? cnt : 0;
            }
            rs = v ? wvol__idwt3_brick_src(v, &g.cs, lo, hi, &scr, &res[q0].err)
                   : wvol_error_set(&res[q0].err, WVOL_ERR_NOMEM, "brick: out of memory");
            if (rs != WVOL_OK) {
                res[q0].status = rs;
                continue;
            }
            for (q = q0; q < q1; q++) {
                size_t bidx[3];
                brick_coords(&g, need[q], bidx);
                mesh_brick(&res[q], &g, bidx, v, lo, hi, iso,
                           p->normals == WVOL_ISO_NORMALS_NONE ? WVOL_ISO_NORMALS_NONE : WVOL_ISO_NORMALS_GRADIENT);
            }
        }
        free(v);
        wvol__brick_scratch_free(&scr);
    }
    t2 = wvol__now();
    st->seconds_reconstruct = t2 - t1;
    for (i = 0; i < nneed; i++)
        if (res[i].status != WVOL_OK) {
            if (err) *err = res[i].err;
            s = res[i].status;
            goto done;
        }
    /* stitch: owned vertices get global ids in brick order */
    for (i = 0; i < nneed; i++) {
        res[i].base = nv;
        nv += res[i].nowned;
        nt += res[i].mesh->ntris;
    }
    if (nv > UINT32_MAX) {
        s = wvol_error_set(err, WVOL_ERR_DIMS, "iso: %zu vertices exceed 32-bit indices", nv);
        goto done;
    }
    s = wvol_mesh_create(&m, nv, nt, p->normals != WVOL_ISO_NORMALS_NONE, err);
    if (s != WVOL_OK) goto done;
    {
        long q;
        size_t tri_base = 0;
        size_t *tb = malloc((nneed + 1) * sizeof *tb);
        if (!tb) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory");
            goto done;
        }
        for (i = 0; i < nneed; i++) {
            tb[i] = tri_base;
            tri_base += res[i].mesh->ntris;
        }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 4) num_threads(nth) if (nth > 1) reduction(+ : misses, nomem)
#endif
        for (q = 0; q < (long)nneed; q++) {
            brick_out *o = &res[q];
            wvol_mesh *bm = o->mesh;
            uint32_t *map = malloc((bm->nverts + 1) * sizeof *map);
            size_t k, r = 0, t;
            if (!map) {
                nomem++;
                continue;
            }
            for (k = 0; k < bm->nverts; k++) {
                if (o->owned[k]) {
                    size_t gid = o->base + r++;
                    memcpy(m->verts + 3 * gid, bm->verts + 3 * k, 3 * sizeof(float));
                    if (m->normals) memcpy(m->normals + 3 * gid, bm->normals + 3 * k, 3 * sizeof(float));
                    map[k] = (uint32_t)gid;
                } else {
                    uint64_t pt[3];
                    int axis;
                    size_t ob, os;
                    long at = -1;
                    decode_key(&g, o->keys[k], pt, &axis);
                    ob = owner_axis(&g, 0, pt[0]) +
                         g.nb[0] * (owner_axis(&g, 1, pt[1]) + g.nb[1] * owner_axis(&g, 2, pt[2]));
                    os = slot[ob];
                    if (os != (size_t)-1) at = find_key(res[os].owned_keys, res[os].nowned, o->keys[k]);
                    if (at >= 0) {
                        map[k] = (uint32_t)(res[os].base + (size_t)at);
                    } else {
                        map[k] = UINT32_MAX;
                        misses++;
                    }
                }
            }
            for (t = 0; t < 3 * bm->ntris; t++) m->tris[3 * tb[q] + t] = map[bm->tris[t]];
            free(map);
        }
        free(tb);
    }
    if (misses) {
        s = wvol_error_set(err, WVOL_ERR_INTERNAL,
                           "iso: %zu brick-boundary vertices have no owner (inconsistent brick reconstructions)",
                           misses);
        goto done;
    }
    if (nomem) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory while stitching bricks");
        goto done;
    }
    st->seconds[2] = t2 - t1;
    st->seconds[3] = wvol__now() - t0;
    if (nt == 0) {
        st->empty = 1;
        st->data_min = gmin;
        st->data_max = gmax;
        if (iso <= gmin || iso > gmax)
            snprintf(st->message, sizeof st->message,
                     "iso-value %.9g is outside the data range (bounded by [%.9g, %.9g] from the coefficients): "
                     "empty mesh",
                     iso, gmin, gmax);
        else if (nneed == 0)
            snprintf(st->message, sizeof st->message,
                     "iso-value %.9g is outside every brick's bounds: empty mesh", iso);
        else
            snprintf(st->message, sizeof st->message,
                     "iso-value %.9g: the reconstruction crosses it nowhere (%zu bricks checked): empty mesh",
                     iso, nneed);
    }
    *out = m;
    m = NULL;
done:
    if (res)
        for (i = 0; i < nneed; i++) {
            wvol_mesh_destroy(res[i].mesh);
            free(res[i].keys);
            free(res[i].owned);
            free(res[i].owned_keys);
        }
    free(res);
    wvol_mesh_destroy(m);
    free(need);
    free(slot);
    free(run);
    wvol__bounds_free(bb);
    wvol__store_blocks_destroy(blocks);
    return s;
}

wvol_status wvol_iso_extract_coeffs(wvol_mesh **out, const wvol_coeffs *c, double iso, const wvol_iso_params *p,
                                    wvol_iso_stats *st, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "iso: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!c || !c->data || !c->filter, err, WVOL_ERR_ARG, "iso: coefficients are NULL");
    return extract_bricks(out, c, NULL, iso, p, st, err);
}

wvol_status wvol_iso_extract_store(wvol_mesh **out, const wvol_store *s, double iso, const wvol_iso_params *p,
                                   wvol_iso_stats *st, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "iso: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "iso: store is NULL");
    return extract_bricks(out, NULL, s, iso, p, st, err);
}
