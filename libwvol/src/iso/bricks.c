/* SPDX-License-Identifier: MIT */
/* Marching cubes from wavelet coefficients, brick by brick. The grid's cells are
 * cut into bricks of B^3 cells. For each brick a rigorous bound of the
 * reconstructed samples (its (B+1)^3 samples: owned cells plus the shared layer)
 * is computed from the coefficients alone; a brick whose bound does not straddle
 * the iso-value cannot hold a vertex and is skipped without reconstruction. The
 * others are reconstructed with wvol_idwt3_brick (plus a one-sample halo for
 * central-difference normals identical to the dense path), meshed by the
 * flying-edges kernel, and stitched: every vertex carries its global edge key,
 * the brick that owns an edge's lower sample writes its vertex, and the other
 * bricks' triangles find it by binary search among the owner's sorted keys, so
 * the stitched mesh has no duplicates and no cracks.
 *
 * The bound. A sample is v(n) = sum over coefficients c R(n - 2^m k), with R the
 * discrete synthesis response of the coefficient's level and band: a product of
 * 1D responses phi_m (low-pass) and psi_m (high-pass) per axis. Per axis
 *   Leb(r) = max over residues rho of sum_t |r[rho + 2^m t]|
 * bounds sum_k |R(n - 2^m k)| at every n. So on a brick
 *   |detail part| <= sum over (m, band) of max|c| (over coefficients reaching the
 *                    brick) * prod_axes Leb,
 *   low-pass part  = a0 S(n) + sum (a_k - a0) R(...), a0 = mid-range of the reaching
 *                    low-pass coefficients, S(n) = sum_t Phi(n - 2^M t) in [Smin, Smax],
 *                    |second term| <= half-range * prod Leb.
 * max|c| per brick comes from per-(level, band) block maxima, one pass over the
 * coefficients.
 * Based on: DESIGN.md section 9; Lorensen & Cline 1987. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "iso/iso_internal.h"
#include "wvol/wavelet.h"

static double now_s(void)
{
#ifdef _OPENMP
    return omp_get_wtime();
#else
    return 0.0;
#endif
}

/* ---- 1D responses ----------------------------------------------------------------- */

/* A response split into a core window [lo, hi] and tails: the core carries all but
 * a 1e-4 share of sum |r|, so long filters (Battle-Lemarie's truncated taps, deep
 * levels) do not make every coefficient "reach" every brick; the tails are
 * bounded with the band's global maximum instead. */
typedef struct resp1 {
    double leb;        /* max_rho sum_t |r[rho + 2^m t]| over the core */
    double tail;       /* sum |r| outside the core */
    double smin, smax; /* min/max_rho sum_t r[rho + 2^m t] (whole response) */
    long lo, hi;       /* core window, offsets in [0, len) */
} resp1;

static void split_core(resp1 *o, const double *r, long nl, long P)
{
    double total = 0.0, cut, out = 0.0;
    long n, rho, lo = 0, hi = nl - 1;
    for (n = 0; n < nl; n++) total += fabs(r[n]);
    cut = 1e-4 * total;
    /* peel the smaller end while the peeled mass stays under the cut */
    while (lo < hi) {
        double a = fabs(r[lo]), b = fabs(r[hi]);
        if (a <= b && out + a <= cut) out += a, lo++;
        else if (b < a && out + b <= cut) out += b, hi--;
        else if (out + a <= cut) out += a, lo++;
        else break;
    }
    o->lo = lo;
    o->hi = hi;
    o->tail = 0.0;
    for (n = 0; n < nl; n++)
        if (n < lo || n > hi) o->tail += fabs(r[n]);
    o->leb = 0.0;
    o->smin = INFINITY;
    o->smax = -INFINITY;
    for (rho = 0; rho < P; rho++) {
        double sa = 0.0, sum = 0.0;
        for (n = rho; n < nl; n += P) {
            if (n >= lo && n <= hi) sa += fabs(r[n]);
            sum += r[n];
        }
        if (sa > o->leb) o->leb = sa;
        if (sum < o->smin) o->smin = sum;
        if (sum > o->smax) o->smax = sum;
    }
}

/* phi_m and psi_m responses for m = 1..M into lp[m], hp[m]. */
static wvol_status responses(resp1 *lp, resp1 *hp, const wvol_filter *f, int M, wvol_error *err)
{
    long L = f->length, len = 1, m;
    double *phi = malloc(sizeof(double));
    if (!phi) return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
    phi[0] = 1.0;
    for (m = 1; m <= M; m++) {
        long step = 1L << (m - 1), nl = len + step * (L - 1), n, t;
        double *nphi = calloc((size_t)nl, sizeof(double)), *npsi = calloc((size_t)nl, sizeof(double));
        if (!nphi || !npsi) {
            free(nphi);
            free(npsi);
            free(phi);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
        }
        for (t = 0; t < L; t++)
            for (n = 0; n < len; n++) {
                nphi[n + step * t] += f->h[t] * phi[n];
                npsi[n + step * t] += f->g[t] * phi[n];
            }
        split_core(&lp[m], nphi, nl, 1L << m);
        split_core(&hp[m], npsi, nl, 1L << m);
        free(phi);
        free(npsi);
        phi = nphi;
        len = nl;
    }
    free(phi);
    return WVOL_OK;
}

/* ---- block maxima of the detail coefficients ---------------------------------------- */

typedef struct band_blocks {
    size_t e[3];       /* band extent (coefficient positions) */
    size_t bs[3];      /* block size (a power of two) */
    int bshift[3];     /* log2 bs */
    size_t nb[3];      /* blocks per axis */
    float *absmax;     /* nb0 nb1 nb2; detail bands only (the low-pass cube is scanned) */
    float gmax;        /* max |c| over the whole band */
    double leb;        /* prod over axes of the core sums */
    double tailw;      /* prod (leb + tail) - prod leb: weight of everything off the cores */
    double smin, smax; /* low-pass: prod over axes of [smin, smax] */
    long lo[3], hi[3]; /* core windows */
    int m, band;
} band_blocks;

struct wvol__brick_bounds {
    const wvol_coeffs *c;
    int M;
    int nbands;
    band_blocks bb[7 * 32 + 1];
};
typedef struct wvol__brick_bounds brick_bounds;

static void bounds_free(brick_bounds *b)
{
    int i;
    if (!b) return;
    for (i = 0; i < b->nbands; i++) free(b->bb[i].absmax);
    free(b);
}

static wvol_status bounds_create(brick_bounds **out, const wvol_coeffs *c, wvol_error *err)
{
    brick_bounds *b;
    resp1 lp[33], hp[33];
    size_t pad[3] = {c->px, c->py, c->pz};
    int m, l, a;
    *out = NULL;
    WVOL_RETURN_IF(c->levels < 1 || c->levels > 32, err, WVOL_ERR_ARG, "brick bounds: %d levels", c->levels);
    for (a = 0; a < 3; a++)
        WVOL_RETURN_IF(pad[a] < 2, err, WVOL_ERR_DIMS, "brick bounds: axis %c is not transformed", "xyz"[a]);
    WVOL_FORWARD(responses(lp, hp, c->filter, c->levels, err));
    b = calloc(1, sizeof *b);
    if (!b) return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
    b->c = c;
    b->M = c->levels;
    for (m = 1; m <= b->M; m++)
        for (l = (m == b->M ? 0 : 1); l < 8; l++) {
            band_blocks *q = &b->bb[b->nbands++];
            double full = 1.0;
            size_t nblk;
            q->m = m;
            q->band = l;
            q->leb = 1.0;
            q->smin = q->smax = 1.0;
            for (a = 0; a < 3; a++) {
                const resp1 *r = ((l >> a) & 1) ? &hp[m] : &lp[m];
                q->e[a] = pad[a] >> m;
                /* blocks of 4, 2, 1 positions at levels 1, 2, >= 3: about 8 samples wide */
                q->bshift[a] = m >= 3 ? 0 : 3 - m;
                q->bs[a] = (size_t)1 << q->bshift[a];
                q->nb[a] = (q->e[a] + q->bs[a] - 1) / q->bs[a];
                q->leb *= r->leb;
                full *= r->leb + r->tail;
                q->smin *= r->smin;
                q->smax *= r->smax;
                q->lo[a] = r->lo;
                q->hi[a] = r->hi;
            }
            q->tailw = full - q->leb;
            if (l == 0) continue;
            nblk = q->nb[0] * q->nb[1] * q->nb[2];
            q->absmax = calloc(nblk, sizeof(float));
            if (!q->absmax) {
                bounds_free(b);
                return wvol_error_set(err, WVOL_ERR_NOMEM, "brick bounds: out of memory");
            }
        }
    /* one pass over the coefficients; a thread owns whole z-slabs of blocks */
    for (int qi = 0; qi < b->nbands; qi++) {
        band_blocks *q = &b->bb[qi];
        long zb;
        size_t off[3];
        float gmax = 0.0f;
        for (a = 0; a < 3; a++) off[a] = ((q->band >> a) & 1) ? q->e[a] : 0;
        if (q->band == 0) { /* global max of the low-pass cube, for the tail terms */
            size_t x, y, z;
            for (z = 0; z < q->e[2]; z++)
                for (y = 0; y < q->e[1]; y++)
                    for (x = 0; x < q->e[0]; x++) {
                        float av = fabsf(c->data[x + c->px * (y + c->py * z)]);
                        if (!(av <= gmax)) gmax = isnan(av) ? INFINITY : av;
                    }
            q->gmax = gmax;
            continue;
        }
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1)
#endif
        for (zb = 0; zb < (long)q->nb[2]; zb++) {
            size_t z0 = (size_t)zb * q->bs[2], z1 = z0 + q->bs[2] < q->e[2] ? z0 + q->bs[2] : q->e[2], z, y, x;
            for (z = z0; z < z1; z++)
                for (y = 0; y < q->e[1]; y++) {
                    const float *row = c->data + off[0] + c->px * ((off[1] + y) + c->py * (off[2] + z));
                    float *brow = q->absmax + q->nb[0] * ((y >> q->bshift[1]) + q->nb[1] * (size_t)zb);
                    const int sh = q->bshift[0];
                    for (x = 0; x < q->e[0]; x++) {
                        float av = fabsf(row[x]);
                        if (!(av <= brow[x >> sh])) brow[x >> sh] = av; /* NaN propagates */
                    }
                }
        }
        {
            size_t i, nblk = q->absmax ? q->nb[0] * q->nb[1] * q->nb[2] : 0;
            for (i = 0; i < nblk; i++)
                if (!(q->absmax[i] <= gmax)) gmax = isnan(q->absmax[i]) ? INFINITY : q->absmax[i];
        }
        q->gmax = gmax;
    }
    *out = b;
    return WVOL_OK;
}

/* Coefficient positions [*k0, *k0 + *kn) (unwrapped) whose core reaches samples
 * [s0, s1] along axis a; the whole band when that covers the period. */
static void reach(const band_blocks *q, int a, long s0, long s1, long *k0, long *kn)
{
    long step = 1L << q->m, e = (long)q->e[a], klo = s0 - q->hi[a], khi = s1 - q->lo[a];
    long c0 = klo >= 0 ? (klo + step - 1) / step : -((-klo) / step); /* ceil */
    long c1 = khi >= 0 ? khi / step : -((-khi + step - 1) / step);   /* floor */
    *k0 = c0;
    *kn = c1 - c0 + 1;
    if (*kn > e) *k0 = 0, *kn = e;
    if (*kn < 0) *kn = 0;
}

static inline long wrap(long k, long e) { return ((k % e) + e) % e; }

/* Bound of the reconstructed samples in the box [s0, s1] (inclusive, voxel indices). */
static void box_bound(const brick_bounds *b, const long s0[3], const long s1[3], double *vmin, double *vmax)
{
    double detail = 0.0, lo = 0.0, hi = 0.0, mag = 0.0;
    int qi, a;
    for (qi = 0; qi < b->nbands; qi++) {
        const band_blocks *q = &b->bb[qi];
        long k0[3], kn[3], x, y, z;
        float amax = 0.0f;
        for (a = 0; a < 3; a++) reach(q, a, s0[a], s1[a], &k0[a], &kn[a]);
        if (q->band == 0) {
            /* the low-pass cube is small: scan the coefficients whose core reaches the box */
            float cmin = INFINITY, cmax = -INFINITY;
            for (z = 0; z < kn[2]; z++) {
                size_t kz = (size_t)wrap(k0[2] + z, (long)q->e[2]);
                for (y = 0; y < kn[1]; y++) {
                    size_t ky = (size_t)wrap(k0[1] + y, (long)q->e[1]);
                    const float *row = b->c->data + b->c->px * (ky + b->c->py * kz);
                    for (x = 0; x < kn[0]; x++) {
                        float v = row[wrap(k0[0] + x, (long)q->e[0])];
                        if (!(v >= cmin)) cmin = v;
                        if (!(v <= cmax)) cmax = v;
                    }
                }
            }
            if (cmin > cmax) cmin = cmax = 0.0f; /* no core reaches (cannot happen for a non-empty box) */
            {
                double a0 = 0.5 * ((double)cmin + (double)cmax), half = 0.5 * ((double)cmax - (double)cmin);
                double p1 = a0 * q->smin, p2 = a0 * q->smax;
                double off = half * q->leb + ((double)q->gmax + fabs(a0)) * q->tailw;
                lo = (p1 < p2 ? p1 : p2) - off;
                hi = (p1 > p2 ? p1 : p2) + off;
                mag += (double)q->gmax * (q->leb + q->tailw);
            }
            continue;
        }
        /* detail band: block maxima over the reach */
        {
            long b0[3], b1[3];
            for (a = 0; a < 3; a++) {
                long bs = (long)q->bs[a], nbk = (long)q->nb[a];
                if (kn[a] >= (long)q->e[a]) {
                    b0[a] = 0, b1[a] = nbk - 1;
                } else {
                    long m0 = wrap(k0[a], (long)q->e[a]), last = m0 + kn[a] - 1;
                    b0[a] = m0 / bs;
                    b1[a] = last < (long)q->e[a] ? last / bs : nbk + (last - (long)q->e[a]) / bs;
                    if (b1[a] - b0[a] + 1 > nbk) b1[a] = b0[a] + nbk - 1;
                }
            }
            if (kn[0] > 0 && kn[1] > 0 && kn[2] > 0)
                for (z = b0[2]; z <= b1[2]; z++) {
                    size_t bz = (size_t)(z % (long)q->nb[2]);
                    for (y = b0[1]; y <= b1[1]; y++) {
                        size_t by = (size_t)(y % (long)q->nb[1]);
                        const float *row = q->absmax + q->nb[0] * (by + q->nb[1] * bz);
                        for (x = b0[0]; x <= b1[0]; x++) {
                            float v = row[x % (long)q->nb[0]];
                            if (!(v <= amax)) amax = v;
                        }
                    }
                }
            detail += (double)amax * q->leb + (double)q->gmax * q->tailw;
        }
    }
    mag += detail;
    /* rounding: float coefficients summed in double, the result rounded to float */
    {
        double pad = 1e-5 * mag + 1e-30;
        *vmin = lo - detail - pad;
        *vmax = hi + detail + pad;
    }
}

/* Exposed for the tests: bound of the samples of box [s0, s1] (inclusive). */
wvol_status wvol__iso_box_bound(const wvol_coeffs *c, const long s0[3], const long s1[3], double *vmin,
                                double *vmax, wvol_error *err)
{
    brick_bounds *b;
    WVOL_FORWARD(bounds_create(&b, c, err));
    box_bound(b, s0, s1, vmin, vmax);
    bounds_free(b);
    return WVOL_OK;
}

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
} brick_grid;

static size_t owner_axis(const brick_grid *g, int a, uint64_t p)
{
    size_t b = (size_t)(p / (uint64_t)g->B);
    return b < g->nb[a] ? b : g->nb[a] - 1;
}

static void decode_key(const size_t gdims[3], uint64_t key, uint64_t p[3], int *axis)
{
    p[0] = key % gdims[0];
    key /= gdims[0];
    *axis = (int)(key % 3);
    key /= 3;
    p[1] = key % gdims[1];
    p[2] = key / gdims[1];
}

static void mesh_brick(brick_out *o, const wvol_coeffs *c, const brick_grid *g, const size_t bidx[3], double iso,
                       wvol_iso_normals normals)
{
    size_t lo[3], hi[3], c0[3], c1[3];
    wvol_volume *v = NULL;
    wvol__mc_job jb;
    size_t i;
    int a;
    wvol_error_clear(&o->err);
    for (a = 0; a < 3; a++) {
        c0[a] = bidx[a] * (size_t)g->B;
        c1[a] = c0[a] + (size_t)g->B < g->n[a] - 1 ? c0[a] + (size_t)g->B : g->n[a] - 1;
        lo[a] = c0[a] > 0 ? c0[a] - 1 : 0;                  /* halo for normals */
        hi[a] = c1[a] + 2 <= g->n[a] ? c1[a] + 2 : g->n[a];  /* exclusive */
    }
    o->status = wvol_idwt3_brick(&v, c, lo, hi, &o->err);
    if (o->status != WVOL_OK) return;
    memset(&jb, 0, sizeof jb);
    jb.data = v->data;
    for (a = 0; a < 3; a++) {
        jb.adims[a] = hi[a] - lo[a];
        jb.lo[a] = c0[a] - lo[a];
        jb.n[a] = c1[a] - c0[a] + 1;
        jb.gofs[a] = (long long)lo[a];
        jb.gdims[a] = g->n[a];
        jb.origin[a] = c->origin[a];
        jb.spacing[a] = c->spacing[a];
    }
    jb.iso = iso;
    jb.threads = 1;
    jb.normals = normals;
    jb.keys = &o->keys;
    o->status = wvol__mc_run(&o->mesh, &jb, NULL, &o->err);
    wvol_volume_destroy(v);
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
        decode_key(g->n, o->keys[i], p, &axis);
        for (a = 0; a < 3; a++)
            if (owner_axis(g, a, p[a]) != bidx[a]) own = 0;
        o->owned[i] = (unsigned char)own;
        if (own) o->owned_keys[o->nowned++] = o->keys[i];
    }
}

static long find_key(const uint64_t *keys, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (keys[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && keys[lo] == key ? (long)lo : -1;
}

wvol_status wvol_iso_extract_coeffs(wvol_mesh **out, const wvol_coeffs *c, double iso, const wvol_iso_params *p,
                                    wvol_iso_stats *st, wvol_error *err)
{
    wvol_iso_params def;
    wvol_iso_stats local;
    brick_bounds *bb = NULL;
    brick_grid g;
    size_t nbricks, nneed = 0, i, *need = NULL, *slot = NULL, nv = 0, nt = 0, misses = 0;
    brick_out *res = NULL;
    wvol_mesh *m = NULL;
    wvol_status s = WVOL_OK;
    double t0 = now_s(), t1, t2, gmin = INFINITY, gmax = -INFINITY;
    int nth, a;

    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "iso: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!c || !c->data || !c->filter, err, WVOL_ERR_ARG, "iso: coefficients are NULL");
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
    WVOL_RETURN_IF(p->normals == WVOL_NORMALS_ANALYTIC && !p->gradient, err, WVOL_ERR_ARG,
                   "iso: analytic normals requested without a gradient function");
    g.n[0] = c->nx, g.n[1] = c->ny, g.n[2] = c->nz;
    g.B = p->brick;
    if (g.n[0] < 2 || g.n[1] < 2 || g.n[2] < 2) {
        WVOL_FORWARD(wvol_mesh_create(out, 0, 0, 0, err));
        st->empty = 1;
        snprintf(st->message, sizeof st->message,
                 "the volume has fewer than 2 samples along an axis (no cells): empty mesh");
        return WVOL_OK;
    }
    for (a = 0; a < 3; a++) g.nb[a] = (g.n[a] - 1 + (size_t)g.B - 1) / (size_t)g.B;
    nbricks = g.nb[0] * g.nb[1] * g.nb[2];
#ifdef _OPENMP
    nth = p->threads > 0 ? p->threads : omp_get_max_threads();
#else
    nth = 1;
#endif
    s = bounds_create(&bb, c, err);
    if (s != WVOL_OK) return s;
    need = malloc(nbricks * sizeof *need);
    slot = malloc(nbricks * sizeof *slot);
    if (!need || !slot) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nbricks);
        goto done;
    }
    /* bounds per brick: samples [c0, c1] (owned cells plus the shared layer) */
    for (i = 0; i < nbricks; i++) {
        size_t bidx[3] = {i % g.nb[0], (i / g.nb[0]) % g.nb[1], i / (g.nb[0] * g.nb[1])};
        long s0[3], s1[3];
        double lo, hi;
        for (a = 0; a < 3; a++) {
            s0[a] = (long)(bidx[a] * (size_t)g.B);
            s1[a] = s0[a] + g.B < (long)g.n[a] - 1 ? s0[a] + g.B : (long)g.n[a] - 1;
        }
        box_bound(bb, s0, s1, &lo, &hi);
        if (lo < gmin) gmin = lo;
        if (hi > gmax) gmax = hi;
        slot[i] = (size_t)-1;
        /* a sample is positive when >= iso: skip when all are surely positive or negative */
        if (!(lo >= iso) && !(hi < iso)) {
            slot[i] = nneed;
            need[nneed++] = i;
        }
    }
    t1 = now_s();
    st->bricks_total = nbricks;
    st->bricks_meshed = nneed;
    st->bricks_skipped = nbricks - nneed;
    st->seconds_bounds = t1 - t0;
    res = calloc(nneed + 1, sizeof *res);
    if (!res) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory for %zu bricks", nneed);
        goto done;
    }
    {
        long q;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth) if (nth > 1)
#endif
        for (q = 0; q < (long)nneed; q++) {
            size_t bi = need[q];
            size_t bidx[3] = {bi % g.nb[0], (bi / g.nb[0]) % g.nb[1], bi / (g.nb[0] * g.nb[1])};
            mesh_brick(&res[q], c, &g, bidx, iso, p->normals == WVOL_NORMALS_NONE ? WVOL_NORMALS_NONE
                                                                                  : WVOL_NORMALS_GRADIENT);
        }
    }
    t2 = now_s();
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
    s = wvol_mesh_create(&m, nv, nt, p->normals != WVOL_NORMALS_NONE, err);
    if (s != WVOL_OK) goto done;
    memset(m->tris, 0xff, 3 * nt * sizeof *m->tris);
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
#pragma omp parallel for schedule(dynamic, 4) num_threads(nth) if (nth > 1) reduction(+ : misses)
#endif
        for (q = 0; q < (long)nneed; q++) {
            brick_out *o = &res[q];
            wvol_mesh *bm = o->mesh;
            uint32_t *map = malloc((bm->nverts + 1) * sizeof *map);
            size_t k, r = 0, t;
            if (!map) continue; /* reported below through the triangle check */
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
                    decode_key(g.n, o->keys[k], pt, &axis);
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
    for (i = 0; i < 3 * nt; i++)
        if (m->tris[i] >= nv) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "iso: out of memory while stitching bricks");
            goto done;
        }
    st->seconds[2] = t2 - t1;
    st->seconds[3] = now_s() - t0;
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
    bounds_free(bb);
    return s;
}
