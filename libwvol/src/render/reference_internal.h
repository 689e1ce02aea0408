/* SPDX-License-Identifier: MIT
 * The reference integrator's private pieces shared by its sources in this folder (ref_*.c;
 * not installed): trilinear views, the transfer-function and exponential tables, the ray's
 * compositing state, the ray walk (ref_walk.c, whose sample loops are ref_samples.h), the
 * brick schedule (ref_bricks.c) and the tile loop (ref_tiles.c). What runs per sample is
 * inline here or in ref_samples.h, so that the walk's copies of its loops keep the mode,
 * shading and colour tests compiled away and the compositing state in registers; what
 * crosses files is called per run of samples, per ray or per tile. */
#ifndef WVOL_REFERENCE_INTERNAL_H
#define WVOL_REFERENCE_INTERNAL_H

#include "render_internal.h"

#include <math.h>
#include <stdint.h>

/* ---- trilinear views (ref_view.c) ------------------------------------------------------- */

/* Clamped to the view's voxel range per axis (the volume's edge voxels for a whole volume). */
double wvol__trilinear_slow(const wvol__view *w, const double x[3]);

/* Trilinear sample at x known to lie strictly inside the view's voxel range (the caller
 * checked; for a run of samples, its first and last positions: x is linear in t, so every
 * one between). In single precision, from float voxels: the sample carries a relative
 * rounding of a few 1e-8 (samples near a voxel value's zero crossing, a few 1e-8 of the
 * neighbours' values), far below the step's own error, and saves the eight conversions
 * to double. */
static inline double trilinear_in(const wvol__view *w, const double x[3])
{
    long i = (long)x[0], j = (long)x[1], k = (long)x[2];
    float wx = (float)(x[0] - (double)i), wy = (float)(x[1] - (double)j), wz = (float)(x[2] - (double)k);
    size_t sy = w->sy, sz = w->sz;
    const float *p = w->data + (size_t)(i - w->off[0]) + sy * (size_t)(j - w->off[1]) + sz * (size_t)(k - w->off[2]);
    float c00 = p[0] + wx * (p[1] - p[0]);
    float c10 = p[sy] + wx * (p[sy + 1] - p[sy]);
    float c01 = p[sz] + wx * (p[sz + 1] - p[sz]);
    float c11 = p[sz + sy] + wx * (p[sz + sy + 1] - p[sz + sy]);
    float c0 = c00 + wy * (c10 - c00), c1 = c01 + wy * (c11 - c01);
    return (double)(c0 + wz * (c1 - c0));
}

static inline int strictly_inside(const wvol__view *w, const double x[3])
{
    return x[0] > w->flo[0] && x[1] > w->flo[1] && x[2] > w->flo[2] && x[0] < w->fhi[0] && x[1] < w->fhi[1] &&
           x[2] < w->fhi[2];
}

/* Trilinear sample at index position x from a view; the common case (strictly inside the
 * view's voxel range) without clamping branches. */
static inline double trilinear(const wvol__view *w, const double x[3])
{
    if (x[0] > w->flo[0] && x[1] > w->flo[1] && x[2] > w->flo[2] && x[0] < w->fhi[0] && x[1] < w->fhi[1] &&
        x[2] < w->fhi[2])
        return trilinear_in(w, x);
    return wvol__trilinear_slow(w, x);
}

/* The dense source (ref_view.c): a whole volume through one view (s->whole), with a min/max
 * brick grid when params->reference.brick > 0. The walk reads its table inline (ref_walk.c, ray_skip)
 * rather than call its fetch once per run of a few samples. */
typedef struct wvol__dense_src {
    const wvol_volume *v;
    double *rate;           /* per brick: wvol__brick_rate of its voxels' min/max (prepare) */
} wvol__dense_src;

extern const wvol__source_ops wvol__dense_ops;

/* ---- the transfer-function and exponential tables (ref_tables.c) -------------------------- */

/* The TF prepared for the inner loop: per segment [v[i], v[i+1]) the colour and kappa at
 * its start and their slopes (no division per sample); constant beyond the end points.
 * grey: every point has the same colour (rgb), so the colour is that everywhere. */
typedef struct tf_fast {
    int n, grey;
    double rgb[3];
    double v[WVOL_TF_MAX_POINTS];
    double c0[WVOL_TF_MAX_POINTS][4], dc[WVOL_TF_MAX_POINTS][4]; /* r, g, b, kappa */
    float vf[WVOL_TF_MAX_POINTS], kf0[WVOL_TF_MAX_POINTS], kfd[WVOL_TF_MAX_POINTS]; /* v, kappa's c0, dc */
    /* the largest float at or below the first point's value when kappa is 0 there (so 0 for
     * every value up to it), else -INFINITY: a float sample at or below it has kappa 0 */
    float v_clear;
    double exp2_256[256];                                          /* 2^(j/256), for exp_neg */
} tf_fast;

void wvol__tf_fast_init(tf_fast *f, const wvol_tf *tf);

/* Colour and kappa at val; *seg is the segment found last (values along a ray change
 * little from one sample to the next), -1 below the first point. */
static inline void tf_fast_eval(const tf_fast *f, double val, int *seg, double rgb[3], double *kappa)
{
    int i = *seg, n = f->n, c;
    double w;
    if (!(i >= 0 && val >= f->v[i] && val < f->v[i + 1])) { /* not the last segment (the common case) */
        if (!(val > f->v[0])) { /* also NaN */
            for (c = 0; c < 3; c++) rgb[c] = f->c0[0][c];
            *kappa = f->c0[0][3];
            return;
        }
        if (val >= f->v[n - 1]) {
            for (c = 0; c < 3; c++) rgb[c] = f->c0[n - 1][c];
            *kappa = f->c0[n - 1][3];
            return;
        }
        int lo = 0, hi = n - 1;
        while (hi - lo > 1) {
            int mid = (lo + hi) / 2;
            if (f->v[mid] <= val) lo = mid;
            else hi = mid;
        }
        i = *seg = lo;
    }
    w = val - f->v[i];
    for (c = 0; c < 3; c++) rgb[c] = f->c0[i][c] + w * f->dc[i][c];
    *kappa = f->c0[i][3] + w * f->dc[i][3];
}

/* exp(x) for x <= 0, inlined for the inner loop: x = (256 m + j) ln2/256 + r with |r| <=
 * ln2/512 (ln2/256 split in two parts, Cody-Waite), e^x = 2^m 2^(j/256) e^r, 2^(j/256)
 * from the table (tf_fast) and e^r by its Taylor series to degree 4 (truncation below
 * 0.00136^5/5! ~ 4e-17), evaluated in Estrin's scheme: the dependency chain is a few
 * operations long, so samples overlap in the pipeline (Horner's chain would serialise them).
 * Relative error a few ulp;
 * 0 below -708 (where the result would be subnormal). */
#define EXP_K 369.32993046757463 /* 256 / ln2 */
/* ln2 / 256 in two parts: fdlibm's ln2_hi (low bits zero, so n * c_hi is exact) and ln2_lo,
 * both divided by 256 (exact) */
#define EXP_C_HI (6.93147180369123816490e-01 / 256)
#define EXP_C_LO (1.90821492927058770002e-10 / 256)
/* 1.5 2^52: adding it rounds x k (|x k| < 2^31) to an integer held in the low bits of the
 * sum's mantissa, shorter than a conversion to integer and back */
#define EXP_SHIFTER 6755399441055744.0

static inline double exp_neg(double x, const double *exp2_256)
{
    const double k = EXP_K, c_hi = EXP_C_HI, c_lo = EXP_C_LO, shifter = EXP_SHIFTER;
    double n, r, r2, p;
    long long ni;
    union {
        double d;
        unsigned long long u;
    } sc, nr;
    if (!(x > -708.0)) return 0.0; /* also NaN: an opaque step */
    nr.d = x * k + shifter;
    n = nr.d - shifter;
    ni = (long long)(int)(unsigned)(nr.u & 0xffffffffu); /* two's complement low 32 bits */
    r = (x - n * c_hi) - n * c_lo;
    r2 = r * r;
    p = (1.0 + r) + r2 * ((0.5 + r * (1.0 / 6.0)) + r2 * (1.0 / 24.0));
    sc.u = (unsigned long long)((ni >> 8) + 1023) << 52; /* arithmetic shift: floor(n / 256) */
    return p * exp2_256[ni & 255] * sc.d;
}

/* ---- one ray (ref_walk.c) ------------------------------------------------------------------ */

/* The compositing state of one ray. */
typedef struct ray_acc {
    double T, acc[3], xr;
    double od;            /* optical depth the one-colour path summed and T and acc do not yet
                             hold (acc_settle): one exponential per ray instead of per run */
    double T_lim, od_lim; /* run_blocked's one-colour limit (grey_limit) and the T it holds for */
    double vprev, hprev, sprev; /* pre-integration: the last sample's value, step and shade */
    int seg, nclamp;
    int have_prev;        /* pre-integration: vprev holds a sample whose segment to the next
                             sample is not yet composited */
} ray_acc;

/* T and the colour brought up to date with the optical depth od the one-colour path summed
 * (run_blocked): the colour of those samples, sum_l T_l alpha_l c, is c (T - T exp(-od))
 * (T_l+1 = T_l (1 - alpha_l)). Called before anything else reads or changes T. */
static inline __attribute__((always_inline)) void acc_settle(const tf_fast *tfx, ray_acc *r)
{
    if (r->od > 0) {
        const double Tn = r->T * exp_neg(-r->od, tfx->exp2_256);
        for (int c = 0; c < 3; c++) r->acc[c] += tfx->rgb[c] * (r->T - Tn);
        if (r->T_lim == r->T) { /* the limit follows T: less what was spent */
            r->od_lim -= r->od;
            r->T_lim = Tn;
        }
        r->T = Tn;
        r->od = 0.0;
    }
}

/* ---- pre-integration (preint.c) ------------------------------------------------------------ */

/* Composites, front to back into r, the segment of length len (world units) along which the
 * scalar goes linearly from a to b, its emission times shade: the exact emission-absorption
 * integral of the piecewise-linear TF, split at every TF knot crossed (optical depth exact,
 * emission up to a quadrature of relative ~1e-9). NaN-free for len >= 0 and any kappa. */
void wvol__preint_segment(const tf_fast *f, double a, double b, double len, double shade, ray_acc *r);

/* Pre-integrated sampling (wvol_render_params.preintegrate): sample k (value v, step h)
 * composites the segment from the previous sample, of length (h_prev + h) / 2, or, with no
 * previous sample (the ray's first, or the first after a skipped run), the constant v over
 * the front half of its step; preint_close composites the back half of the last sample's
 * step as a constant (the ray's end, or before a skipped run). So each step is covered once,
 * and a ray with no skipped run is the integral of the piecewise-linear interpolant of its
 * samples (constant over the first and last half steps). */
static inline void preint_sample(const tf_fast *f, double v, double h, double shade, ray_acc *r)
{
    if (r->have_prev) wvol__preint_segment(f, r->vprev, v, 0.5 * (r->hprev + h), shade, r);
    else wvol__preint_segment(f, v, v, 0.5 * h, shade, r);
    r->vprev = v, r->hprev = h, r->sprev = shade, r->have_prev = 1;
}

static inline void preint_close(const tf_fast *f, ray_acc *r)
{
    if (r->have_prev) wvol__preint_segment(f, r->vprev, r->vprev, 0.5 * r->hprev, r->sprev, r);
    r->have_prev = 0;
}

/* One ray's walk, resumable: samples at the midpoints of steps of dt over [t0, t1], front
 * to back, in runs of full steps, one run per brick crossed (ray_advance), then the last,
 * shorter step (ray_last). A dense source's view is the whole volume; a bricked source's
 * is fetched (through the thread's context) at the start of each run, so no view is held
 * from one run to the next: other rays' fetches may evict it meanwhile (render_tile_bricked). */
typedef struct ray_state {
    double x0[3], e[3];         /* start and direction in index units (world direction: ray_dir) */
    double t0, t1, t_exit;      /* the ray's interval; where it leaves its current brick */
    long k, nsteps, nfull;      /* next step; steps; full steps (ending by t1) */
    long bid;                   /* the current brick (bricked sources), -1 before the first */
    int32_t bc[3];              /* its coordinates in the brick grid */
    int pixel;                  /* index of its pixel in the tile (here, in the padding before r,
                                   so that the state is 256 bytes: four cache lines in the tile's
                                   array, aligned to 64 by ref_tiles.c) */
    ray_acc r;
    size_t nsamp;
    uint32_t nskip, nskip_tol;  /* runs skipped: at most the bricks the ray crosses */
    double skipped;             /* optical depth (X-ray: integral) skipped so far, bounded */
    int done;                   /* ray terminated */
    wvol_status failed;         /* a bricked source's fetch failed */
} ray_state;

void wvol__ray_begin(const wvol__source *s, const double o[3], const double d[3], double t0, double t1, double dt,
                     ray_state *st);
/* One run: the full steps of the ray in its next brick (all of them without a grid); 1 while
 * full steps remain. */
int wvol__ray_advance_any(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                          ray_state *st);
/* The last step, shorter than dt, once; its counters stay in st. */
void wvol__ray_last(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                    ray_state *st);
/* The brick holding the ray's next sample, entered; -1 when it has none left. */
long wvol__ray_next_brick(const wvol__source *s, ray_state *st, double dt);
/* The ray's pixel. */
void wvol__ray_pixel(const wvol_render_params *p, const ray_state *st, float px[4]);

/* ---- a pixel's ray (for the tile loop, ref_tiles.c, and the brick schedule) ----------------- */

/* The ray of pixel (x, y): its origin, direction and span in the volume; 0 when it misses
 * the volume. */
static inline int pixel_span(const wvol__cam *k, const double lo[3], const double hi[3], int x, int y, double o[3],
                             double d[3], double *t0, double *t1)
{
    wvol__cam_ray(k, x + 0.5, y + 0.5, o, d);
    if (!wvol__ray_box(o, d, lo, hi, t0, t1)) return 0;
    if (k->c.projection == WVOL_PROJECTION_PERSPECTIVE && *t0 < 0) *t0 = 0;
    return *t1 > *t0;
}

/* The ray of pixel (x, y) into *st, its pixel cleared; 0 when it misses the volume. */
static inline int pixel_ray(const wvol__source *s, const wvol__cam *k, const wvol_image *img, const double lo[3],
                            const double hi[3], double dt, int x, int y, ray_state *st)
{
    double o[3], d[3], t0, t1;
    float *px = img->rgba + 4 * ((size_t)x + (size_t)img->width * (size_t)y);
    px[0] = px[1] = px[2] = px[3] = 0.0f;
    if (!pixel_span(k, lo, hi, x, y, o, d, &t0, &t1)) return 0;
    wvol__ray_begin(s, o, d, t0, t1, dt, st);
    return 1;
}

/* ---- the brick schedule (ref_bricks.c) ------------------------------------------------------ */

/* The order in which a tile's rays walk the bricks (render_tile_bricked). Along a ray the
 * brick coordinate on each axis moves one way only (positions x0 + t e with t increasing,
 * the coordinate computed by monotone operations, ray_enter): away from the eye's brick for
 * a perspective camera (every ray starts at the eye, t >= 0), in the direction's sign for
 * parallel rays; and it moves by at most one brick from one sample to the next when the
 * step is shorter than a brick (a run skipped ends at the first step past the brick; a
 * longer step may jump a brick, and walk_brick then walks the ray on at once). So a ray
 * leaves a brick only for an *outward neighbour* (outward_step): each
 * coordinate the same or one step on. The relation has no cycle (the sum of the distances
 * in bricks from the start grows along it), so the bricks can be taken in an order in which
 * each comes after its *inward* neighbours (those of which it is an outward neighbour): by
 * then no ray can join its list any more. */
typedef struct brick_order {
    size_t n;
    long bn[3], eye[3], dir[3]; /* grid; the eye's brick and dir 2 (perspective), or the
                                   direction's signs (parallel rays) */
    uint8_t *inward;   /* per brick: its inward neighbours in the grid (at most 7) */
    uint8_t *pending;  /* per brick, during a tile: inward neighbours not yet walked */
    uint32_t *ready;   /* the bricks whose inward neighbours are walked, not yet taken */
    size_t nready, ndone;
} brick_order;

wvol_status wvol__brick_order_make(brick_order *bo, const wvol__source *s, const wvol__cam *k, wvol_error *err);
void wvol__brick_order_free(brick_order *bo);
/* A walker of bo's order for a thread walking tiles of its own: its own pending counts and
 * ready stack, bo's inward counts shared (read only); freed by wvol__brick_order_walker_free
 * (before bo is freed). WVOL_ERR_NOMEM when out of memory. */
wvol_status wvol__brick_order_walker(brick_order *w, const brick_order *bo);
void wvol__brick_order_walker_free(brick_order *w);
/* A barrier for the threads of one parallel region that waits without spinning for long
 * (ref_bricks.c, idle_wait): OpenMP's own barriers spin (libgomp: GOMP_SPINCOUNT, 300 000
 * by default), which on a machine with fewer free cores than threads burns the core the
 * late thread needs. */
typedef struct walk_sync {
    int n;              /* threads */
    int count;          /* arrived in this round */
    int round;          /* rounds completed */
} walk_sync;

void wvol__walk_sync_wait(walk_sync *w);

/* The rays of the tile (x0, y0, tw, th) walked brick by brick front to back by the calling
 * thread (its source context tc), number tid of the nt threads that share the tile, every one
 * of which calls it for the same tile (it synchronises them through w, whose n is nt); nt = 1
 * (tid 0): the tile is the caller's alone, bo, head, next and the buffers its own. rs receives
 * the tile's rays that meet the volume (row_first[th] of them), complete when it returns;
 * span: scratch of 2 tw th doubles (each pixel's ray span, for the threads sharing a tile;
 * NULL with nt = 1). */
void wvol__render_tile_bricked(const wvol__source *s, void *tc, const wvol__cam *k, wvol_image *img,
                               const double lo[3], const double hi[3], int x0, int y0, int tw, int th,
                               const tf_fast *tfx, const wvol_render_params *p, double dt, ray_state *rs,
                               int32_t *row_first, double *span, brick_order *bo, int32_t *head, int32_t *next,
                               int tid, int nt, walk_sync *w);

#endif
