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

#include "core/alloc.h"
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

/* A meshed brick until it is stitched; after that only lkeys / lgid stay: the keys of its
 * owned vertices that lie on a lower face (the only ones another brick can ask for: a
 * vertex a brick does not own lies on its upper face, the owner's lower one), sorted,
 * with their global ids. */
typedef struct brick_out {
    wvol_mesh *mesh;
    uint64_t *keys;
    unsigned char *vflags;  /* per local vertex: WVOL__MC_KEY_ONLY (a later brick's), WVOL__MC_FIRST */
    size_t nowned;
    uint64_t *lkeys;        /* owned lower-face vertices' keys, sorted */
    uint32_t *lgid;         /* their rank among the owned vertices, then (stitched) global id */
    size_t nlower;
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
    /* a vertex on the upper layer along a is the next brick's (the edge's lower sample is in
     * the next brick's cells), one on the lower layer may be asked for by the brick before */
    for (a = 0; a < 3; a++) {
        jb.key_only[a] = bidx[a] + 1 < g->nb[a];
        jb.first_shared[a] = bidx[a] > 0;
    }
    jb.vflags = &o->vflags;
    o->status = wvol__mc_run(&o->mesh, &jb, NULL, &o->err);
    if (o->status != WVOL_OK) return;
    for (i = 0; i < o->mesh->nverts; i++) {
        const unsigned char f = o->vflags[i];
        if (f & WVOL__MC_KEY_ONLY) continue;
        if (f & WVOL__MC_FIRST) {
            if (!o->lkeys) {
                o->lkeys = malloc(o->mesh->nverts * sizeof *o->lkeys);
                o->lgid = malloc(o->mesh->nverts * sizeof *o->lgid);
                if (!o->lkeys || !o->lgid) {
                    o->status = wvol_error_set(&o->err, WVOL_ERR_NOMEM, "brick: out of memory");
                    return;
                }
            }
            o->lkeys[o->nlower] = o->keys[i];
            o->lgid[o->nlower++] = (uint32_t)o->nowned; /* < nverts <= UINT32_MAX (wvol__mc_run) */
        }
        o->nowned++;
    }
}

static void brick_out_release(brick_out *o)
{
    wvol_mesh_destroy(o->mesh);
    free(o->keys);
    free(o->vflags);
    o->mesh = NULL;
    o->keys = NULL;
    o->vflags = NULL;
}

/* Each brick's bound: range[2 i], range[2 i + 1] = lo, hi of brick i's samples. The bricks
 * form a tensor grid (a brick's cells along an axis depend on its index along that axis
 * alone), so the bound takes them all at once (wvol__bounds_grid, the same values as brick by
 * brick); brick by brick only when that is out of memory. */
static void brick_ranges(const brick_grid *g, const wvol__brick_bounds *bb, size_t nbricks, double *range)
{
    long *ax = malloc(2 * (g->nb[0] + g->nb[1] + g->nb[2]) * sizeof *ax);
    if (ax) {
        const long *s0[3], *s1[3];
        long *at = ax;
        for (int a = 0; a < 3; a++) {
            long *lo = at, *hi = at + g->nb[a];
            for (size_t t = 0; t < g->nb[a]; t++) {
                size_t bidx[3] = {0, 0, 0}, c0[3], c1[3];
                bidx[a] = t;
                brick_cells(g, bidx, c0, c1);
                lo[t] = (long)c0[a];
                hi[t] = (long)c1[a];
            }
            s0[a] = lo, s1[a] = hi;
            at += 2 * g->nb[a];
        }
        if (wvol__bounds_grid(bb, s0, s1, g->nb, range)) {
            free(ax);
            return;
        }
        free(ax);
    }
    for (size_t i = 0; i < nbricks; i++) {
        size_t bidx[3], c0[3], c1[3];
        long s0[3], s1[3];
        brick_coords(g, i, bidx);
        brick_cells(g, bidx, c0, c1);
        for (int a = 0; a < 3; a++) {
            s0[a] = (long)c0[a];
            s1[a] = (long)c1[a];
        }
        wvol__bounds_box(bb, s0, s1, &range[2 * i], &range[2 * i + 1]);
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

/* ---- stitching, in brick order, as the bricks are meshed ------------------------- */

/* The output mesh grows brick by brick: a brick's owned vertices take the next global ids
 * (so the ids follow brick order, then each brick's own order, whatever the thread count),
 * its triangles are appended with their owned corners mapped at once, and a corner on a
 * vertex owned by a later brick is left pending until every brick is stitched. The bricks'
 * own meshes are freed as they are stitched, so the extraction holds about one output mesh
 * (not the bricks' meshes and the output mesh together: fewer fresh pages to touch). */
typedef struct stitch_corner {
    size_t pos;     /* index into the output's tris */
    uint32_t pend;  /* index into the pending keys */
} stitch_corner;

typedef struct stitcher {
    wvol_mesh *m;           /* nverts / ntris: stitched so far; arrays grown (capacities below) */
    size_t vcap, tcap;
    uint64_t *pend;         /* keys of the vertices owned by later bricks, one per (brick, vertex) */
    size_t npend, pcap;
    stitch_corner *fix;
    size_t nfix, fcap;
    uint32_t *map;          /* per local vertex of the brick being stitched: global id or pending index */
    size_t mapcap;
    wvol_status status;     /* the first failure in brick order (then nothing more is stitched) */
    wvol_error err;
} stitcher;

/* The output arrays are reserved large from the start (OUT_RESERVE bytes of address space,
 * touched only as far as they are filled): above malloc's largest mmap threshold, so they
 * are mappings of their own that grow by remapping, never by copying; in huge pages, so that
 * filling them takes a page fault per 2 MiB rather than per 4 KiB; and taken from the reuse
 * pool, so that an extraction after another fills pages the last one's mesh touched
 * (core/alloc.h says why that matters). The mesh keeps the reservations (unused address
 * space costs nothing resident), and gives them back to the pool when it is destroyed.
 * Where the reservation is refused (strict overcommit), the arrays grow from small. */
#define OUT_RESERVE ((size_t)48 << 20)

/* An output array (element size el) grown to at least n elements. */
static int grow_out(void **p, size_t *cap, size_t n, size_t el)
{
    if (*cap == 0 && n <= OUT_RESERVE / el) {
        void *q = wvol__reuse_get(OUT_RESERVE); /* nothing to keep: the array holds no element */
        if (q) {
            free(*p);
            *p = q;
            *cap = OUT_RESERVE / el;
        }
    }
    return wvol__grow(p, cap, n, el, 4096);
}

/* The vertex arrays (verts, normals) share the capacity vcap. */
static int grow_verts(stitcher *s, size_t n)
{
    size_t c = s->vcap, cn = s->vcap;
    if (n <= s->vcap) return 1;
    if (!grow_out((void **)&s->m->verts, &c, n, 3 * sizeof(float))) return 0;
    if (s->m->normals && !grow_out((void **)&s->m->normals, &cn, n, 3 * sizeof(float))) return 0;
    s->vcap = c < cn || !s->m->normals ? c : cn;
    return 1;
}

static void stitch_brick(stitcher *s, brick_out *o)
{
    wvol_mesh *bm = o->mesh, *m = s->m;
    size_t k, t, r = 0, base = m->nverts, tb = 3 * m->ntris;
    if (s->status != WVOL_OK) return;
    if (o->status != WVOL_OK) {
        s->status = o->status;
        s->err = o->err;
        return;
    }
    if (base + o->nowned > UINT32_MAX) {
        s->status = wvol_error_set(&s->err, WVOL_ERR_DIMS, "iso: more than %u vertices exceed 32-bit indices",
                                   (unsigned)UINT32_MAX);
        return;
    }
    if (!grow_verts(s, base + o->nowned) ||
        !grow_out((void **)&m->tris, &s->tcap, m->ntris + bm->ntris, 3 * sizeof(uint32_t)) ||
        !wvol__grow((void **)&s->map, &s->mapcap, bm->nverts, sizeof *s->map, 4096) ||
        !wvol__grow((void **)&s->pend, &s->pcap, s->npend + bm->nverts - o->nowned, sizeof *s->pend, 4096)) {
        s->status = wvol_error_set(&s->err, WVOL_ERR_NOMEM, "iso: out of memory while stitching bricks");
        return;
    }
    for (k = 0; k < bm->nverts; k++) {
        if (!(o->vflags[k] & WVOL__MC_KEY_ONLY)) {
            size_t gid = base + r++;
            memcpy(m->verts + 3 * gid, bm->verts + 3 * k, 3 * sizeof(float));
            if (m->normals) memcpy(m->normals + 3 * gid, bm->normals + 3 * k, 3 * sizeof(float));
            s->map[k] = (uint32_t)gid;
        } else {
            s->map[k] = (uint32_t)s->npend;
            s->pend[s->npend++] = o->keys[k];
        }
    }
    if (r < bm->nverts) {
        /* corners on pending vertices: at most every corner of the brick */
        if (!wvol__grow((void **)&s->fix, &s->fcap, s->nfix + 3 * bm->ntris, sizeof *s->fix, 4096)) {
            s->status = wvol_error_set(&s->err, WVOL_ERR_NOMEM, "iso: out of memory while stitching bricks");
            return;
        }
        for (t = 0; t < 3 * bm->ntris; t++) {
            uint32_t lv = bm->tris[t];
            m->tris[tb + t] = s->map[lv];
            if (o->vflags[lv] & WVOL__MC_KEY_ONLY) {
                s->fix[s->nfix].pos = tb + t;
                s->fix[s->nfix++].pend = s->map[lv];
            }
        }
    } else {
        for (t = 0; t < 3 * bm->ntris; t++) m->tris[tb + t] = s->map[bm->tris[t]];
    }
    for (k = 0; k < o->nlower; k++) o->lgid[k] += (uint32_t)base;
    m->nverts += o->nowned;
    m->ntris += bm->ntris;
}

/* After every brick: the pending corners get their owners' ids (the owner: the brick
 * holding the edge's lower sample; its lower-face keys); the number found nowhere. */
static size_t stitch_finish(stitcher *s, const brick_grid *g, const brick_out *res, const size_t *slot, int nth)
{
    size_t misses = 0;
    long p;
    (void)nth;
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nth) if (nth > 1 && s->npend > 4096) reduction(+ : misses)
#endif
    for (p = 0; p < (long)s->npend; p++) {
        uint64_t pt[3], key = s->pend[p];
        int axis;
        size_t ob, os;
        long at = -1;
        decode_key(g, key, pt, &axis);
        ob = owner_axis(g, 0, pt[0]) + g->nb[0] * (owner_axis(g, 1, pt[1]) + g->nb[1] * owner_axis(g, 2, pt[2]));
        os = slot[ob];
        if (os != (size_t)-1) at = find_key(res[os].lkeys, res[os].nlower, key);
        /* the pending key becomes its global id (UINT32_MAX: no owner) */
        if (at >= 0) {
            s->pend[p] = res[os].lgid[at];
        } else {
            s->pend[p] = UINT32_MAX;
            misses++;
        }
    }
    for (size_t f = 0; f < s->nfix; f++) s->m->tris[s->fix[f].pos] = (uint32_t)s->pend[s->fix[f].pend];
    return misses;
}

/* The box of samples the run of needed bricks need[q0 .. q1) meshes from (one row: only x
 * differs): the first brick's box stretched to the last's. */
static void run_box(const brick_grid *g, const size_t *need, size_t q0, size_t q1, size_t lo[3], size_t hi[3])
{
    size_t first[3], last[3], blo[3], bhi[3];
    brick_coords(g, need[q0], first);
    brick_coords(g, need[q1 - 1], last);
    brick_box(g, first, lo, hi);
    brick_box(g, last, blo, bhi);
    hi[0] = bhi[0];
}

/* For a store opened on a .wvc file whose bricks the index's bounds decided (nothing decoded):
 * the whole reconstruction into *whole when those bricks' reconstructions would gather more
 * coefficient positions than the whole pyramid has and the file's budget has room for the
 * pyramid and the file's bytes (else *whole stays NULL). A brick's reconstruction takes the
 * coefficients whose support reaches it, an apron around it at every level (wide for long
 * filters and deep levels), while the whole inverse transform takes each once: where the
 * surface crosses most of the index's coarse blocks (a noisy volume) the bricks cost more. The
 * file is then decoded whole, straight into the pyramid, on the extraction's threads (the
 * decoder's and the inverse transform's parallel regions take the calling thread's default,
 * set for the while). The samples are the whole inverse transform's, as when the file is
 * decoded whole, and differ from the bricks' by the float rounding of sums taken in another
 * order. *refine: whether the bricks left are worth the decoded chunks' bounds (below). */
static wvol_status whole_if_cheaper(wvol_volume **whole, int *refine, const brick_grid *g, const wvol_store *sto,
                                    const size_t *need, const size_t *run, size_t nrun, int nth, wvol_error *err)
{
    const size_t *pad = g->cs.pad;
    size_t work = 0, positions;
    uint64_t file_bytes;
    wvol_coeffs *c = NULL;
    wvol_status s;
    *whole = NULL;
    *refine = 1;
    if (pad[0] > SIZE_MAX / pad[1] || pad[0] * pad[1] > SIZE_MAX / pad[2] / sizeof(float) / 2) return WVOL_OK;
    positions = pad[0] * pad[1] * pad[2];
    for (size_t r = 0; r < nrun && work <= positions; r++) {
        size_t lo[3], hi[3];
        run_box(g, need, run[r], run[r + 1], lo, hi);
        work += wvol__idwt3_brick_positions(&g->cs, lo, hi);
    }
    /* the decoded chunks' bounds cost a decode of every chunk, about what rebuilding the
     * pyramid's worth of positions costs: worth it only where the bricks left would gather at
     * least half that many */
    *refine = work >= positions / 2;
    file_bytes = wvol_store_file_info(sto)->file_bytes;
    if (work <= positions || g->cs.levels < 1 || file_bytes > SIZE_MAX - positions * sizeof(float) ||
        !wvol__store_file_room(sto, positions * sizeof(float) + (size_t)file_bytes))
        return WVOL_OK;
#ifdef _OPENMP
    const int saved = omp_get_max_threads();
    omp_set_num_threads(nth);
#else
    (void)nth;
#endif
    s = wvol_store_densify(sto, &c, err); /* a file store's: the file decoded whole, no cache */
    if (s == WVOL_OK && (c->px != pad[0] || c->py != pad[1] || c->pz != pad[2] || c->nx != g->n[0] ||
                         c->ny != g->n[1] || c->nz != g->n[2])) {
        wvol_coeffs_destroy(c); /* not the view's grid: keep to the bricks */
        c = NULL;
    }
    if (s == WVOL_OK && c) s = wvol_idwt3_consume(whole, &c, err);
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
    wvol_coeffs_destroy(c);
    return s;
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
    size_t nbricks, nneed = 0, nrun = 0, i, *need = NULL, *slot = NULL, *run = NULL, nt = 0, misses = 0;
    size_t next = 0;         /* the next brick to stitch */
    unsigned char *ready = NULL;
    wvol_volume *whole = NULL; /* the whole reconstruction, when the bricks would cost more */
    int probe = 0;             /* a file store's bricks decided by its index's bounds so far */
    int refine = 0;            /* the index's bricks leave enough work for the decoded bounds */
    double t_whole = 0;        /* seconds making the whole reconstruction */
    int stitching = 0;       /* a thread is stitching */
    stitcher sti;
    brick_out *res = NULL;
    const double *range = NULL; /* per brick: lo, hi of its samples (NULL: unbounded) */
    double *own_range = NULL;
    wvol_mesh *m = NULL;
    wvol_status s = WVOL_OK;
    double t0 = wvol__now(), t1, t2, gmin = INFINITY, gmax = -INFINITY;
    int nth, a;

    memset(&sti, 0, sizeof sti);
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
    WVOL_FORWARD(wvol__iso_params_check(p, err));
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
    WVOL_FORWARD(wvol__iso_vertex_range_check(g.origin, g.spacing, g.n, err));
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
        /* a file store: first the index's bounds (one maximum per chunk, nothing decoded),
         * which say whether the bricks they leave would cost more than the whole inverse;
         * if not, the decoded chunks' own maxima (below), which decide far more bricks, and the
         * chunks are needed for the meshing */
        probe = wvol_store_is_file(sto);
        WVOL_FORWARD(probe ? wvol__store_blocks_create(&blocks, &bb, sto, nth, err)
                           : wvol__store_blocks_create_exact(&blocks, &bb, sto, nth, &exact, err));
        wvol__store_blocks_source(&g.cs, blocks);
    }
    need = malloc(nbricks * sizeof *need);
    slot = malloc(nbricks * sizeof *slot);
    run = malloc((nbricks + 1) * sizeof *run);
    if (!need || !slot || !run) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nbricks);
        goto done;
    }
    /* bounds per brick: samples [c0, c1] (owned cells plus the shared layer); they depend
     * on the coefficients and the brick size alone, so a store's view keeps them */
    for (;;) {
        double tw;
        if (bb) {
            range = blocks ? wvol__store_blocks_table(blocks, g.B) : NULL;
            if (!range) {
                own_range = malloc(2 * nbricks * sizeof *own_range);
                if (!own_range) {
                    s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nbricks);
                    goto done;
                }
                brick_ranges(&g, bb, nbricks, own_range);
                if (blocks && wvol__store_blocks_keep_table(blocks, g.B, &own_range)) {
                    range = own_range;
                    own_range = NULL; /* the view's now */
                } else {
                    range = own_range;
                }
            }
        }
        nneed = nrun = 0;
        gmin = INFINITY, gmax = -INFINITY;
        for (i = 0; i < nbricks; i++) {
            double lo = range ? range[2 * i] : -INFINITY, hi = range ? range[2 * i + 1] : INFINITY;
            if (lo < gmin) gmin = lo;
            if (hi > gmax) gmax = hi;
            slot[i] = (size_t)-1;
            /* a sample is positive when >= iso: skip when all are surely positive or negative */
            if (!(lo >= iso) && !(hi < iso)) {
                slot[i] = nneed;
                need[nneed++] = i;
            }
        }
        /* runs of consecutive needed bricks along x (need[] is in brick order, x fastest),
         * each reconstructed once as one box: neighbours share their apron, and the synthesis
         * works on longer rows; a run is capped so that the threads' work items stay small */
        for (i = 0; i < nneed; i++)
            if (i == 0 || need[i] != need[i - 1] + 1 || need[i] % g.nb[0] == 0 || i - run[nrun - 1] == RUN_MAX)
                run[nrun++] = i;
        run[nrun] = nneed;
        if (!probe || !nneed) break;
        tw = wvol__now();
        s = whole_if_cheaper(&whole, &refine, &g, sto, need, run, nrun, nth, err);
        t_whole = wvol__now() - tw;
        if (s != WVOL_OK) goto done;
        if (whole || !refine) break;
        /* the index's bounds leave the bricks cheaper than the whole inverse, and enough of
         * them to pay for the decoded chunks' bounds, which skip more */
        probe = 0;
        range = NULL;
        free(own_range);
        own_range = NULL;
        wvol__bounds_free(bb);
        bb = NULL;
        wvol__store_blocks_destroy(blocks);
        blocks = NULL;
        {
            int exact;
            s = wvol__store_blocks_create_exact(&blocks, &bb, sto, nth, &exact, err);
            if (s != WVOL_OK) goto done;
        }
        wvol__store_blocks_source(&g.cs, blocks);
    }
    st->whole_inverse = whole != NULL;
    t1 = wvol__now();
    st->bricks_total = nbricks;
    st->bricks_meshed = nneed;
    st->bricks_skipped = nbricks - nneed;
    st->seconds_bounds = t1 - t0 - t_whole;
    if (whole && nneed == nbricks) {
        /* every brick to mesh: the whole reconstruction's dense marching cubes, the mesh of the
         * file decoded whole exactly, without the bricks' stitching */
        wvol_iso_stats ds;
        s = wvol_iso_extract(&m, whole, iso, p, &ds, err);
        if (s != WVOL_OK) goto done;
        memcpy(st->seconds, ds.seconds, sizeof st->seconds);
        st->seconds[2] += t_whole;
        st->seconds[3] = wvol__now() - t0;
        st->seconds_reconstruct = t_whole + ds.seconds[3];
        st->cells_active = ds.cells_active;
        st->empty = ds.empty;
        st->data_min = ds.data_min, st->data_max = ds.data_max;
        memcpy(st->message, ds.message, sizeof st->message);
        *out = m;
        m = NULL;
        goto done;
    }
    res = calloc(nneed + 1, sizeof *res);
    ready = calloc(nneed + 1, 1);
    if (!res || !ready) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nneed);
        goto done;
    }
    s = wvol_mesh_create(&sti.m, 0, 0, p->normals != WVOL_ISO_NORMALS_NONE, err);
    if (s != WVOL_OK) goto done;
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
            size_t q0 = run[r], q1 = run[r + 1], lo[3], hi[3], q, cnt;
            wvol_status rs;
            int mine = 0;
            if (whole) {
                /* the run's bricks read the whole reconstruction as their box */
                for (a = 0; a < 3; a++) lo[a] = 0, hi[a] = g.n[a];
                rs = WVOL_OK;
            } else {
                run_box(&g, need, q0, q1, lo, hi);
                cnt = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
                if (cnt > vcap) {
                    free(v);
                    v = malloc(cnt * sizeof *v);
                    vcap = v ? cnt : 0;
                }
                rs = v ? wvol__idwt3_brick_src(v, &g.cs, lo, hi, &scr, &res[q0].err)
                       : wvol_error_set(&res[q0].err, WVOL_ERR_NOMEM, "brick: out of memory");
            }
            if (rs != WVOL_OK) {
                res[q0].status = rs; /* stitched first of its run: the run's failure */
            } else {
                for (q = q0; q < q1; q++) {
                    size_t bidx[3];
                    brick_coords(&g, need[q], bidx);
                    mesh_brick(&res[q], &g, bidx, whole ? whole->data : v, lo, hi, iso,
                               p->normals == WVOL_ISO_NORMALS_NONE ? WVOL_ISO_NORMALS_NONE
                                                                   : WVOL_ISO_NORMALS_GRADIENT);
                }
            }
            /* the bricks stitched in order: whichever thread finds the next one ready
             * stitches from there while the others go on meshing */
#ifdef _OPENMP
#pragma omp critical(wvol_bricks_stitch)
#endif
            {
                for (q = q0; q < q1; q++) ready[q] = 1;
                if (!stitching) stitching = mine = 1;
            }
            while (mine) {
                int go;
#ifdef _OPENMP
#pragma omp critical(wvol_bricks_stitch)
#endif
                {
                    go = next < nneed && ready[next];
                    if (!go) stitching = 0;
                }
                if (!go) break;
                stitch_brick(&sti, &res[next]);
                brick_out_release(&res[next]);
                next++;
            }
        }
        free(v);
        wvol__brick_scratch_free(&scr);
    }
    t2 = wvol__now();
    st->seconds_reconstruct = t2 - t1 + t_whole;
    if (sti.status != WVOL_OK) {
        if (err) *err = sti.err;
        s = sti.status;
        goto done;
    }
    misses = stitch_finish(&sti, &g, res, slot, nth);
    if (misses) {
        s = wvol_error_set(err, WVOL_ERR_INTERNAL,
                           "iso: %zu brick-boundary vertices have no owner (inconsistent brick reconstructions)",
                           misses);
        goto done;
    }
    m = sti.m;
    sti.m = NULL;
    nt = m->ntris;
    st->seconds[2] = t2 - t1 + t_whole;
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
            brick_out_release(&res[i]);
            free(res[i].lkeys);
            free(res[i].lgid);
        }
    free(res);
    free(ready);
    wvol_mesh_destroy(sti.m);
    free(sti.pend);
    free(sti.fix);
    free(sti.map);
    wvol_mesh_destroy(m);
    free(need);
    free(slot);
    free(run);
    free(own_range);
    wvol_volume_destroy(whole);
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
