/* SPDX-License-Identifier: MIT
 * Reference integrator (paper eq 33): front-to-back compositing of samples taken at a
 * regular step along each ray, with step-corrected opacity alpha = 1 - exp(-kappa dt)
 * (or the linearised kappa dt in absorption-linear mode), early ray termination and
 * skipping over a min/max brick grid (bricks that add nothing, and within
 * params->skip_tolerance those that add little: ray_skip). Samples are trilinear
 * interpolation of the voxels, or f^ through the spline tables (the converged reference
 * of the spline model).
 * Based on: Levoy 1988 (ray casting); Max 1995 (optical models); DESIGN.md section 8. */
#include "render_internal.h"

#include <math.h>
#include <stdint.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>
#include <omp.h>



static double trilinear_slow(const wvol__view *w, const double x[3]);

static inline double trilinear_in(const wvol__view *w, const double x[3]);

/* Trilinear sample at index position x from a view; the common case (strictly inside the
 * view's voxel range) without clamping branches. */
static inline double trilinear(const wvol__view *w, const double x[3])
{
    if (x[0] > w->flo[0] && x[1] > w->flo[1] && x[2] > w->flo[2] && x[0] < w->fhi[0] && x[1] < w->fhi[1] &&
        x[2] < w->fhi[2])
        return trilinear_in(w, x);
    return trilinear_slow(w, x);
}

/* Clamped to the view's voxel range per axis (the volume's edge voxels for a whole volume). */
static double trilinear_slow(const wvol__view *w, const double x[3])
{
    size_t i0[3], i1[3];
    double wt[3];
    int a;
    for (a = 0; a < 3; a++) {
        double xa = x[a], f;
        long lo = w->lo[a], hi = w->hi[a];
        if (hi == lo || !(xa > (double)lo)) { /* also NaN */
            i0[a] = i1[a] = (size_t)(lo - w->off[a]);
            wt[a] = 0;
            continue;
        }
        if (xa >= (double)hi) {
            i0[a] = i1[a] = (size_t)(hi - w->off[a]);
            wt[a] = 0;
            continue;
        }
        f = floor(xa);
        i0[a] = (size_t)((long)f - w->off[a]);
        i1[a] = i0[a] + 1;
        wt[a] = xa - f;
    }
    {
        const float *d = w->data;
        size_t sy = w->sy, sz = w->sz;
        size_t b00 = i0[1] * sy + i0[2] * sz, b10 = i1[1] * sy + i0[2] * sz, b01 = i0[1] * sy + i1[2] * sz,
               b11 = i1[1] * sy + i1[2] * sz;
        double c00 = d[b00 + i0[0]] + wt[0] * (d[b00 + i1[0]] - d[b00 + i0[0]]);
        double c10 = d[b10 + i0[0]] + wt[0] * (d[b10 + i1[0]] - d[b10 + i0[0]]);
        double c01 = d[b01 + i0[0]] + wt[0] * (d[b01 + i1[0]] - d[b01 + i0[0]]);
        double c11 = d[b11 + i0[0]] + wt[0] * (d[b11 + i1[0]] - d[b11 + i0[0]]);
        double c0 = c00 + wt[1] * (c10 - c00), c1 = c01 + wt[1] * (c11 - c01);
        return c0 + wt[2] * (c1 - c0);
    }
}

/* Value at index position x; world gradient into grad when not NULL. */
static double sample_at(const wvol__sampler *s, const wvol__view *w, const double x[3], double grad[3])
{
    if (!s->eval) {
        double val = trilinear(w, x);
        if (grad) {
            int a;
            for (a = 0; a < 3; a++) {
                double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
                xp[a] += 0.5;
                xm[a] -= 0.5;
                grad[a] = (trilinear(w, xp) - trilinear(w, xm)) / s->spacing[a];
            }
        }
        return val;
    } else {
        double g[3], val = s->eval(s->ctx, x, grad ? g : NULL);
        if (grad) {
            int a;
            for (a = 0; a < 3; a++) grad[a] = g[a] / s->spacing[a];
        }
        return val;
    }
}

/* The colour volume's RGB at the voxel nearest to index position x (clamped to the grid):
 * nearest rather than trilinear so that segmented classes keep their own colours. */
static void nearest_color(const wvol__sampler *s, const float *colors, const double x[3], double rgb[3])
{
    size_t i[3], off;
    int a;
    for (a = 0; a < 3; a++) {
        double r = floor(x[a] + 0.5);
        i[a] = r > 0 ? (size_t)r : 0;
        if (i[a] > s->n[a] - 1) i[a] = s->n[a] - 1;
    }
    off = 3 * (i[0] + s->n[0] * (i[1] + s->n[1] * i[2]));
    for (a = 0; a < 3; a++) rgb[a] = colors[off + (size_t)a];
}

/* Largest kappa of the TF over [lo, hi] (piecewise linear: endpoints and knots inside). */
static double tf_max_kappa(const wvol_tf *tf, double lo, double hi)
{
    double k, m;
    int i;
    wvol_tf_eval(tf, lo, NULL, &m);
    wvol_tf_eval(tf, hi, NULL, &k);
    if (k > m) m = k;
    for (i = 0; i < tf->count; i++)
        if (tf->points[i].value > lo && tf->points[i].value < hi && tf->points[i].opacity > m) m = tf->points[i].opacity;
    return m;
}

void wvol__view_finish(wvol__view *w)
{
    for (int a = 0; a < 3; a++) {
        w->flo[a] = (double)w->lo[a];
        w->fhi[a] = (double)w->hi[a];
    }
    /* run_blocked's voxel offsets and coordinates are 32-bit */
    w->blocked_ok = (double)w->sz * (double)(w->hi[2] - w->off[2] + 1) < 2147483647.0 && w->hi[0] < INT32_MAX &&
                    w->hi[1] < INT32_MAX && w->hi[2] < INT32_MAX;
    w->local = 0;
}

double wvol__brick_rate(const wvol_tf *tf, wvol_render_mode mode, double mn, double mx)
{
    if (mode == WVOL_MODE_XRAY) return fmax(fabs(mn), fabs(mx));
    return fmax(tf_max_kappa(tf, mn, mx), 0.0);
}

/* Each brick's contribution rate (wvol__brick_rate), 0 where its samples cannot contribute.
 * Each brick covers the voxel cells [b*B - 1/2, (b+1)*B - 1/2) and its min/max is taken
 * over voxels b*B-1 .. (b+1)*B, every voxel a trilinear sample inside the brick can touch. */
static wvol_status build_bricks(wvol__sampler *s, const wvol_tf *tf, wvol_render_mode mode, wvol_error *err)
{
    const wvol_volume *v = s->v;
    size_t bi, bj, bk, nb;
    int a, B = s->B;
    for (a = 0; a < 3; a++) s->bn[a] = (s->n[a] + (size_t)B - 1) / (size_t)B;
    nb = s->bn[0] * s->bn[1] * s->bn[2];
    s->rate = malloc(nb * sizeof *s->rate);
    WVOL_RETURN_IF(!s->rate, err, WVOL_ERR_NOMEM, "render: out of memory for %zu bricks", nb);
    for (bk = 0; bk < s->bn[2]; bk++)
        for (bj = 0; bj < s->bn[1]; bj++)
            for (bi = 0; bi < s->bn[0]; bi++) {
                size_t lo[3], hi[3], b[3] = {bi, bj, bk}, i, j, k;
                double mn = INFINITY, mx = -INFINITY;
                for (a = 0; a < 3; a++) {
                    lo[a] = b[a] * (size_t)B;
                    lo[a] = lo[a] > 0 ? lo[a] - 1 : 0;
                    hi[a] = (b[a] + 1) * (size_t)B + 1;
                    if (hi[a] > s->n[a]) hi[a] = s->n[a];
                }
                for (k = lo[2]; k < hi[2]; k++)
                    for (j = lo[1]; j < hi[1]; j++) {
                        const float *row = v->data + v->nx * (j + v->ny * k);
                        for (i = lo[0]; i < hi[0]; i++) {
                            if (row[i] < mn) mn = row[i];
                            if (row[i] > mx) mx = row[i];
                        }
                    }
                s->rate[bi + s->bn[0] * (bj + s->bn[1] * bk)] = wvol__brick_rate(tf, mode, mn, mx);
            }
    return WVOL_OK;
}

/* The TF prepared for the inner loop: per segment [v[i], v[i+1]) the colour and kappa at
 * its start and their slopes (no division per sample); constant beyond the end points.
 * grey: every point has the same colour (rgb), so the colour is that everywhere. */
typedef struct tf_fast {
    int n, grey;
    double rgb[3];
    double v[WVOL_TF_MAX_POINTS];
    double c0[WVOL_TF_MAX_POINTS][4], dc[WVOL_TF_MAX_POINTS][4]; /* r, g, b, kappa */
    float vf[WVOL_TF_MAX_POINTS], kf0[WVOL_TF_MAX_POINTS], kfd[WVOL_TF_MAX_POINTS]; /* v, kappa's c0, dc */
    double exp2_256[256];                                          /* 2^(j/256), for exp_neg */
} tf_fast;

static void tf_fast_init(tf_fast *f, const wvol_tf *tf)
{
    int i, c;
    f->n = tf->count;
    f->grey = tf->count > 0;
    for (c = 0; c < 3; c++) f->rgb[c] = tf->count > 0 ? tf->points[0].rgb[c] : 0.0;
    for (i = 0; i < 256; i++) f->exp2_256[i] = exp2(i / 256.0);
    for (i = 0; i < tf->count; i++) {
        const wvol_tf_point *p = &tf->points[i], *q = i + 1 < tf->count ? p + 1 : p;
        double span = q->value - p->value;
        f->v[i] = p->value;
        f->vf[i] = (float)p->value;
        for (c = 0; c < 4; c++) {
            double a = c < 3 ? p->rgb[c] : p->opacity, b = c < 3 ? q->rgb[c] : q->opacity;
            f->c0[i][c] = a;
            f->dc[i][c] = span > 0 ? (b - a) / span : 0.0;
            if (c < 3 && a != f->rgb[c]) f->grey = 0;
        }
        f->kf0[i] = (float)f->c0[i][3];
        f->kfd[i] = (float)f->dc[i][3];
    }
}

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
 * operations long, so samples overlap in the pipeline (Horner's chain made the exponential
 * a third of a step; the 32-entry table it had needed degree 6). Relative error a few ulp;
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

/* The compositing state of one ray. */
typedef struct ray_acc {
    double T, acc[3], xr;
    double od;            /* optical depth the one-colour path summed and T and acc do not yet
                             hold (acc_settle): one exponential per ray instead of per run */
    double T_lim, od_lim; /* run_blocked's one-colour limit (grey_limit) and the T it holds for */
    int seg, nclamp;
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

/* One sample at index position x for a step of length h: returns 1 when the ray
 * terminates. `inside`: x is known to be strictly inside the view (no clamping). */
static inline __attribute__((always_inline)) int step(const wvol__sampler *s, const wvol__view *view,
                                                      const tf_fast *tfx, const wvol_render_params *p,
                                                      const wvol_render_mode mode, const int shading,
                                                      const int colors, const int inside, const double x[3],
                                                      const double d[3],
                                                      double h, ray_acc *r)
{
    double val, grad[3], rgb[3], kappa;
    val = inside ? trilinear_in(view, x) : sample_at(s, view, x, NULL);
    if (mode == WVOL_MODE_XRAY) {
        r->xr += val * h;
        return 0;
    }
    tf_fast_eval(tfx, val, &r->seg, rgb, &kappa);
    if (kappa > 0) {
        double alpha, shade = 1.0;
        acc_settle(tfx, r);
        int a;
        if (colors) nearest_color(s, p->colors, x, rgb);
        if (mode == WVOL_MODE_ABSORPTION) {
            alpha = 1.0 - exp_neg(-kappa * h, tfx->exp2_256); /* not expm1: the difference is far below the
                                                  step's own error */
        } else {
            alpha = kappa * h;
            if (alpha > 1) {
                alpha = 1;
                r->nclamp++;
            }
        }
        if (shading) {
            sample_at(s, view, x, grad);
            shade = wvol__shade(grad, d, p->ambient);
        }
        for (a = 0; a < 3; a++) r->acc[a] += r->T * alpha * rgb[a] * shade;
        r->T *= 1.0 - alpha;
        if (r->T < p->termination) return 1;
    }
    return 0;
}

/* Samples per block of the blocked loop (run_blocked). */
#define RUN_BLOCK 8

#if defined(__SSE2__)
/* A block's sample positions: per lane its voxel's offset in the view's data and its
 * trilinear weights (two quads of lanes). Exact: t = t0 + ((kk + l) + 0.5) dt and x = x0 + t e
 * in double as step() computes them, lanes past nb repeating the last sample. */
static inline __attribute__((always_inline)) void block_positions(const wvol__view *view, const double x0[3],
                                                                  const double e[3], double t0, double dt, long kk,
                                                                  int nb, int32_t idx[RUN_BLOCK], __m128 w[3][2])
{
    const __m128d vt0 = _mm_set1_pd(t0), vdt = _mm_set1_pd(dt), half = _mm_set1_pd(0.5);
    const __m128d syd = _mm_set1_pd((double)view->sy), szd = _mm_set1_pd((double)view->sz);
    const __m128d kd = _mm_set1_pd((double)kk);
    double lanes[RUN_BLOCK];
    for (int l = 0; l < RUN_BLOCK; l++) lanes[l] = l < nb ? l : nb - 1;
#pragma GCC unroll 4
    for (int pr = 0; pr < RUN_BLOCK / 2; pr++) {
        /* t = t0 + ((kk + l) + 0.5) dt; the voxel's integer coordinates in double */
        __m128d t = _mm_add_pd(vt0, _mm_mul_pd(_mm_add_pd(_mm_add_pd(kd, _mm_loadu_pd(lanes + 2 * pr)), half), vdt));
        __m128d off = _mm_setzero_pd();
#pragma GCC unroll 3
        for (int a = 0; a < 3; a++) {
            __m128d x = _mm_add_pd(_mm_set1_pd(x0[a]), _mm_mul_pd(t, _mm_set1_pd(e[a])));
            __m128d fi = _mm_cvtepi32_pd(_mm_cvttpd_epi32(x)), rel = _mm_sub_pd(fi, _mm_set1_pd((double)view->off[a]));
            __m128 px = _mm_cvtpd_ps(_mm_sub_pd(x, fi));
            off = a == 0 ? rel : _mm_add_pd(off, _mm_mul_pd(a == 1 ? syd : szd, rel));
            w[a][pr / 2] = pr & 1 ? _mm_movelh_ps(w[a][pr / 2], px) : px;
        }
        _mm_storel_epi64((__m128i *)(void *)(idx + 2 * pr), _mm_cvttpd_epi32(off));
    }
}

/* The same for a brick's small view (view->local: extents of 1 to 127 voxel cells), in
 * single precision relative to the view: the block's first position in double, x - off,
 * rounded to float (below 128: within 4e-6 voxel), then x_l = x + l (dt e) four lanes per
 * operation, and the offsets as floats (exact: a brick has far fewer than 2^24 voxels). A
 * third of the exact version's operations. Each coordinate is clamped to the view's range,
 * as the clamping path (trilinear_slow) clamps it: the samples in a face's outer half voxel,
 * where a ray enters or leaves the volume, are taken here too, and no read leaves the
 * brick. */
static inline __attribute__((always_inline)) void block_positions_local(const wvol__view *view, const double x0[3],
                                                                        const double e[3], double t0, double dt,
                                                                        long kk, int nb, int32_t idx[RUN_BLOCK],
                                                                        __m128 w[3][2])
{
    const double t = t0 + ((double)kk + 0.5) * dt;
    __m128 lane[2] = {_mm_setr_ps(0, 1, 2, 3), _mm_setr_ps(4, 5, 6, 7)}, off[2] = {_mm_setzero_ps(), _mm_setzero_ps()};
    if (nb < RUN_BLOCK) {
        const __m128 last = _mm_set1_ps((float)(nb - 1));
        lane[0] = _mm_min_ps(lane[0], last);
        lane[1] = _mm_min_ps(lane[1], last);
    }
#pragma GCC unroll 3
    for (int a = 0; a < 3; a++) {
        const __m128 xs = _mm_set1_ps((float)(x0[a] + t * e[a] - (double)view->off[a]));
        const __m128 dx = _mm_set1_ps((float)(dt * e[a]));
        const __m128 cell_max = _mm_set1_ps((float)(view->hi[a] - view->off[a] - 1));
        const __m128 x_max = _mm_set1_ps((float)(view->hi[a] - view->off[a])), zero = _mm_setzero_ps();
        const __m128 stride = _mm_set1_ps(a == 0 ? 1.0f : (float)(a == 1 ? view->sy : view->sz));
#pragma GCC unroll 2
        for (int h = 0; h < 2; h++) {
            __m128 x = _mm_min_ps(_mm_max_ps(_mm_add_ps(xs, _mm_mul_ps(lane[h], dx)), zero), x_max);
            __m128 fi = _mm_min_ps(_mm_cvtepi32_ps(_mm_cvttps_epi32(x)), cell_max);
            w[a][h] = _mm_sub_ps(x, fi);
            off[h] = _mm_add_ps(off[h], _mm_mul_ps(fi, stride));
        }
    }
    _mm_storeu_si128((__m128i *)(void *)idx, _mm_cvttps_epi32(off[0]));
    _mm_storeu_si128((__m128i *)(void *)(idx + 4), _mm_cvttps_epi32(off[1]));
}

/* A block's trilinear samples, four lanes per float operation (two quads; a block of at
 * most 4 samples interpolates one, and the second repeats it): a voxel row's two neighbours
 * along x as one 64-bit load, two shuffles turning four lanes' pairs into the four low and
 * the four high neighbours. rows: the offsets of the rows (j, k), (j + 1, k), (j, k + 1),
 * (j + 1, k + 1). The loops here and in the positions are unrolled by request: in
 * ray_advance_any's many inlined copies GCC stopped unrolling them on its own, and the
 * sums went through memory. */
static inline __attribute__((always_inline)) void block_values(const float *data, const size_t rows[4],
                                                               const int32_t idx[RUN_BLOCK], __m128 w[3][2], int nb,
                                                               __m128 vq[2])
{
#pragma GCC unroll 2
    for (int qd = 0; qd < 2; qd++) {
        if (qd == 1 && nb <= 4) {
            vq[1] = vq[0];
            break;
        }
        const float *qa = data + idx[4 * qd], *qb = data + idx[4 * qd + 1], *qc = data + idx[4 * qd + 2],
                    *qe = data + idx[4 * qd + 3];
        __m128 lo[4], c0, c1;
#pragma GCC unroll 4
        for (int row = 0; row < 4; row++) {
            size_t o = rows[row];
            __m128 ab = _mm_loadh_pi(_mm_loadl_pi(_mm_setzero_ps(), (const __m64 *)(const void *)(qa + o)),
                                     (const __m64 *)(const void *)(qb + o));
            __m128 ce = _mm_loadh_pi(_mm_loadl_pi(_mm_setzero_ps(), (const __m64 *)(const void *)(qc + o)),
                                     (const __m64 *)(const void *)(qe + o));
            __m128 p0 = _mm_shuffle_ps(ab, ce, _MM_SHUFFLE(2, 0, 2, 0)); /* the voxels at i */
            __m128 p1 = _mm_shuffle_ps(ab, ce, _MM_SHUFFLE(3, 1, 3, 1)); /* and at i + 1 */
            lo[row] = _mm_add_ps(p0, _mm_mul_ps(w[0][qd], _mm_sub_ps(p1, p0)));
        }
        c0 = _mm_add_ps(lo[0], _mm_mul_ps(w[1][qd], _mm_sub_ps(lo[1], lo[0])));
        c1 = _mm_add_ps(lo[2], _mm_mul_ps(w[1][qd], _mm_sub_ps(lo[3], lo[2])));
        vq[qd] = _mm_add_ps(c0, _mm_mul_ps(w[2][qd], _mm_sub_ps(c1, c0)));
    }
}

/* run_blocked's one-colour path: the optical depth ln(T / term) that T, now T, may lose
 * before it falls to the termination threshold, less a relative 1e-9 (the rounding of log,
 * of the exponentials and of the subtractions in acc_settle is far below that); -1 when T is
 * already below it. Kept in the ray's state with the T it holds for, so that a T only the
 * one-colour path changed takes no logarithm (acc_settle keeps it up to date). */
static inline __attribute__((always_inline)) double grey_limit(ray_acc *r, double term)
{
    if (r->T != r->T_lim) {
        r->T_lim = r->T;
        r->od_lim = r->T > term ? log(r->T / term) * (1.0 - 1e-9) : -1.0;
    }
    return r->od_lim;
}

/* Full steps *k .. ke - 1 of a ray inside one view (strictly inside it, or anywhere in a
 * brick's view, whose positions are clamped to it), without shading or colour volume, in blocks of RUN_BLOCK samples computed lane-parallel in SSE2 (every x86-64 has
 * it): the block's positions, voxel offsets and trilinear weights (block_positions, two
 * lanes per double operation; block_positions_local for a brick, four per float operation);
 * a voxel row's two neighbours along x as one 64-bit load, two shuffles turning four lanes'
 * pairs into the four low and the four high neighbours, so the interpolation runs four
 * lanes per float operation; the transfer function and the exponential two lanes per
 * operation (the table read as two loads); then the compositing, sample by sample (the only
 * dependency from one sample to the next), or for a one-colour TF in absorption mode only
 * the sum of kappa (one exponential per ray: acc_settle). Sample by sample (step), each
 * sample's chain (about 140 instructions: addresses, eight loads, interpolation, transfer
 * function, exponential, and for a dense volume cache misses) ended before the next could
 * start beyond what the out-of-order window holds; here the block's chains overlap. (Written as plain loops over
 * the lanes, the compiler's vectorisation gathered voxels one float at a time and converted
 * lane by lane, ~190 instructions a sample; GCC's generic 8-lane vector types did no
 * better.) On a dense view each operation is step's, lane-wise (IEEE, same order, no fused
 * multiply-add on baseline x86-64), so the transmittance is the same bit for bit, and so is
 * every channel but with the one-colour shortcut (the same integral, rounded differently, its
 * kappa in single precision),
 * which the tests check against the per-sample path; voxel offsets are computed in double,
 * exact below 2^53, and the view must have fewer than 2^31 voxels (view->blocked_ok). A
 * short last block fills its spare lanes with samples of its own (the positions repeat the
 * last sample; of at most 4 samples only the first quad is interpolated, and the second
 * repeats it), which are read but never composited. Returns 1 when the ray
 * terminates, *k then the terminating step. Other targets take the per-sample loop. */
static inline __attribute__((always_inline)) int run_blocked(const wvol__view *view, const tf_fast *tfx,
                                                             const wvol_render_params *p,
                                                             const wvol_render_mode mode, const double x0[3],
                                                             const double e[3], double t0, double dt, long *k,
                                                             long ke, ray_acc *r)
{
    const double term = p->termination;
    const int grey = tfx->grey && mode == WVOL_MODE_ABSORPTION;
    const __m128d vdt = _mm_set1_pd(dt), half = _mm_set1_pd(0.5);
    const float *data = view->data;
    const size_t sy = view->sy, sz = view->sz, rows[4] = {0, sy, sz, sz + sy};
    /* one colour: the run's optical depth / dt (added to r->od when the run ends), and the
     * most it may reach before T could fall below the threshold (a hair short of it, so that
     * the rounding of log and exp cannot carry T below it unchecked) */
    double od_run = 0.0, od_lim = 0.0;
    long kk;
    /* the positions of block n + 1 are computed while block n's voxels load (pos[cur ^ 1]):
     * they head each block's chain of dependent operations (positions, offsets, loads,
     * interpolation, kappa, sum), which is longer than the out-of-order window reaches from
     * one block into the next */
    int32_t idx[2][RUN_BLOCK];
    __m128 w[2][3][2];
    int cur = 0;
#define POSITIONS(kb, slot)                                                                                   \
    do {                                                                                                      \
        const int nb_ = ke - (kb) < RUN_BLOCK ? (int)(ke - (kb)) : RUN_BLOCK;                                 \
        if (view->local) block_positions_local(view, x0, e, t0, dt, (kb), nb_, idx[slot], w[slot]);           \
        else block_positions(view, x0, e, t0, dt, (kb), nb_, idx[slot], w[slot]);                             \
    } while (0)
    if (grey) od_lim = (grey_limit(r, term) - r->od) / dt;
    if (*k < ke) POSITIONS(*k, 0);
    for (kk = *k; kk < ke; kk += RUN_BLOCK, cur ^= 1) {
        int l, pr, nb = ke - kk < RUN_BLOCK ? (int)(ke - kk) : RUN_BLOCK, seg = r->seg, sg, same;
        double val[RUN_BLOCK], kappa[RUN_BLOCK], alpha[RUN_BLOCK], rgb[3][RUN_BLOCK];
        __m128 vq[2];
        block_values(data, rows, idx[cur], w[cur], nb, vq);
        if (kk + RUN_BLOCK < ke) POSITIONS(kk + RUN_BLOCK, cur ^ 1);
        if (grey && tfx->n >= 2) {
            /* one colour: only the block's sum of kappa counts; when every sample lies in the
             * current segment (as below), kappa four lanes per float operation (a relative
             * rounding of a few 1e-8, against the double path's; the tests' one-colour bound
             * is 2e-6), lanes past nb dropped */
            const int sf = r->seg < 0 ? 0 : r->seg;
            const __m128 f0 = _mm_set1_ps(tfx->vf[sf]), f1 = _mm_set1_ps(tfx->vf[sf + 1]);
            __m128 in0 = _mm_cmplt_ps(vq[0], f1), in1 = _mm_cmplt_ps(vq[1], f1);
            if (sf > 0) {
                in0 = _mm_and_ps(in0, _mm_cmpge_ps(vq[0], f0));
                in1 = _mm_and_ps(in1, _mm_cmpge_ps(vq[1], f0));
            }
            if (_mm_movemask_ps(_mm_and_ps(in0, in1)) == 15) {
                const __m128 zero = _mm_setzero_ps(), k0 = _mm_set1_ps(tfx->kf0[sf]), dk = _mm_set1_ps(tfx->kfd[sf]);
                __m128 ka = _mm_max_ps(_mm_add_ps(k0, _mm_mul_ps(_mm_max_ps(_mm_sub_ps(vq[0], f0), zero), dk)), zero);
                __m128 kb = _mm_max_ps(_mm_add_ps(k0, _mm_mul_ps(_mm_max_ps(_mm_sub_ps(vq[1], f0), zero), dk)), zero);
                __m128 sum;
                double od;
                if (nb < RUN_BLOCK) {
                    const __m128 n = _mm_set1_ps((float)nb);
                    ka = _mm_and_ps(ka, _mm_cmplt_ps(_mm_setr_ps(0, 1, 2, 3), n));
                    kb = _mm_and_ps(kb, _mm_cmplt_ps(_mm_setr_ps(4, 5, 6, 7), n));
                }
                sum = _mm_add_ps(ka, kb);
                sum = _mm_add_ps(sum, _mm_movehl_ps(sum, sum));
                od = (double)_mm_cvtss_f32(_mm_add_ss(sum, _mm_shuffle_ps(sum, sum, 1)));
                if (od_run + od <= od_lim) {
                    od_run += od;
                    continue;
                }
                /* else: the double path below, sample by sample */
            }
        }
        for (int qd = 0; qd < 2; qd++) {
            _mm_storeu_pd(val + 4 * qd, _mm_cvtps_pd(vq[qd]));
            _mm_storeu_pd(val + 4 * qd + 2, _mm_cvtps_pd(_mm_movehl_ps(vq[qd], vq[qd])));
        }
        if (mode == WVOL_MODE_XRAY) {
            for (l = 0; l < nb; l++) r->xr += val[l] * dt;
            continue;
        }
        /* the transfer function: every sample in the current segment (the common case; for
         * the first segment, or before any, also below the first point, where the TF is the
         * first point's: w clamped to 0 gives exactly that, c0 + 0 dc = c0, so that a ray
         * through a haze of values around the first point stays on this path), or one by
         * one */
        sg = seg < 0 ? 0 : seg;
        same = tfx->n >= 2;
        if (same) {
            const __m128d v0 = _mm_set1_pd(tfx->v[sg]), v1 = _mm_set1_pd(tfx->v[sg + 1]);
            for (pr = 0; pr < RUN_BLOCK / 2; pr++) {
                __m128d v = _mm_loadu_pd(val + 2 * pr), in = _mm_cmplt_pd(v, v1);
                if (sg > 0) in = _mm_and_pd(in, _mm_cmpge_pd(v, v0));
                same &= _mm_movemask_pd(in) == 3;
            }
        }
        if (same) {
            const double *cs = tfx->c0[sg], *dc = tfx->dc[sg];
            const __m128d v0 = _mm_set1_pd(tfx->v[sg]), zero = _mm_setzero_pd();
            const __m128d c0r = _mm_set1_pd(cs[0]), c0g = _mm_set1_pd(cs[1]), c0b = _mm_set1_pd(cs[2]),
                          c0k = _mm_set1_pd(cs[3]), dcr = _mm_set1_pd(dc[0]), dcg = _mm_set1_pd(dc[1]),
                          dcb = _mm_set1_pd(dc[2]), dck = _mm_set1_pd(dc[3]);
            for (pr = 0; pr < RUN_BLOCK / 2; pr++) {
                __m128d w = _mm_max_pd(_mm_sub_pd(_mm_loadu_pd(val + 2 * pr), v0), zero);
                _mm_storeu_pd(kappa + 2 * pr, _mm_add_pd(c0k, _mm_mul_pd(w, dck)));
                if (grey) continue; /* the colours are filled below, if at all */
                _mm_storeu_pd(rgb[0] + 2 * pr, _mm_add_pd(c0r, _mm_mul_pd(w, dcr)));
                _mm_storeu_pd(rgb[1] + 2 * pr, _mm_add_pd(c0g, _mm_mul_pd(w, dcg)));
                _mm_storeu_pd(rgb[2] + 2 * pr, _mm_add_pd(c0b, _mm_mul_pd(w, dcb)));
            }
        } else {
            for (l = 0; l < RUN_BLOCK; l++) { /* the spare lanes too: every lane is read below */
                double c[3];
                tf_fast_eval(tfx, val[l], &r->seg, c, &kappa[l]);
                rgb[0][l] = c[0], rgb[1][l] = c[1], rgb[2][l] = c[2];
            }
        }
        if (grey) {
            /* One colour c: the colour of samples a .. b, sum_l T_l alpha_l c, is c (T_a - T_b)
             * (T_l+1 = T_l (1 - alpha_l)), and T_b = T_a exp(-dt sum_l kappa_l): the blocks only
             * sum kappa, and one exponential per ray (acc_settle) gives T and the colour. The
             * same integral (the step-corrected opacities' product), rounded differently (a
             * few ulp of double). A block whose sum would pass od_lim is composited sample by
             * sample below (T first brought up to date), to stop at the sample where T falls
             * below the threshold. */
            double od = 0.0;
            if (nb == RUN_BLOCK) { /* a tree of lane sums: a short dependency chain */
                const __m128d zero = _mm_setzero_pd(); /* max(kappa, 0): kappa <= 0 or NaN adds 0 */
                __m128d s01 = _mm_add_pd(_mm_max_pd(_mm_loadu_pd(kappa), zero), _mm_max_pd(_mm_loadu_pd(kappa + 2), zero));
                __m128d s23 = _mm_add_pd(_mm_max_pd(_mm_loadu_pd(kappa + 4), zero), _mm_max_pd(_mm_loadu_pd(kappa + 6), zero));
                __m128d sum = _mm_add_pd(s01, s23);
                od = _mm_cvtsd_f64(_mm_add_sd(sum, _mm_unpackhi_pd(sum, sum)));
            } else {
                for (l = 0; l < nb; l++) od += kappa[l] > 0 ? kappa[l] : 0.0;
            }
            if (od_run + od <= od_lim) {
                od_run += od;
                continue;
            }
            r->od += od_run * dt;
            acc_settle(tfx, r);
            od_run = 0.0;
            for (l = 0; l < RUN_BLOCK; l++) rgb[0][l] = tfx->rgb[0], rgb[1][l] = tfx->rgb[1], rgb[2][l] = tfx->rgb[2];
        }
        if (mode == WVOL_MODE_ABSORPTION) {
            /* alpha = 1 - exp_neg(-kappa dt), exp_neg's operations two lanes at a time */
            const __m128d kexp = _mm_set1_pd(EXP_K), shifter = _mm_set1_pd(EXP_SHIFTER);
            const __m128d c_hi = _mm_set1_pd(EXP_C_HI), c_lo = _mm_set1_pd(EXP_C_LO);
            const __m128d one = _mm_set1_pd(1.0), sixth = _mm_set1_pd(1.0 / 6.0), p24 = _mm_set1_pd(1.0 / 24.0),
                          lim = _mm_set1_pd(-708.0), sign = _mm_set1_pd(-0.0);
            const __m128i bias = _mm_set1_epi32(1023);
            for (pr = 0; pr < RUN_BLOCK / 2; pr++) {
                /* -kappa dt: the negation is exact, so (-kappa) dt = -(kappa dt) */
                __m128d x = _mm_xor_pd(_mm_mul_pd(_mm_loadu_pd(kappa + 2 * pr), vdt), sign);
                __m128d nrd = _mm_add_pd(_mm_mul_pd(x, kexp), shifter), n = _mm_sub_pd(nrd, shifter);
                __m128i ni = _mm_castpd_si128(nrd); /* each lane's low 32 bits: the rounded x k */
                __m128d rr = _mm_sub_pd(_mm_sub_pd(x, _mm_mul_pd(n, c_hi)), _mm_mul_pd(n, c_lo));
                __m128d r2 = _mm_mul_pd(rr, rr);
                __m128d pp = _mm_add_pd(_mm_add_pd(one, rr),
                                        _mm_mul_pd(r2, _mm_add_pd(_mm_add_pd(half, _mm_mul_pd(rr, sixth)),
                                                                  _mm_mul_pd(r2, p24))));
                /* 2^floor(n / 256): the biased exponent in the low 12 bits of the low half,
                 * shifted to bits 52..63 (the high half shifted out) */
                __m128d sc = _mm_castsi128_pd(_mm_slli_epi64(_mm_add_epi32(_mm_srai_epi32(ni, 8), bias), 52));
                int n0 = _mm_cvtsi128_si32(ni), n1 = _mm_cvtsi128_si32(_mm_srli_si128(ni, 8));
                __m128d tab = _mm_set_pd(tfx->exp2_256[n1 & 255], tfx->exp2_256[n0 & 255]);
                __m128d ev = _mm_and_pd(_mm_mul_pd(_mm_mul_pd(pp, tab), sc), _mm_cmpgt_pd(x, lim));
                _mm_storeu_pd(alpha + 2 * pr, _mm_sub_pd(one, ev));
            }
        } else {
            for (pr = 0; pr < RUN_BLOCK / 2; pr++)
                _mm_storeu_pd(alpha + 2 * pr, _mm_mul_pd(_mm_loadu_pd(kappa + 2 * pr), vdt));
        }
        {
            /* the compositing, branch-free where step branches: a sample with kappa <= 0
             * (or NaN) composites with alpha 0, which leaves T and the colour exactly as
             * they were (acc + T 0 c = acc, T (1 - 0) = T); absorption-linear clamps
             * alpha to 1 and counts the clamps of the samples composited (up to the one
             * that terminates the ray) */
            const __m128d zero = _mm_setzero_pd(), one = _mm_set1_pd(1.0);
            double om[RUN_BLOCK], T = r->T, a0 = r->acc[0], a1 = r->acc[1], a2 = r->acc[2];
            unsigned clamps = 0; /* bit l: sample l clamped */
            for (pr = 0; pr < RUN_BLOCK / 2; pr++) {
                __m128d al = _mm_loadu_pd(alpha + 2 * pr), live = _mm_cmpgt_pd(_mm_loadu_pd(kappa + 2 * pr), zero);
                if (mode != WVOL_MODE_ABSORPTION) {
                    __m128d over = _mm_and_pd(_mm_cmpgt_pd(al, one), live);
                    clamps |= (unsigned)_mm_movemask_pd(over) << (2 * pr);
                    al = _mm_or_pd(_mm_andnot_pd(over, al), _mm_and_pd(over, one));
                }
                al = _mm_and_pd(al, live);
                _mm_storeu_pd(alpha + 2 * pr, al);
                _mm_storeu_pd(om + 2 * pr, _mm_sub_pd(one, al));
            }
            for (l = 0; l < nb; l++) {
                double ta = T * alpha[l];
                a0 += ta * rgb[0][l];
                a1 += ta * rgb[1][l];
                a2 += ta * rgb[2][l];
                T *= om[l];
                if (T < term) break;
            }
            r->T = T, r->acc[0] = a0, r->acc[1] = a1, r->acc[2] = a2;
            if (clamps) r->nclamp += __builtin_popcount(clamps & ((2u << (l < nb ? l : nb - 1)) - 1));
            if (l < nb) {
                *k = kk + l;
                return 1;
            }
            if (grey) od_lim = grey_limit(r, term) / dt; /* on from the sample-by-sample block's T */
        }
    }
    if (grey) r->od += od_run * dt;
    *k = ke;
    return 0;
#undef POSITIONS
}
#endif

/* Full steps *k .. ke - 1 of a ray, all in one view (`inside`: strictly inside it); returns 1
 * when the ray terminates, *k then the terminating step. */
static inline __attribute__((always_inline)) int run(const wvol__sampler *s, const wvol__view *view,
                                                     const tf_fast *tfx, const wvol_render_params *p,
                                                     const wvol_render_mode mode, const int shading,
                                                     const int colors, const int inside, const double x0[3],
                                                     const double e[3], const double d[3], double t0, double dt,
                                                     long *k, long ke, ray_acc *r)
{
    long kk;
#if defined(__SSE2__)
    if (inside && !shading && !colors && view->blocked_ok && run_blocked(view, tfx, p, mode, x0, e, t0, dt, k, ke, r))
        return 1;
#endif
    for (kk = *k; kk < ke; kk++) {
        double t = t0 + ((double)kk + 0.5) * dt, x[3];
        for (int a = 0; a < 3; a++) x[a] = x0[a] + t * e[a];
        if (step(s, view, tfx, p, mode, shading, colors, inside, x, d, dt, r)) {
            *k = kk;
            return 1;
        }
    }
    *k = ke;
    return 0;
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
    ray_acc r;
    size_t nsamp;
    uint32_t nskip, nskip_tol;  /* runs skipped: at most the bricks the ray crosses */
    double skipped;             /* optical depth (X-ray: integral) skipped so far, bounded */
    int done;                   /* ray terminated */
    wvol_status failed;         /* a bricked source's fetch failed */
    int pixel;                  /* index of its pixel in the tile */
} ray_state;

/* The ray's world direction, for shading (a tile's rays are held for the whole walk, so
 * their states are kept small): e times the spacing, the direction to an ulp. */
static inline void ray_dir(const wvol__sampler *s, const ray_state *st, double d[3])
{
    for (int a = 0; a < 3; a++) d[a] = st->e[a] * s->spacing[a];
}

static void ray_begin(const wvol__sampler *s, const double o[3], const double d[3], double t0, double t1, double dt,
                      ray_state *st)
{
    memset(st, 0, sizeof *st);
    for (int a = 0; a < 3; a++) {
        st->x0[a] = (o[a] - s->origin[a]) / s->spacing[a];
        st->e[a] = d[a] / s->spacing[a];
    }
    st->t0 = t0, st->t1 = t1, st->t_exit = -INFINITY, st->bid = -1;
    st->r.T = 1.0, st->r.seg = -1, st->r.T_lim = -1.0;
    st->nsteps = (long)ceil((t1 - t0) / dt);
    if (st->nsteps < 1) st->nsteps = 1;
    st->nfull = st->nsteps;
    while (st->nfull > 0 && t0 + (double)st->nfull * dt > t1) st->nfull--; /* steps ending by t1 */
}

/* Enters the brick holding x (sample parameter t; clamped to the grid) when t is at or past
 * the current one's exit, and finds where the ray leaves it: per axis the face it moves
 * towards. */
static inline void ray_enter(const wvol__sampler *s, ray_state *st, const double x[3], double t)
{
    double te = INFINITY;
    long b[3];
    if (t < st->t_exit) return;
    for (int a = 0; a < 3; a++) {
        double c = (x[a] + 0.5) / s->B, lo, ta;
        b[a] = c > 0 ? (long)c : 0;
        if (b[a] > (long)s->bn[a] - 1) b[a] = (long)s->bn[a] - 1;
        lo = (double)b[a] * s->B - 0.5;
        if (st->e[a] > 0) ta = (lo + s->B - x[a]) / st->e[a];
        else if (st->e[a] < 0) ta = (lo - x[a]) / st->e[a];
        else continue;
        if (ta < te) te = ta;
    }
    st->bid = b[0] + (long)s->bn[0] * (b[1] + (long)s->bn[1] * b[2]);
    for (int a = 0; a < 3; a++) st->bc[a] = (int32_t)b[a];
    st->t_exit = t + te;
}

/* Whether the ray's next `len` world units, in its current brick, are skipped: the brick's
 * contribution rate (wvol__brick_rate) is 0, or times len it fits in what is left of the
 * ray's skip tolerance, which it then spends (st->skipped). Otherwise returns 0 with *view
 * the brick's (fetched anew each time, a cache lookup, since another ray may have evicted
 * it; a dense source keeps the whole volume's); -1 when the fetch failed. */
static inline __attribute__((always_inline)) int ray_skip(const wvol__sampler *s, void *tc, ray_state *st,
                                                          double tol, double len, const wvol__view **view)
{
    double rate, allow = tol > st->skipped ? (tol - st->skipped) / len : 0.0;
    if (s->fetch) {
        st->failed = s->fetch(tc, (size_t)st->bid, allow, view, &rate);
        if (st->failed != WVOL_OK) return -1;
    } else {
        rate = s->rate[st->bid];
    }
    if (rate > allow) return 0;
    if (rate > 0) {
        st->skipped += rate * len;
        st->nskip_tol++;
    }
    st->nskip++;
    return 1;
}

/* One run: the full steps of the ray in its next brick (all of them for an unbricked
 * source). Returns 1 while full steps remain. When a run's first and last sample lie
 * strictly inside the view its samples are taken without clamping tests (run_blocked). */
static inline __attribute__((always_inline)) int ray_advance(const wvol__sampler *s, void *tc, const tf_fast *tfx,
                                                             const wvol_render_params *p,
                                                             const wvol_render_mode mode, const int shading,
                                                             const int colors, double dt, ray_state *st)
{
    const wvol__view *view = &s->whole;
    const double t0 = st->t0, *x0 = st->x0, *e = st->e;
    long k = st->k, nfull = st->nfull, ke = nfull; /* this run: steps k .. ke - 1 */
    int a, bricked = s->rate || s->fetch, done;
    double x[3], xl[3], d[3] = {0, 0, 0}, t;
#define T_AT(kk) (t0 + ((double)(kk) + 0.5) * dt)
    if (k >= nfull || st->done || st->failed != WVOL_OK) return 0;
    t = T_AT(k);
    for (a = 0; a < 3; a++) x[a] = x0[a] + t * e[a];
    if (bricked) {
        int skip;
        ray_enter(s, st, x, t);
        /* the first step whose sample is at or past the exit */
        if (st->t_exit < T_AT(nfull)) {
            double q = (st->t_exit - t0) / dt - 0.5;
            ke = q > (double)k ? (long)q : k;
            while (ke < nfull && T_AT(ke) < st->t_exit) ke++;
            while (ke > k + 1 && !(T_AT(ke - 1) < st->t_exit)) ke--;
            if (ke <= k) ke = k + 1;
        }
        skip = ray_skip(s, tc, st, p->skip_tolerance, (double)(ke - k) * dt, &view);
        if (skip < 0) return 0;
        if (skip) {
            st->k = ke;
            return ke < nfull;
        }
    }
    st->nsamp += (size_t)(ke - k);
    if (shading) ray_dir(s, st, d);
    if (s->eval) {
        done = run(s, view, tfx, p, mode, shading, colors, 0, x0, e, d, t0, dt, &k, ke, &st->r);
#if defined(__SSE2__)
    } else if (view->local && view->blocked_ok && !shading && !colors) {
        /* a brick's view: block_positions_local clamps every position to it, so the samples
         * in a face's outer half voxel need no clamping path of their own */
        done = run_blocked(view, tfx, p, mode, x0, e, t0, dt, &k, ke, &st->r);
#endif
    } else {
        /* the steps whose samples lie strictly inside the view are an interval (x is
         * linear in t); the few outside it, where the ray enters or leaves the volume
         * through a face's outer half voxel, take the clamping path */
        long kin = k, kout = ke;
        while (kin < kout && !strictly_inside(view, x)) {
            kin++;
            for (a = 0; a < 3; a++) x[a] = x0[a] + T_AT(kin) * e[a];
        }
        for (a = 0; a < 3; a++) xl[a] = x0[a] + T_AT(kout - 1) * e[a];
        while (kout > kin && !strictly_inside(view, xl)) {
            kout--;
            for (a = 0; a < 3; a++) xl[a] = x0[a] + T_AT(kout - 1) * e[a];
        }
        done = run(s, view, tfx, p, mode, shading, colors, 0, x0, e, d, t0, dt, &k, kin, &st->r) ||
               run(s, view, tfx, p, mode, shading, colors, 1, x0, e, d, t0, dt, &k, kout, &st->r) ||
               run(s, view, tfx, p, mode, shading, colors, 0, x0, e, d, t0, dt, &k, ke, &st->r);
    }
    if (done) st->nsamp -= (size_t)(ke - k - 1); /* the samples not taken */
    st->k = k;
    st->done = done;
#undef T_AT
    return !done && k < nfull;
}

/* Where the ray's last step (shorter than dt, ending at t1) samples: 1 with its position,
 * parameter and length while the ray still has it to take. */
static int ray_last_at(const ray_state *st, double dt, double x[3], double *t, double *h)
{
    double ta;
    if (st->done || st->failed != WVOL_OK || st->nfull >= st->nsteps) return 0;
    ta = st->t0 + (double)st->nfull * dt;
    *h = st->t1 - ta;
    *t = 0.5 * (ta + st->t1);
    for (int a = 0; a < 3; a++) x[a] = st->x0[a] + *t * st->e[a];
    return *h > 0;
}

/* The last step, once; its counters stay in st. */
static void ray_last(const wvol__sampler *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                     ray_state *st)
{
    double x[3], t, h;
    const wvol__view *view = &s->whole;
    int skip = 0;
    if (!ray_last_at(st, dt, x, &t, &h)) return;
    st->nsteps = st->nfull; /* taken */
    if (s->rate || s->fetch) {
        ray_enter(s, st, x, t);
        skip = ray_skip(s, tc, st, p->skip_tolerance, h, &view);
    }
    if (!skip) {
        double d[3];
        ray_dir(s, st, d);
        st->nsamp++;
        st->done = step(s, view, tfx, p, p->mode, p->shading, p->colors != NULL, 0, x, d, h, &st->r);
    }
}

/* The ray's pixel. */
static void ray_pixel(const wvol_render_params *p, const ray_state *st, float px[4])
{
    if (p->mode == WVOL_MODE_XRAY) {
        px[0] = px[1] = px[2] = (float)st->r.xr;
        px[3] = 1.0f;
    } else {
        for (int a = 0; a < 3; a++) px[a] = (float)st->r.acc[a];
        px[3] = (float)(1.0 - st->r.T);
    }
}

/* The brick holding the ray's next sample (its next full step's, else its last step's),
 * entered (ray_enter); -1 when it has none left. */
static long ray_next_brick(const wvol__sampler *s, ray_state *st, double dt)
{
    double x[3], t, h;
    if (st->done || st->failed != WVOL_OK) return -1;
    if (st->k < st->nfull) {
        t = st->t0 + ((double)st->k + 0.5) * dt;
        for (int a = 0; a < 3; a++) x[a] = st->x0[a] + t * st->e[a];
    } else if (!ray_last_at(st, dt, x, &t, &h)) {
        return -1;
    }
    ray_enter(s, st, x, t);
    return st->bid;
}

/* ray_advance with the common cases' own copies of the loop, the mode, shading and colour
 * tests compiled away (and with them every call in the inner loop: the compositing state
 * stays in registers). */
static int ray_advance_any(const wvol__sampler *s, void *tc, const tf_fast *tfx, const wvol_render_params *p,
                           double dt, ray_state *st)
{
    if (p->mode == WVOL_MODE_ABSORPTION && !p->shading && !p->colors)
        return ray_advance(s, tc, tfx, p, WVOL_MODE_ABSORPTION, 0, 0, dt, st);
    if (p->mode == WVOL_MODE_XRAY && !p->shading) return ray_advance(s, tc, tfx, p, WVOL_MODE_XRAY, 0, 0, dt, st);
    return ray_advance(s, tc, tfx, p, p->mode, p->shading, p->colors != NULL, dt, st);
}

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

/* Whether d (-1 or +1) is an outward step from brick coordinate c along axis a: away from the
 * eye's brick (either way from it), or the direction's sign for parallel rays. */
static inline int outward_ok(const brick_order *bo, int a, long c, long d)
{
    if (bo->dir[a] == 2) return c == bo->eye[a] ? (d == 1 || d == -1) : d == (c > bo->eye[a] ? 1 : -1);
    return bo->dir[a] != 0 && d == bo->dir[a];
}

/* Whether brick `to` is an outward neighbour of brick `from` (coordinates): every axis the
 * same or one outward step, not all the same. */
static inline int outward_step(const brick_order *bo, const long from[3], const int32_t to[3])
{
    int moved = 0;
    for (int a = 0; a < 3; a++) {
        long d = (long)to[a] - from[a];
        if (!d) continue;
        if ((d != 1 && d != -1) || !outward_ok(bo, a, from[a], d)) return 0;
        moved = 1;
    }
    return moved;
}

static void brick_coords(const brick_order *bo, long b, long c[3])
{
    c[0] = b % bo->bn[0];
    c[1] = (b / bo->bn[0]) % bo->bn[1];
    c[2] = b / (bo->bn[0] * bo->bn[1]);
}

/* Runs BODY with nb set to each outward neighbour of brick b in the grid. */
#define FOR_OUTWARD(bo, b, BODY)                                                                           \
    do {                                                                                                   \
        long c_[3], n_[3];                                                                                 \
        brick_coords(bo, b, c_);                                                                           \
        for (long dz_ = -1; dz_ <= 1; dz_++)                                                               \
            for (long dy_ = -1; dy_ <= 1; dy_++)                                                           \
                for (long dx_ = -1; dx_ <= 1; dx_++) {                                                     \
                    const long d_[3] = {dx_, dy_, dz_};                                                    \
                    int ok_ = dx_ || dy_ || dz_;                                                           \
                    for (int a_ = 0; ok_ && a_ < 3; a_++) {                                                \
                        n_[a_] = c_[a_] + d_[a_];                                                          \
                        ok_ = n_[a_] >= 0 && n_[a_] < bo->bn[a_];                                          \
                        if (ok_ && d_[a_]) ok_ = outward_ok(bo, a_, c_[a_], d_[a_]);                       \
                    }                                                                                      \
                    if (ok_) {                                                                             \
                        const long nb = n_[0] + bo->bn[0] * (n_[1] + bo->bn[1] * n_[2]);                   \
                        BODY;                                                                              \
                    }                                                                                      \
                }                                                                                          \
    } while (0)

static void brick_order_free(brick_order *bo)
{
    free(bo->inward);
    free(bo->pending);
    free(bo->ready);
}

static wvol_status brick_order_make(brick_order *bo, const wvol__sampler *s, const wvol__cam *k, wvol_error *err)
{
    memset(bo, 0, sizeof *bo);
    bo->n = s->bn[0] * s->bn[1] * s->bn[2];
    WVOL_RETURN_IF(bo->n > UINT32_MAX, err, WVOL_ERR_NOMEM, "render: %zu bricks (at most 2^32: a larger brick side)",
                   bo->n);
    for (int a = 0; a < 3; a++) {
        bo->bn[a] = (long)s->bn[a];
        if (k->c.projection == WVOL_PERSPECTIVE) { /* the eye's brick, as ray_enter finds it */
            double c = ((k->c.eye[a] - s->origin[a]) / s->spacing[a] + 0.5) / s->B;
            bo->eye[a] = c > 0 ? (c < (double)s->bn[a] ? (long)c : (long)s->bn[a] - 1) : 0;
            bo->dir[a] = 2;
        } else { /* every ray's index-space direction has the sign of fwd / spacing */
            bo->dir[a] = k->fwd[a] > 0 ? 1 : k->fwd[a] < 0 ? -1 : 0;
        }
    }
    bo->inward = calloc(bo->n, sizeof *bo->inward);
    bo->pending = malloc(bo->n * sizeof *bo->pending);
    bo->ready = malloc(bo->n * sizeof *bo->ready);
    if (!bo->inward || !bo->pending || !bo->ready) {
        brick_order_free(bo);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the brick order");
    }
    for (long b = 0; b < (long)bo->n; b++) FOR_OUTWARD(bo, b, bo->inward[nb]++);
    return WVOL_OK;
}

/* The rays of one tile (n of them, in rs) of a dense source: one after the other. */
static void render_tile(const wvol__sampler *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                        ray_state *rs, int n)
{
    for (int i = 0; i < n; i++) {
        while (ray_advance_any(s, tc, tfx, p, dt, &rs[i])) continue;
        ray_last(s, tc, tfx, p, dt, &rs[i]);
        acc_settle(tfx, &rs[i].r);
    }
}

/* The ray of pixel (x, y): its origin, direction and span in the volume; 0 when it misses
 * the volume. */
static int pixel_span(const wvol__cam *k, const double lo[3], const double hi[3], int x, int y, double o[3],
                      double d[3], double *t0, double *t1)
{
    wvol__cam_ray(k, x + 0.5, y + 0.5, o, d);
    if (!wvol__ray_box(o, d, lo, hi, t0, t1)) return 0;
    if (k->c.projection == WVOL_PERSPECTIVE && *t0 < 0) *t0 = 0;
    return *t1 > *t0;
}

/* The ray of pixel (x, y) into *st, its pixel cleared; 0 when it misses the volume. */
static int pixel_ray(const wvol__sampler *s, const wvol__cam *k, const wvol_image *img, const double lo[3],
                     const double hi[3], double dt, int x, int y, ray_state *st)
{
    double o[3], d[3], t0, t1;
    float *px = img->rgba + 4 * ((size_t)x + (size_t)img->width * (size_t)y);
    px[0] = px[1] = px[2] = px[3] = 0.0f;
    if (!pixel_span(k, lo, hi, x, y, o, d, &t0, &t1)) return 0;
    ray_begin(s, o, d, t0, t1, dt, st);
    return 1;
}

/* Ray i onto brick b's list (head: per brick, -1 when empty; next: per ray); several threads
 * may push onto one list at once. */
static inline void list_push(int32_t *head, int32_t *next, long b, int32_t i)
{
    int32_t old = __atomic_load_n(&head[b], __ATOMIC_RELAXED);
    do {
        next[i] = old;
    } while (!__atomic_compare_exchange_n(&head[b], &old, i, 1, __ATOMIC_RELEASE, __ATOMIC_RELAXED));
}

/* The rays on brick b's list take their runs in it (its view fetched once, then a cache hit
 * for each) and move to the list of the brick they enter next, an outward neighbour, which is
 * walked after b (render_tile_bricked). A ray whose next brick is not one (which the geometry
 * rules out: brick_order) walks on at once: its fetch may build a brick again, and its image
 * is the same. */
static void walk_brick(const wvol__sampler *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                       ray_state *rs, const brick_order *bo, int32_t *head, int32_t *next, long b)
{
    int32_t i = head[b];
    long bc[3];
    brick_coords(bo, b, bc);
    head[b] = -1;
    while (i >= 0) {
        const int32_t after = next[i];
        ray_state *st = &rs[i];
        for (;;) {
            long nb;
            if (st->k < st->nfull) ray_advance_any(s, tc, tfx, p, dt, st);
            else ray_last(s, tc, tfx, p, dt, st);
            nb = ray_next_brick(s, st, dt);
            if (nb < 0) { /* the ray is done */
                acc_settle(tfx, &st->r);
                break;
            }
            if (outward_step(bo, bc, st->bc)) {
                list_push(head, next, nb, i);
                break;
            }
        }
        i = after;
    }
}

/* The rays of one tile of a bricked source, walked brick by brick front to back
 * (brick_order): each brick's list holds the rays whose next sample lies in it; the rays of
 * the brick at hand take their runs there and move to the list of the brick they enter next.
 * A brick is taken once its inward neighbours are walked (a count per brick; the bricks whose
 * count reaches 0 wait on a stack, taken and released under one lock, twice per brick), so
 * no ray can join its list afterwards: the tile builds each brick its rays need once, and a
 * thread's cache needs to hold one brick. The threads share the tile's bricks: a brick is
 * walked, and built, by whichever thread takes it. Each ray's own samples are taken in its
 * order, so the image is the ray-by-ray walk's, whatever the thread count.
 * Measured before: one run per ray per round with a least-recently-used cache of 8 MiB and a
 * tile per thread, 733 builds of the 391 bricks the 512^2 perspective frame of the 256^3 skull
 * needs (561 now, with 256^2 tiles); bricks dealt out in rounds of equal distance from the
 * eye's brick, with a barrier between rounds, two threads spent 7-10% more CPU time (waiting
 * at the barriers) for the same builds. */
static void render_tile_bricked(const wvol__sampler *s, const wvol__cam *k, wvol_image *img, const double lo[3],
                                const double hi[3], int x0, int y0, int tw, int th, const tf_fast *tfx,
                                const wvol_render_params *p, double dt, ray_state *rs, int32_t *row_first,
                                brick_order *bo, int32_t *head, int32_t *next, int nthreads)
{
    memcpy(bo->pending, bo->inward, bo->n * sizeof *bo->pending);
    bo->nready = bo->ndone = 0;
    for (size_t b = bo->n; b-- > 0;)
        if (!bo->inward[b]) bo->ready[bo->nready++] = (uint32_t)b;
#pragma omp parallel num_threads(nthreads)
    {
        void *tc = s->tctx[omp_get_thread_num()];
        /* the tile's rays that meet the volume, in rs row by row, each onto its first brick's
         * list: set up by the threads (serially, 5% of a two-thread frame), in two passes so
         * that they lie packed (a state per pixel would make the pages of the misses resident
         * too): each row's count, then its rays from the row's first index on */
#pragma omp for schedule(static)
        for (int y = y0; y < y0 + th; y++) {
            int32_t n = 0;
            for (int x = x0; x < x0 + tw; x++) {
                double o[3], d[3], t0, t1;
                n += pixel_span(k, lo, hi, x, y, o, d, &t0, &t1);
            }
            row_first[y - y0 + 1] = n;
        }
#pragma omp single
        {
            row_first[0] = 0;
            for (int j = 0; j < th; j++) row_first[j + 1] += row_first[j];
        }
#pragma omp for schedule(static)
        for (int y = y0; y < y0 + th; y++) {
            int32_t i = row_first[y - y0];
            for (int x = x0; x < x0 + tw; x++) {
                long b;
                if (!pixel_ray(s, k, img, lo, hi, dt, x, y, &rs[i])) continue;
                rs[i].pixel = (x - x0) + tw * (y - y0);
                b = ray_next_brick(s, &rs[i], dt);
                if (b >= 0) list_push(head, next, b, i);
                i++;
            }
        }
        for (;;) {
            long b = -1;
            int finished = 0;
#pragma omp critical(wvol_walk_ready)
            {
                if (bo->nready) b = (long)bo->ready[--bo->nready];
                else finished = bo->ndone == bo->n;
            }
            if (finished) break;
            if (b < 0) { /* the other threads hold the bricks that would free some */
#if defined(__SSE2__)
                _mm_pause();
#endif
                continue;
            }
            if (head[b] >= 0) walk_brick(s, tc, tfx, p, dt, rs, bo, head, next, b);
#pragma omp critical(wvol_walk_ready)
            {
                FOR_OUTWARD(bo, b, if (!--bo->pending[nb]) bo->ready[bo->nready++] = (uint32_t)nb);
                bo->ndone++;
            }
        }
    }
}

/* The bricked walk's tile side: the largest square whose rays (states and list links) fit
 * the bytes the source grants, evened out so that the image's tiles are alike (a tile's rays
 * build each brick they need once, render_tile_bricked: the larger the tile, the fewer
 * bricks two tiles both build); 0 without a grant. */
static int walk_tile(const wvol__sampler *s, const wvol_image *img)
{
    int side, n, big = img->width > img->height ? img->width : img->height;
    if (!s->walk_bytes) return 0;
    side = (int)sqrt((double)s->walk_bytes / (double)(sizeof(ray_state) + sizeof(int32_t)));
    if (side < 16) side = 16;
    if (side >= big) return big;
    n = (big + side - 1) / side;
    return (big + n - 1) / n;
}

/* A tile's rays (those that meet the volume) into rs; returns their count. */
static int tile_rays(const wvol__sampler *s, const wvol__cam *k, const wvol_image *img, const double lo[3],
                     const double hi[3], double dt, int x0, int y0, int tw, int th, ray_state *rs)
{
    int n = 0;
    for (int y = y0; y < y0 + th; y++)
        for (int x = x0; x < x0 + tw; x++)
            if (pixel_ray(s, k, img, lo, hi, dt, x, y, &rs[n])) rs[n++].pixel = (x - x0) + tw * (y - y0);
    return n;
}

/* A walked tile's pixels, and its rays' counts added to c; a failed fetch's status to *failed. */
static void tile_finish(const wvol_render_params *p, wvol_image *img, int x0, int y0, int tw, const ray_state *rs,
                        int n, wvol__counts *c, wvol_status *failed)
{
    for (int i = 0; i < n; i++) {
        const ray_state *st = &rs[i];
        c->rays_hit++;
        ray_pixel(p, st, img->rgba + 4 * ((size_t)(x0 + st->pixel % tw) + (size_t)img->width * (size_t)(y0 + st->pixel / tw)));
        c->samples += st->nsamp;
        c->skipped += st->nskip;
        c->skipped_tolerance += st->nskip_tol;
        if (st->skipped > c->skip_bound) c->skip_bound = st->skipped;
        c->terminated += (size_t)st->done;
        c->clamped += (size_t)st->r.nclamp;
        if (st->failed != WVOL_OK) *failed = st->failed;
    }
}

static void counts_add(wvol__counts *to, const wvol__counts *c)
{
    to->rays_hit += c->rays_hit;
    to->samples += c->samples;
    to->skipped += c->skipped;
    to->skipped_tolerance += c->skipped_tolerance;
    to->terminated += c->terminated;
    to->clamped += c->clamped;
    if (c->skip_bound > to->skip_bound) to->skip_bound = c->skip_bound;
}

wvol_status wvol__render_sampled(wvol_image *img, wvol__sampler *s, const wvol_camera *cam, const wvol_tf *tf_in,
                          const wvol_render_params *pin, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_geometry g;
    wvol_tf tf;
    tf_fast tfx;
    wvol__cam k;
    double lo[3], hi[3], dt, t_start, c_start;
    int ntiles, tx, a, *order, nthreads;
    size_t tile_rays_n;
    brick_order bo;
    wvol__counts counts;
    wvol_status status = WVOL_OK, failed = WVOL_OK;

    memset(&counts, 0, sizeof counts);
    wvol__params(&p, pin);
    WVOL_FORWARD(wvol__render_check(img, cam, tf_in, &p, err));
    WVOL_FORWARD(wvol__check_colors(&p, s->n, 1, err));
    WVOL_FORWARD(wvol__check_skip(&p, (s->v && p.reference.brick > 0) || s->prepare, err));
    for (a = 0; a < 3; a++) {
        g.dims[a] = s->n[a];
        g.spacing[a] = s->spacing[a];
        g.origin[a] = s->origin[a];
        WVOL_RETURN_IF(!(s->spacing[a] > 0) || !isfinite(s->spacing[a]) || !isfinite(s->origin[a]), err, WVOL_ERR_ARG,
                       "render: spacing and origin must be finite, spacing > 0");
    }
    if (p.mode != WVOL_MODE_XRAY) wvol__tf_world(&tf, tf_in, &g);
    else memset(&tf, 0, sizeof tf);
    tf_fast_init(&tfx, &tf);
    wvol_geometry_bounds(&g, lo, hi);
    dt = p.step * fmin(s->spacing[0], fmin(s->spacing[1], s->spacing[2]));
    t_start = wvol__now();
    c_start = wvol__cpu_now();
    s->rate = NULL;
    if (s->v && p.reference.brick > 0) {
        s->B = p.reference.brick;
        WVOL_FORWARD(build_bricks(s, &tf, p.mode, err));
    } else if (s->prepare) {
        WVOL_FORWARD(s->prepare(s, &tf, &p, err));
    }
    wvol__cam_init(&k, cam);
    p.tile = wvol__tile_side(&p, walk_tile(s, img));
    ntiles = wvol__tiles(img->width, img->height, p.tile);
    tx = (img->width + p.tile - 1) / p.tile;
    order = wvol__tile_order(img->width, img->height, p.tile);
    nthreads = wvol__threads(p.threads);
    tile_rays_n = (size_t)p.tile * (size_t)p.tile;
    memset(&bo, 0, sizeof bo);
    if (s->fetch) {
        /* the bricked walk: one tile at a time, its bricks shared by the threads */
        ray_state *rs = malloc(tile_rays_n * sizeof *rs);
        int32_t *lists = NULL; /* the bricks' list heads, then the rays' links */
        int32_t *row_first = malloc(((size_t)p.tile + 1) * sizeof *row_first);
        status = !order || !rs || !row_first ? wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for a tile's rays")
                               : brick_order_make(&bo, s, &k, err);
        if (status == WVOL_OK) {
            lists = malloc((bo.n + tile_rays_n) * sizeof *lists);
            if (!lists) status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for a tile's rays");
            else
                for (size_t b = 0; b < bo.n; b++) lists[b] = -1;
        }
        for (int ti = 0; status == WVOL_OK && ti < ntiles; ti++) {
            int x0 = (order[ti] % tx) * p.tile, y0 = (order[ti] / tx) * p.tile;
            int tw = img->width - x0 < p.tile ? img->width - x0 : p.tile;
            int th = img->height - y0 < p.tile ? img->height - y0 : p.tile;
            render_tile_bricked(s, &k, img, lo, hi, x0, y0, tw, th, &tfx, &p, dt, rs, row_first, &bo, lists, lists + bo.n,
                                nthreads);
            tile_finish(&p, img, x0, y0, tw, rs, row_first[th], &counts, &failed);
        }
        /* the walk's own: the tile's rays and lists, the order */
        counts.bytes = tile_rays_n * (sizeof *rs + sizeof *lists) + ((size_t)p.tile + 1) * sizeof *row_first +
                       bo.n * (sizeof *lists + sizeof *bo.inward + sizeof *bo.pending + sizeof *bo.ready);
        free(rs);
        free(lists);
        free(row_first);
        brick_order_free(&bo);
    } else if (!order) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory");
    } else {
        /* a dense source: tiles over the threads, in chunks of 4 Z-ordered tiles (2 x 2); each
         * thread's tile of ray states allocated once (allocated per tile, a buffer above
         * malloc's mmap threshold came back as fresh pages for the kernel to zero each time: 8%
         * of the process's profile for a 512^2 perspective frame) */
#pragma omp parallel num_threads(nthreads)
        {
            ray_state *rs = malloc(tile_rays_n * sizeof *rs);
            void *tc = s->tctx ? s->tctx[omp_get_thread_num()] : NULL;
            wvol__counts mine;
            wvol_status my_failed = rs ? WVOL_OK : WVOL_ERR_NOMEM;
            memset(&mine, 0, sizeof mine);
#pragma omp for schedule(dynamic, 4)
            for (int ti = 0; ti < ntiles; ti++) {
                int x0 = (order[ti] % tx) * p.tile, y0 = (order[ti] / tx) * p.tile, n;
                int tw = img->width - x0 < p.tile ? img->width - x0 : p.tile;
                int th = img->height - y0 < p.tile ? img->height - y0 : p.tile;
                if (!rs) continue;
                n = tile_rays(s, &k, img, lo, hi, dt, x0, y0, tw, th, rs);
                render_tile(s, tc, &tfx, &p, dt, rs, n);
                tile_finish(&p, img, x0, y0, tw, rs, n, &mine, &my_failed);
            }
#pragma omp critical(wvol_render_counts)
            {
                counts_add(&counts, &mine);
                if (my_failed != WVOL_OK) failed = my_failed;
            }
            free(rs);
        }
    }
    free(order);
    free(s->rate);
    s->rate = NULL;
    if (status != WVOL_OK) return status;
    WVOL_RETURN_IF(failed != WVOL_OK, err, failed, "render: out of memory (a brick could not be reconstructed, or a tile's rays)");
    wvol__stats_fill(stats, img, t_start, c_start, &counts);
    return WVOL_OK;
}

wvol_status wvol_render_reference(wvol_image *img, const wvol_volume *v, const wvol_camera *cam, const wvol_tf *tf,
                                  const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol__sampler s;
    int a;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "render: no volume");
    memset(&s, 0, sizeof s);
    s.v = v;
    s.n[0] = v->nx;
    s.n[1] = v->ny;
    s.n[2] = v->nz;
    s.whole.data = v->data;
    s.whole.sy = v->nx;
    s.whole.sz = v->nx * v->ny;
    for (a = 0; a < 3; a++) s.whole.hi[a] = (long)s.n[a] - 1;
    wvol__view_finish(&s.whole);
    for (a = 0; a < 3; a++) {
        s.spacing[a] = v->spacing[a];
        s.origin[a] = v->origin[a];
    }
    return wvol__render_sampled(img, &s, cam, tf, params, stats, err);
}
