/* SPDX-License-Identifier: MIT
 * The bricked iso caster (Parker et al. 1998, "Interactive ray tracing for isosurface
 * rendering"; Marmitt et al. 2004 for the cell test, cast_cell.c): rays against the surface
 * interp = iso of the trilinear interpolant of a volume's samples or of a store's
 * reconstruction.
 *
 * Bricks. The grid's cells are cut into bricks of B^3 cells; a brick holds its (B+1)^3 samples
 * (its cells' corners, sharing a layer with the next brick). Before any ray, each brick gets a
 * class from a bound of its samples: for a store the rigorous bound from the kept coefficients
 * alone (wavelet/bounds.c through store/store_blocks.h, marching cubes' bound), for a volume
 * the samples' exact min and max. Class 1: every sample >= iso; 0: every sample < iso; -1:
 * undecided. A trilinear cell lies between its corners' min and max, so a brick of class 0 or
 * 1 holds no crossing and rays step over it. An undecided brick is built the first time a ray
 * reaches it (reconstructed from the store's block view by wvol__idwt3_brick_src, or copied
 * from the volume), under a per-brick lock, with the exact min/max of its samples and of each
 * group of 4^3 cells: the min/max hierarchy that lets rays skip most of it.
 *
 * The walk. In voxel coordinates, the ray is clipped to the sample extent [0, n-1]; three
 * nested grid walks (Amanatides-Woo) visit bricks, groups and cells front to back over
 * contiguous parameter intervals. `prev` is the class at the end of what is done (-1 before
 * the entry); a skipped brick, group or cell of class c after prev != c means interp equals
 * iso on their common face: a crossing there. A straddling cell gets the exact test.
 *
 * The convention for a ray that enters the extent inside the surface (interp >= iso at its
 * entry, where a face of the box cuts the surface): its hit is the first change of class after
 * the entry, where it leaves the surface (what a mesh of the same samples shows there: the
 * back face of the open mesh); no cap is drawn on the box face. docs/iso.md. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/clock.h"
#include "iso_internal.h"
#include "store/store_blocks.h"
#include "wvol/iso.h"

#define GROUP 4 /* cells per group edge */

struct wvol__caster {
    const wvol_volume *vol;          /* the source: a volume, or */
    wvol__store_blocks *blocks;      /* a store's block view, */
    wvol__brick_bounds *bb;          /* its bounds (NULL: none apply), */
    wvol__coef_source cs;            /* and the reconstruction's source */
    size_t n[3], nb[3], nbricks;
    int B;
    double origin[3], spacing[3];
    double iso, tol;
    signed char *bcls;               /* per brick: the bound's class, -1 undecided */
    float **bdata;                   /* per brick: NULL until built */
    double *fbound;                  /* per built brick of a store: the bound of |f^ - interp| over it
                                        (+inf: none applies), NaN until built */
    double **gbound;                 /* ... and per group of its cells (NULL: none) */
    const wvol_store *store;
    wvol__fhat_link link;            /* constants of that bound */
    size_t halo[2];                  /* samples kept below and above a brick's own */
    size_t nbound, built, bytes;
#ifdef _OPENMP
    omp_lock_t *locks;
#endif
};

void wvol_iso_cast_params_default(wvol_iso_cast_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->brick = 32;
    p->tolerance = 1e-5;
    p->color[0] = 0.93f, p->color[1] = 0.89f, p->color[2] = 0.80f;
    p->ambient = 0.15f;
}

/* Where brick b's samples are: its own cells' corners c0 .. c0 + cells, and the stored box
 * lo .. lo + md - 1 around them (the halo the model bound needs, clipped to the volume). */
typedef struct bgeom {
    size_t c0[3], cells[3], lo[3], md[3], g[3], ns, ng, core;
    int whole; /* the halo is complete (no face clipped it) */
} bgeom;

/* Groups of GROUP cells along an axis of `cells` cells. */
static size_t groups(size_t cells)
{
    return (cells + GROUP - 1) / GROUP;
}

static void brick_geom(const wvol__caster *c, size_t b, bgeom *q)
{
    size_t idx[3] = {b % c->nb[0], (b / c->nb[0]) % c->nb[1], b / (c->nb[0] * c->nb[1])};
    int a;
    q->whole = 1;
    for (a = 0; a < 3; a++) {
        size_t hi;
        q->c0[a] = idx[a] * (size_t)c->B;
        q->cells[a] = c->n[a] - 1 - q->c0[a] < (size_t)c->B ? c->n[a] - 1 - q->c0[a] : (size_t)c->B;
        q->lo[a] = q->c0[a] >= c->halo[0] ? q->c0[a] - c->halo[0] : 0;
        hi = q->c0[a] + q->cells[a] + c->halo[1] <= c->n[a] - 1 ? q->c0[a] + q->cells[a] + c->halo[1] : c->n[a] - 1;
        if (q->c0[a] - q->lo[a] < c->halo[0] || hi - q->c0[a] - q->cells[a] < c->halo[1]) q->whole = 0;
        q->md[a] = hi - q->lo[a] + 1;
        q->g[a] = groups(q->cells[a]);
    }
    q->ns = q->md[0] * q->md[1] * q->md[2];
    q->ng = q->g[0] * q->g[1] * q->g[2];
    q->core = (q->c0[0] - q->lo[0]) + q->md[0] * ((q->c0[1] - q->lo[1]) + q->md[1] * (q->c0[2] - q->lo[2]));
}

/* Layout of a built brick: [bmin, bmax] of its own samples, the stored samples (x fastest),
 * then the groups' min and max. */
static float *brick_build(wvol__caster *c, wvol__cast_ws *w, size_t b, wvol_error *err)
{
    bgeom q;
    size_t i, j, k, hi[3];
    float *d, *s, *core, *gmin, *gmax, lo = INFINITY, up = -INFINITY;
    const size_t *m;
    int a;
    brick_geom(c, b, &q);
    for (a = 0; a < 3; a++) hi[a] = q.lo[a] + q.md[a];
    d = malloc((2 + q.ns + 2 * q.ng) * sizeof *d);
    if (!d) {
        wvol_error_set(err, WVOL_ERR_NOMEM, "iso cast: out of memory for a brick");
        return NULL;
    }
    s = d + 2;
    if (c->vol) {
        for (k = 0; k < q.md[2]; k++)
            for (j = 0; j < q.md[1]; j++)
                memcpy(s + q.md[0] * (j + q.md[1] * k),
                       c->vol->data + q.lo[0] + c->n[0] * (q.lo[1] + j + c->n[1] * (q.lo[2] + k)), q.md[0] * sizeof *s);
    } else if (wvol__idwt3_brick_src(s, &c->cs, q.lo, hi, &w->scr, err) != WVOL_OK) {
        free(d);
        return NULL;
    }
    core = s + q.core;
    m = q.md;
    gmin = s + q.ns;
    gmax = gmin + q.ng;
    for (i = 0; i < q.ng; i++) gmin[i] = INFINITY, gmax[i] = -INFINITY;
    /* a sample belongs to every group whose cells it is a corner of */
    for (k = 0; k <= q.cells[2]; k++)
        for (j = 0; j <= q.cells[1]; j++)
            for (i = 0; i <= q.cells[0]; i++) {
                float v = core[i + m[0] * (j + m[1] * k)];
                size_t gk0 = k ? (k - 1) / GROUP : 0, gk1 = k / GROUP < q.g[2] ? k / GROUP : q.g[2] - 1;
                size_t gj0 = j ? (j - 1) / GROUP : 0, gj1 = j / GROUP < q.g[1] ? j / GROUP : q.g[1] - 1;
                size_t gi0 = i ? (i - 1) / GROUP : 0, gi1 = i / GROUP < q.g[0] ? i / GROUP : q.g[0] - 1;
                size_t x, y, z;
                if (v < lo) lo = v;
                if (v > up) up = v;
                for (z = gk0; z <= gk1; z++)
                    for (y = gj0; y <= gj1; y++)
                        for (x = gi0; x <= gi1; x++) {
                            size_t g = x + q.g[0] * (y + q.g[1] * z);
                            if (v < gmin[g]) gmin[g] = v;
                            if (v > gmax[g]) gmax[g] = v;
                        }
            }
    d[0] = lo;
    d[1] = up;
    if (c->fbound) { /* the model bound per group: its samples' window and the functions touching it */
        double e = INFINITY, *ge = q.whole && c->link.ok ? malloc(q.ng * sizeof *ge) : NULL;
        if (ge) {
            double blo[3], bhi[3];
            size_t core[3];
            for (a = 0; a < 3; a++) {
                blo[a] = (double)q.c0[a], bhi[a] = (double)(q.c0[a] + q.cells[a]);
                core[a] = q.c0[a] - q.lo[a];
            }
            if (wvol_store_query_box(c->store, blo, bhi, &w->hits, err) != WVOL_OK) {
                free(ge);
                free(d);
                return NULL;
            }
            e = wvol__fhat_link_bound(&c->link, s, q.md, core, q.c0, q.cells, GROUP, w->hits.hits, w->hits.count, ge);
            if (!isfinite(e)) free(ge), ge = NULL;
        }
        c->gbound[b] = ge;
        c->fbound[b] = e;
    }
    return d;
}

/* Brick b's data, built on first use (one thread builds, the others wait on its lock). */
static const float *brick_get(wvol__caster *c, wvol__cast_ws *w, size_t b, wvol_error *err)
{
    float *d = __atomic_load_n(&c->bdata[b], __ATOMIC_ACQUIRE);
    if (d) return d;
#ifdef _OPENMP
    omp_set_lock(&c->locks[b]);
#endif
    d = __atomic_load_n(&c->bdata[b], __ATOMIC_ACQUIRE);
    if (!d) {
        double t0 = wvol__now();
        d = brick_build(c, w, b, err);
        w->seconds_build += wvol__now() - t0;
        if (d) {
            __atomic_fetch_add(&c->built, 1, __ATOMIC_RELAXED);
            __atomic_store_n(&c->bdata[b], d, __ATOMIC_RELEASE);
        }
    }
#ifdef _OPENMP
    omp_unset_lock(&c->locks[b]);
#endif
    return d;
}

wvol_status wvol__caster_create(wvol__caster **out, const wvol_render_source *src, double iso,
                                const wvol_iso_cast_params *p, wvol_error *err)
{
    wvol_iso_cast_params def;
    wvol__caster *c;
    size_t b;
    int a;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "iso cast: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!src || (src->kind == WVOL_RENDER_SOURCE_VOLUME ? !src->volume || !src->volume->data
                                                                   : src->kind != WVOL_RENDER_SOURCE_STORE || !src->store),
                   err, WVOL_ERR_ARG, "iso cast: no volume or store to cast");
    WVOL_RETURN_IF(!isfinite(iso), err, WVOL_ERR_ARG, "iso cast: iso-value %g is not finite", iso);
    if (!p) {
        wvol_iso_cast_params_default(&def);
        p = &def;
    }
    WVOL_RETURN_IF(p->brick < 4 || p->brick > 1024, err, WVOL_ERR_ARG, "iso cast: brick %d outside 4..1024",
                   p->brick);
    WVOL_RETURN_IF(!(p->tolerance > 0) || !isfinite(p->tolerance), err, WVOL_ERR_ARG,
                   "iso cast: tolerance %g must be a positive number of voxels", p->tolerance);
    WVOL_FORWARD(wvol__threads_check(p->threads, "iso cast", err));
    WVOL_RETURN_IF(p->model_bound != 0 && p->model_bound != 1, err, WVOL_ERR_ARG, "iso cast: model_bound %d (0 or 1)",
                   p->model_bound);
    WVOL_FORWARD(wvol__iso_shading_check(p->light, p->color, p->ambient, "iso cast", err));
    c = calloc(1, sizeof *c);
    WVOL_RETURN_IF(!c, err, WVOL_ERR_NOMEM, "iso cast: out of memory");
    c->iso = iso;
    c->tol = p->tolerance;
    c->B = p->brick;
    if (src->kind == WVOL_RENDER_SOURCE_VOLUME) {
        const wvol_volume *v = src->volume;
        c->vol = v;
        c->n[0] = v->nx, c->n[1] = v->ny, c->n[2] = v->nz;
        for (a = 0; a < 3; a++) c->origin[a] = v->origin[a], c->spacing[a] = v->spacing[a];
    } else {
        wvol_store_info info;
        wvol_status st;
        wvol_store_get_info(src->store, &info);
        c->n[0] = info.nx, c->n[1] = info.ny, c->n[2] = info.nz;
        for (a = 0; a < 3; a++) c->origin[a] = info.origin[a], c->spacing[a] = info.spacing[a];
        st = wvol__store_blocks_create(&c->blocks, &c->bb, src->store, p->threads, err);
        if (st != WVOL_OK) {
            wvol__caster_destroy(c);
            return st;
        }
        wvol__store_blocks_source(&c->cs, c->blocks);
        if (p->model_bound) {
            c->store = src->store;
            wvol__fhat_link_init(&c->link, src->store);
            if (c->link.ok) c->halo[0] = (size_t)c->link.below, c->halo[1] = (size_t)c->link.above;
        }
        c->bytes += wvol__store_blocks_bytes(c->blocks) + (c->bb ? wvol__bounds_bytes(c->bb) : 0);
    }
    /* at least one sample around each brick: central differences for the normals */
    if (c->halo[0] < 1) c->halo[0] = 1;
    if (c->halo[1] < 1) c->halo[1] = 1;
    for (a = 0; a < 3; a++) {
        if (!(c->spacing[a] > 0) || !isfinite(c->spacing[a])) {
            wvol__caster_destroy(c);
            return wvol_error_set(err, WVOL_ERR_ARG, "iso cast: spacing %g along axis %d", c->spacing[a], a);
        }
        c->nb[a] = c->n[a] >= 2 ? (c->n[a] - 2) / (size_t)c->B + 1 : 0;
    }
    c->nbricks = c->nb[0] * c->nb[1] * c->nb[2];
    c->bcls = malloc(c->nbricks + 1);
    c->bdata = calloc(c->nbricks + 1, sizeof *c->bdata);
#ifdef _OPENMP
    c->locks = malloc((c->nbricks + 1) * sizeof *c->locks);
    if (c->locks)
        for (b = 0; b < c->nbricks; b++) omp_init_lock(&c->locks[b]);
    if (!c->locks) {
        wvol__caster_destroy(c);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "iso cast: out of memory for %zu bricks", c->nbricks);
    }
#endif
    if (!c->bcls || !c->bdata) {
        wvol__caster_destroy(c);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "iso cast: out of memory for %zu bricks", c->nbricks);
    }
    c->bytes += c->nbricks * (1 + sizeof *c->bdata);
    if (c->store) {
        c->fbound = malloc((c->nbricks + 1) * sizeof *c->fbound);
        c->gbound = calloc(c->nbricks + 1, sizeof *c->gbound);
        if (!c->fbound || !c->gbound) {
            wvol__caster_destroy(c);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "iso cast: out of memory for %zu bricks", c->nbricks);
        }
        for (b = 0; b < c->nbricks; b++) c->fbound[b] = NAN;
        c->bytes += c->nbricks * (sizeof *c->fbound + sizeof *c->gbound);
    }
    for (b = 0; b < c->nbricks; b++) { /* the bound's class of every brick's samples */
        bgeom q;
        const size_t *c0 = q.c0, *cells = q.cells;
        double lo = -INFINITY, hi = INFINITY;
        brick_geom(c, b, &q);
        if (c->vol) {
            size_t i, j, k;
            lo = INFINITY, hi = -INFINITY;
            for (k = c0[2]; k <= c0[2] + cells[2]; k++)
                for (j = c0[1]; j <= c0[1] + cells[1]; j++) {
                    const float *row = c->vol->data + c->n[0] * (j + c->n[1] * k);
                    for (i = c0[0]; i <= c0[0] + cells[0]; i++) {
                        double v = row[i];
                        if (!isfinite(v)) {
                            wvol__caster_destroy(c);
                            return wvol_error_set(err, WVOL_ERR_NONFINITE, "iso cast: voxel (%zu, %zu, %zu) is not finite",
                                                  i, j, k);
                        }
                        if (v < lo) lo = v;
                        if (v > hi) hi = v;
                    }
                }
        } else if (c->bb) {
            long s0[3], s1[3];
            for (a = 0; a < 3; a++) s0[a] = (long)c0[a], s1[a] = (long)(c0[a] + cells[a]);
            wvol__bounds_box(c->bb, s0, s1, &lo, &hi);
        }
        c->bcls[b] = lo >= iso ? 1 : hi < iso ? 0 : -1;
        c->nbound += c->bcls[b] >= 0;
    }
    *out = c;
    return WVOL_OK;
}

void wvol__caster_destroy(wvol__caster *c)
{
    size_t b;
    if (!c) return;
    if (c->bdata)
        for (b = 0; b < c->nbricks; b++) free(c->bdata[b]);
    if (c->gbound)
        for (b = 0; b < c->nbricks; b++) free(c->gbound[b]);
#ifdef _OPENMP
    if (c->locks)
        for (b = 0; b < c->nbricks; b++) omp_destroy_lock(&c->locks[b]);
    free(c->locks);
#endif
    free(c->bdata);
    free(c->bcls);
    free(c->fbound);
    free(c->gbound);
    wvol__bounds_free(c->bb);
    wvol__store_blocks_destroy(c->blocks);
    free(c);
}

void wvol__caster_counts(const wvol__caster *c, size_t *total, size_t *bound, size_t *built, size_t *bytes)
{
    size_t b, nb = 0;
    *total = c->nbricks;
    *bound = c->nbound;
    *built = c->built;
    for (b = 0; b < c->nbricks; b++)
        if (c->bdata[b]) {
            bgeom q;
            brick_geom(c, b, &q);
            nb += (2 + q.ns + 2 * q.ng) * sizeof(float);
            if (c->gbound && c->gbound[b]) nb += q.ng * sizeof(double);
        }
    *bytes = c->bytes + nb;
}

double wvol__caster_fhat_bound(wvol__caster *c, wvol__cast_ws *w, const double x[3], wvol_error *err)
{
    size_t b = 0, stride = 1, g = 0, gs = 1, ci[3];
    bgeom q;
    int a;
    if (!c->fbound) return INFINITY;
    for (a = 0; a < 3; a++) {
        long i = (long)floor(x[a]);
        if (i < 0) i = 0;
        if (i > (long)c->n[a] - 2) i = (long)c->n[a] - 2;
        ci[a] = (size_t)i;
        b += (size_t)i / (size_t)c->B * stride;
        stride *= c->nb[a];
    }
    if (!brick_get(c, w, b, err)) return NAN;
    if (!c->gbound[b]) return c->fbound[b];
    brick_geom(c, b, &q);
    for (a = 0; a < 3; a++) { /* the group holding the cell of x (its closed box holds x) */
        g += (ci[a] - q.c0[a]) / GROUP * gs;
        gs *= q.g[a];
    }
    return c->gbound[b][g];
}

void wvol__cast_ws_free(wvol__cast_ws *w)
{
    wvol__brick_scratch_free(&w->scr);
    wvol_store_hits_free(&w->hits);
    memset(w, 0, sizeof *w);
}

/* ---- the grid walk (Amanatides & Woo 1987) over cells of size S from `base`, n per axis ---- */
typedef struct walk {
    long i[3], n[3], step[3];
    double next[3], delta[3], t, tend;
    int done;
} walk;

static void walk_init(walk *w, const double ov[3], const double dv[3], double ta, double tb, const double base[3],
                      double S, const long n[3])
{
    int a;
    for (a = 0; a < 3; a++) {
        double x = ov[a] + ta * dv[a], f = floor((x - base[a]) / S);
        long i = f < 0 ? 0 : f >= (double)n[a] ? n[a] - 1 : (long)f;
        w->i[a] = i;
        w->n[a] = n[a];
        if (dv[a] > 0) {
            w->step[a] = 1;
            w->next[a] = (base[a] + S * (double)(i + 1) - ov[a]) / dv[a];
            w->delta[a] = S / dv[a];
        } else if (dv[a] < 0) {
            w->step[a] = -1;
            w->next[a] = (base[a] + S * (double)i - ov[a]) / dv[a];
            w->delta[a] = -S / dv[a];
        } else {
            w->step[a] = 0;
            w->next[a] = INFINITY;
            w->delta[a] = INFINITY;
        }
    }
    w->t = ta;
    w->tend = tb;
    w->done = !(ta < tb);
}

/* The current cell and its interval [*t0, *t1]; then steps. 0 when the walk is over. */
static int walk_next(walk *w, long idx[3], double *t0, double *t1)
{
    int a, m;
    double out;
    if (w->done) return 0;
    m = w->next[0] <= w->next[1] ? (w->next[0] <= w->next[2] ? 0 : 2) : (w->next[1] <= w->next[2] ? 1 : 2);
    out = w->next[m] < w->tend ? w->next[m] : w->tend;
    if (out < w->t) out = w->t;
    for (a = 0; a < 3; a++) idx[a] = w->i[a];
    *t0 = w->t;
    *t1 = out;
    if (w->next[m] >= w->tend) {
        w->done = 1;
    } else {
        w->i[m] += w->step[m];
        w->next[m] += w->delta[m];
        w->t = out;
        if (w->i[m] < 0 || w->i[m] >= w->n[m]) w->done = 1;
    }
    return 1;
}

/* ---- one ray ---- */

typedef struct ray {
    double o[3], d[3], ov[3], dv[3], speed;
    int prev;       /* class at the end of what is done; -1 before the entry */
} ray;

/* The eight corners of the cell at l (relative to s, a brick's own first sample; m the stored
 * box's dimensions). */
static void corners(const float *s, const size_t m[3], const long l[3], double c8[8])
{
    size_t sx = 1, sy = m[0], sz = m[0] * m[1];
    const float *p = s + (size_t)l[0] + sy * (size_t)l[1] + sz * (size_t)l[2];
    c8[0] = p[0], c8[1] = p[sx], c8[2] = p[sy], c8[3] = p[sy + sx];
    c8[4] = p[sz], c8[5] = p[sz + sx], c8[6] = p[sz + sy], c8[7] = p[sz + sy + sx];
}

/* Where a cell's samples are: s the brick's first own sample, md the stored box's dimensions,
 * coff the brick's first own sample within the stored box, l the cell within the brick. */
typedef struct cellref {
    const float *s;
    const size_t *md, *coff;
    const long *l;
} cellref;

/* The gradient (per voxel) at q in the cell: central differences of the samples at its eight
 * corners (one-sided where the stored box ends: the volume's faces), interpolated trilinearly
 * like the values, so that normals vary smoothly across cells as a mesh's vertex normals do. */
static void smooth_gradient(const cellref *cr, const double q[3], double g[3])
{
    size_t sy = cr->md[0], sz = cr->md[0] * cr->md[1], st[3] = {1, cr->md[0], cr->md[0] * cr->md[1]};
    int k, a;
    g[0] = g[1] = g[2] = 0;
    for (k = 0; k < 8; k++) {
        long o[3] = {k & 1, (k >> 1) & 1, (k >> 2) & 1};
        const float *p = cr->s + (size_t)(cr->l[0] + o[0]) + sy * (size_t)(cr->l[1] + o[1]) + sz * (size_t)(cr->l[2] + o[2]);
        double w = (o[0] ? q[0] : 1 - q[0]) * (o[1] ? q[1] : 1 - q[1]) * (o[2] ? q[2] : 1 - q[2]);
        for (a = 0; a < 3; a++) {
            size_t x = cr->coff[a] + (size_t)(cr->l[a] + o[a]); /* the corner within the stored box */
            int lo = x > 0, hi = x + 1 < cr->md[a];
            double dv = (hi ? p[st[a]] : p[0]) - (lo ? p[-(ptrdiff_t)st[a]] : p[0]);
            g[a] += w * (lo && hi ? 0.5 * dv : dv);
        }
    }
}

/* Records the hit at t inside the cell cr whose lower corner is at cell[] (voxels). */
static void set_hit(const wvol__caster *c, const ray *r, const cellref *cr, const double cell[3], double t,
                    wvol_iso_hit *h)
{
    double q[3], g[3], c8[8], len = 0;
    int a;
    for (a = 0; a < 3; a++) {
        q[a] = r->ov[a] + t * r->dv[a] - cell[a];
        q[a] = q[a] < 0 ? 0 : q[a] > 1 ? 1 : q[a];
    }
    corners(cr->s, cr->md, cr->l, c8);
    h->hit = 1;
    h->t = t;
    h->value = wvol__cell_eval(c8, q, g);
    smooth_gradient(cr, q, g);
    for (a = 0; a < 3; a++) {
        h->pos[a] = r->o[a] + t * r->d[a];
        g[a] /= c->spacing[a];
        len += g[a] * g[a];
    }
    len = sqrt(len);
    for (a = 0; a < 3; a++) h->normal[a] = len > 0 ? -g[a] / len : 0.0;
}

/* A hit at t where the class changes between two decided regions: the cell there gives the
 * value and normal. */
static wvol_status hit_at(wvol__caster *c, wvol__cast_ws *w, const ray *r, double t, wvol_iso_hit *h,
                          wvol_error *err)
{
    size_t b = 0, stride = 1;
    long l[3], bi[3];
    double cell[3];
    const float *d;
    bgeom q;
    int a;
    for (a = 0; a < 3; a++) {
        double x = r->ov[a] + t * r->dv[a];
        long ci = (long)floor(x);
        if (ci < 0) ci = 0;
        if (ci > (long)c->n[a] - 2) ci = (long)c->n[a] - 2;
        bi[a] = ci / c->B;
        b += (size_t)bi[a] * stride;
        stride *= c->nb[a];
        l[a] = ci - bi[a] * c->B;
        cell[a] = (double)ci;
    }
    d = brick_get(c, w, b, err);
    if (!d) return err ? err->status : WVOL_ERR_NOMEM;
    brick_geom(c, b, &q);
    {
        size_t coff[3] = {q.c0[0] - q.lo[0], q.c0[1] - q.lo[1], q.c0[2] - q.lo[2]};
        cellref cr = {d + 2 + q.core, q.md, coff, l};
        set_hit(c, r, &cr, cell, t, h);
    }
    return WVOL_OK;
}

/* A region of decided class cls entered at t: 1 when that is a crossing (recorded in h). */
static int decided(wvol__caster *c, wvol__cast_ws *w, ray *r, int cls, double t, wvol_iso_hit *h, wvol_status *st,
                   wvol_error *err)
{
    if (r->prev >= 0 && r->prev != cls) {
        *st = hit_at(c, w, r, t, h, err);
        return 1;
    }
    r->prev = cls;
    return 0;
}

/* The cells of group (gi) of a built brick over [ta, tb]: 1 on a hit (or an error in *st). */
static int cast_cells(wvol__caster *c, wvol__cast_ws *w, ray *r, const float *s, const size_t c0[3],
                      const size_t cells[3], const size_t m[3], const size_t coff[3], const long gi[3], double ta,
                      double tb, wvol_iso_hit *h)
{
    walk wk;
    long n[3], idx[3];
    double base[3], t0, t1, tol = c->tol / r->speed;
    int a;
    for (a = 0; a < 3; a++) {
        long first = gi[a] * GROUP, left = (long)cells[a] - first;
        base[a] = (double)c0[a] + (double)first;
        n[a] = left < GROUP ? left : GROUP;
    }
    walk_init(&wk, r->ov, r->dv, ta, tb, base, 1.0, n);
    while (walk_next(&wk, idx, &t0, &t1)) {
        long l[3];
        double c8[8], lo, hi, cell[3], q0[3], tau;
        int k;
        for (a = 0; a < 3; a++) l[a] = gi[a] * GROUP + idx[a], cell[a] = base[a] + (double)idx[a];
        corners(s, m, l, c8);
        lo = hi = c8[0];
        for (k = 1; k < 8; k++) lo = c8[k] < lo ? c8[k] : lo, hi = c8[k] > hi ? c8[k] : hi;
        if (lo >= c->iso || hi < c->iso) {
            int cls = lo >= c->iso;
            if (r->prev >= 0 && r->prev != cls) {
                cellref cr = {s, m, coff, l};
                set_hit(c, r, &cr, cell, t0, h);
                return 1;
            }
            r->prev = cls;
            continue;
        }
        w->cells++;
        for (a = 0; a < 3; a++) q0[a] = r->ov[a] + t0 * r->dv[a] - cell[a];
        if (wvol__cell_crossing(c8, q0, r->dv, t1 - t0, c->iso, &r->prev, tol, &tau)) {
            cellref cr = {s, m, coff, l};
            set_hit(c, r, &cr, cell, t0 + tau, h);
            return 1;
        }
    }
    return 0;
}

/* The groups of built brick b over [ta, tb]. */
static int cast_brick(wvol__caster *c, wvol__cast_ws *w, ray *r, size_t b, const float *d, double ta, double tb,
                      wvol_iso_hit *h, wvol_status *st, wvol_error *err)
{
    bgeom q;
    const float *s = d + 2, *gmin, *gmax;
    walk wk;
    long n[3], idx[3];
    double base[3], t0, t1;
    int a;
    brick_geom(c, b, &q);
    for (a = 0; a < 3; a++) {
        n[a] = (long)q.g[a];
        base[a] = (double)q.c0[a];
    }
    gmin = s + q.ns;
    gmax = gmin + q.ng;
    walk_init(&wk, r->ov, r->dv, ta, tb, base, (double)GROUP, n);
    while (walk_next(&wk, idx, &t0, &t1)) {
        size_t g = (size_t)idx[0] + q.g[0] * ((size_t)idx[1] + q.g[1] * (size_t)idx[2]);
        if (gmin[g] >= c->iso || gmax[g] < c->iso) {
            if (decided(c, w, r, gmin[g] >= c->iso, t0, h, st, err)) return 1;
            continue;
        }
        size_t coff[3] = {q.c0[0] - q.lo[0], q.c0[1] - q.lo[1], q.c0[2] - q.lo[2]};
        if (cast_cells(c, w, r, s + q.core, q.c0, q.cells, q.md, coff, idx, t0, t1, h)) return 1;
    }
    return 0;
}

wvol_status wvol__cast(wvol__caster *c, wvol__cast_ws *w, const double o[3], const double d[3], double tmin,
                       wvol_iso_hit *h, wvol_error *err)
{
    ray r;
    walk wk;
    long n[3], idx[3];
    double t0 = tmin, t1 = INFINITY, ta, tb, base[3] = {0, 0, 0};
    wvol_status st = WVOL_OK;
    int a;
    memset(h, 0, sizeof *h);
    h->t = INFINITY;
    if (c->nbricks == 0) return WVOL_OK;
    for (a = 0; a < 3; a++) {
        double lo = 0.0, hi = (double)c->n[a] - 1.0, x, y;
        r.o[a] = o[a];
        r.d[a] = d[a];
        r.ov[a] = (o[a] - c->origin[a]) / c->spacing[a];
        r.dv[a] = d[a] / c->spacing[a];
        if (r.dv[a] == 0.0) {
            if (!(r.ov[a] >= lo && r.ov[a] <= hi)) return WVOL_OK;
            continue;
        }
        x = (lo - r.ov[a]) / r.dv[a];
        y = (hi - r.ov[a]) / r.dv[a];
        if (x > y) {
            double tmp = x;
            x = y, y = tmp;
        }
        if (x > t0) t0 = x;
        if (y < t1) t1 = y;
        n[a] = (long)c->nb[a];
    }
    for (a = 0; a < 3; a++) n[a] = (long)c->nb[a];
    if (!(t0 < t1) || !isfinite(t0) || !isfinite(t1)) return WVOL_OK;
    r.speed = sqrt(r.dv[0] * r.dv[0] + r.dv[1] * r.dv[1] + r.dv[2] * r.dv[2]);
    r.prev = -1;
    walk_init(&wk, r.ov, r.dv, t0, t1, base, (double)c->B, n);
    while (walk_next(&wk, idx, &ta, &tb)) {
        size_t b = (size_t)idx[0] + c->nb[0] * ((size_t)idx[1] + c->nb[1] * (size_t)idx[2]);
        const float *bd;
        if (c->bcls[b] >= 0) {
            if (decided(c, w, &r, c->bcls[b], ta, h, &st, err)) return st;
            continue;
        }
        bd = brick_get(c, w, b, err);
        if (!bd) return err ? err->status : WVOL_ERR_NOMEM;
        if (bd[0] >= c->iso || bd[1] < c->iso) {
            if (decided(c, w, &r, bd[0] >= c->iso, ta, h, &st, err)) return st;
            continue;
        }
        if (cast_brick(c, w, &r, b, bd, ta, tb, h, &st, err)) return st;
    }
    return WVOL_OK;
}

/* ---- the API ---- */

wvol_status wvol_iso_cast_ray(const wvol_render_source *source, double iso, const double o[3], const double d[3],
                              const wvol_iso_cast_params *p, wvol_iso_hit *hit, wvol_error *err)
{
    wvol__caster *c;
    wvol__cast_ws w;
    double dn[3], len;
    wvol_status st;
    WVOL_RETURN_IF(!o || !d || !hit, err, WVOL_ERR_ARG, "iso cast: NULL argument");
    WVOL_RETURN_IF(!isfinite(o[0]) || !isfinite(o[1]) || !isfinite(o[2]), err, WVOL_ERR_ARG,
                   "iso cast: ray origin is not finite");
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    WVOL_RETURN_IF(!(len > 0) || !isfinite(len), err, WVOL_ERR_ARG, "iso cast: direction has no length");
    dn[0] = d[0] / len, dn[1] = d[1] / len, dn[2] = d[2] / len;
    WVOL_FORWARD(wvol__caster_create(&c, source, iso, p, err));
    memset(&w, 0, sizeof w);
    st = wvol__cast(c, &w, o, dn, 0.0, hit, err);
    wvol__cast_ws_free(&w);
    wvol__caster_destroy(c);
    return st;
}

wvol_status wvol_iso_cast(wvol_image *img, float *depth, float *normals, const wvol_render_source *source,
                          const wvol_camera *cam, double iso, const wvol_iso_cast_params *p, wvol_iso_cast_stats *st,
                          wvol_error *err)
{
    wvol_iso_cast_params def;
    wvol__caster *c = NULL;
    double t_start = wvol__now(), c_start = wvol__cpu_now(), t_bounds, tmin;
    size_t hits = 0, cells = 0;
    double build = 0.0;
    int nth, failed = 0;
    wvol_error first_err;
    WVOL_FORWARD(wvol__iso_image_check(img, cam, "iso cast", err));
    if (!p) {
        wvol_iso_cast_params_default(&def);
        p = &def;
    }
    WVOL_FORWARD(wvol__caster_create(&c, source, iso, p, err));
    t_bounds = wvol__now() - t_start;
    nth = wvol__threads(p->threads);
    tmin = cam->projection == WVOL_PROJECTION_PERSPECTIVE ? 0.0 : -INFINITY;
    wvol_error_clear(&first_err);
#pragma omp parallel num_threads(nth) reduction(+ : hits, cells, build)
    {
        wvol__cast_ws w;
        memset(&w, 0, sizeof w);
#pragma omp for schedule(dynamic, 1)
        for (int row = 0; row < img->height; row++) {
            for (int x = 0; x < img->width; x++) {
                double o[3], d[3];
                wvol_iso_hit h;
                size_t px = (size_t)row * (size_t)img->width + (size_t)x;
                int a;
                wvol_error e2;
                wvol_camera_ray(cam, x + 0.5, row + 0.5, o, d);
                memset(&h, 0, sizeof h);
                if (!failed && wvol__cast(c, &w, o, d, tmin, &h, &e2) != WVOL_OK) {
#pragma omp critical(wvol_iso_cast_err)
                    if (!failed) {
                        failed = 1;
                        first_err = e2;
                    }
                }
                if (depth) depth[px] = h.hit ? (float)h.t : INFINITY;
                if (normals)
                    for (a = 0; a < 3; a++) normals[3 * px + a] = h.hit ? (float)h.normal[a] : 0.0f;
                hits += (size_t)h.hit;
                wvol__iso_shade(img->rgba + 4 * px, &h, d, p->light, p->color, p->ambient);
            }
        }
        cells += w.cells;
        build += w.seconds_build;
        wvol__cast_ws_free(&w);
    }
    if (failed) {
        wvol__caster_destroy(c);
        if (err) *err = first_err;
        return first_err.status ? first_err.status : WVOL_ERR_INTERNAL;
    }
    if (st) {
        size_t b, cnt[3] = {0, 0, 0};
        memset(st, 0, sizeof *st);
        st->rays = (size_t)img->width * (size_t)img->height;
        st->hits = hits;
        st->cells_tested = cells;
        wvol__caster_counts(c, &st->bricks_total, &st->bricks_bound, &st->bricks_built, &st->bytes);
        st->seconds_bounds = t_bounds;
        st->seconds_build = build;
        st->threads = nth;
        if (c->fbound) { /* the model bound over the bricks built */
            size_t nfin = 0;
            double sum = 0.0;
            for (b = 0; b < c->nbricks; b++) {
                double e = c->fbound[b];
                if (isnan(e)) continue;
                if (isinf(e)) {
                    st->fhat_bound_faces++;
                    continue;
                }
                nfin++;
                sum += e;
                if (e > st->fhat_bound_max) st->fhat_bound_max = e;
            }
            st->fhat_bound_bricks = nfin;
            st->fhat_bound_mean = nfin ? sum / (double)nfin : 0.0;
        }
        st->cpu_seconds = wvol__cpu_now() - c_start;
        if (hits == 0) {
            for (b = 0; b < c->nbricks; b++) cnt[c->bcls[b] + 1]++;
            if (c->nbricks && (cnt[1] == c->nbricks || cnt[2] == c->nbricks))
                snprintf(st->message, sizeof st->message,
                         "iso-value %.9g is %s every sample (%s): empty image", iso,
                         cnt[1] == c->nbricks ? "above" : "at or below",
                         c->vol ? "the volume's samples" : "rigorous bounds of the reconstruction");
            else
                snprintf(st->message, sizeof st->message, "no ray meets the surface interp = %.9g: empty image", iso);
        }
        st->seconds = wvol__now() - t_start;
    }
    wvol__caster_destroy(c);
    return WVOL_OK;
}
