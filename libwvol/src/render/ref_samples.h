/* SPDX-License-Identifier: MIT
 * The reference integrator's sample loops (included by ref_walk.c only; not installed): one
 * sample (step), a run of samples in one view (run), and its SIMD form for runs without
 * shading or colour volume (run_blocked), every one inlined into the walk's copies of its
 * loop. */
#ifndef WVOL_REF_SAMPLES_H
#define WVOL_REF_SAMPLES_H

#include "reference_internal.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* Value at index position x; world gradient into grad when not NULL. */
static inline double sample_at(const wvol__source *s, const wvol__view *w, const double x[3], double grad[3])
{
    if (!s->ops->eval) {
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
        double g[3], val = s->ops->eval(s->ctx, x, grad ? g : NULL);
        if (grad) {
            int a;
            for (a = 0; a < 3; a++) grad[a] = g[a] / s->spacing[a];
        }
        return val;
    }
}

/* The colour volume's RGB at the voxel nearest to index position x (clamped to the grid):
 * nearest rather than trilinear so that segmented classes keep their own colours. */
static inline void nearest_color(const wvol__source *s, const float *colors, const double x[3], double rgb[3])
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

/* One sample at index position x for a step of length h: returns 1 when the ray
 * terminates. `inside`: x is known to be strictly inside the view (no clamping). */
static inline __attribute__((always_inline)) int step(const wvol__source *s, const wvol__view *view,
                                                      const tf_fast *tfx, const wvol_render_params *p,
                                                      const wvol_render_mode mode, const int shading,
                                                      const int colors, const int inside, const double x[3],
                                                      const double d[3],
                                                      double h, ray_acc *r)
{
    double val, grad[3], rgb[3], kappa;
    val = inside ? trilinear_in(view, x) : sample_at(s, view, x, NULL);
    if (mode == WVOL_RENDER_MODE_XRAY) {
        r->xr += val * h;
        return 0;
    }
    if (mode == WVOL_RENDER_MODE_ABSORPTION && p->preintegrate) { /* checked: absorption, no colour volume */
        double shade = 1.0;
        if (shading) {
            sample_at(s, view->grad ? view->grad : view, x, grad);
            shade = wvol__shade(grad, d, p->ambient);
        }
        acc_settle(tfx, r);
        preint_sample(tfx, val, h, shade, r);
        return r->T < p->termination;
    }
    tf_fast_eval(tfx, val, &r->seg, rgb, &kappa);
    if (kappa > 0) {
        double alpha, shade = 1.0;
        acc_settle(tfx, r);
        int a;
        if (colors) nearest_color(s, p->colors, x, rgb);
        if (mode == WVOL_RENDER_MODE_ABSORPTION) {
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
            sample_at(s, view->grad ? view->grad : view, x, grad);
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
/* Transfer functions of at most this many points take run_blocked's branch-free segment count
 * (one comparison per point and lane pair); longer ones the search lane by lane. */
#define TF_COUNTED 16

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
 * sample's long chain (addresses, eight loads, interpolation, transfer function,
 * exponential, and for a dense volume cache misses) ends before the next can start beyond
 * what the out-of-order window holds; here the block's chains overlap. (Plain loops over the
 * lanes are not enough: the compiler's vectorisation gathers voxels one float at a time.)
 * On a dense view each operation is step's, lane-wise (IEEE, same order, no fused
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
    const int grey = tfx->grey && mode == WVOL_RENDER_MODE_ABSORPTION;
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
        if (mode != WVOL_RENDER_MODE_XRAY &&
            _mm_movemask_ps(_mm_and_ps(_mm_cmple_ps(vq[0], _mm_set1_ps(tfx->v_clear)),
                                       _mm_cmple_ps(vq[1], _mm_set1_ps(tfx->v_clear)))) == 15)
            /* every sample at or below the first TF point, where kappa is 0 (the lanes past
             * nb repeat the last sample): each would composite with alpha 0, leaving T and
             * the colour exactly as they are, so the block is a no-op (the samples of a
             * sub-cell that its few voxels above the threshold keep from being skipped) */
            continue;
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
        if (mode == WVOL_RENDER_MODE_XRAY) {
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
        } else if (tfx->n >= 2 && tfx->n <= TF_COUNTED) {
            /* the block's samples in several segments (noisy data around a knot): each lane's
             * segment without a branch, the count of the points 1 .. n - 1 at or below its
             * value (the largest i with v_i <= value, what tf_fast_eval's search finds;
             * NaN and values below the first point count 0, values from the last point on
             * n - 1, whose slopes are 0), then tf_fast_eval's c0 + w dc with w = max(value
             * - v_i, 0), exactly its numbers. The search lane by lane mispredicted its
             * branches there. */
            __m128i cnt[RUN_BLOCK / 2];
            for (pr = 0; pr < RUN_BLOCK / 2; pr++) cnt[pr] = _mm_setzero_si128();
            for (int j = 1; j < tfx->n; j++) {
                const __m128d vj = _mm_set1_pd(tfx->v[j]);
                for (pr = 0; pr < RUN_BLOCK / 2; pr++) /* a true lane is all ones: -1 */
                    cnt[pr] = _mm_sub_epi64(cnt[pr], _mm_castpd_si128(_mm_cmpge_pd(_mm_loadu_pd(val + 2 * pr), vj)));
            }
            for (pr = 0; pr < RUN_BLOCK / 2; pr++) {
                const int s0 = _mm_cvtsi128_si32(cnt[pr]), s1 = _mm_cvtsi128_si32(_mm_srli_si128(cnt[pr], 8));
                const __m128d zero = _mm_setzero_pd();
                const __m128d w0 = _mm_max_sd(_mm_set_sd(val[2 * pr] - tfx->v[s0]), zero);
                const __m128d w1 = _mm_max_sd(_mm_set_sd(val[2 * pr + 1] - tfx->v[s1]), zero);
                const __m128d ww0 = _mm_unpacklo_pd(w0, w0), ww1 = _mm_unpacklo_pd(w1, w1);
                __m128d rg0 = _mm_add_pd(_mm_loadu_pd(tfx->c0[s0]), _mm_mul_pd(ww0, _mm_loadu_pd(tfx->dc[s0])));
                __m128d bk0 = _mm_add_pd(_mm_loadu_pd(tfx->c0[s0] + 2), _mm_mul_pd(ww0, _mm_loadu_pd(tfx->dc[s0] + 2)));
                __m128d rg1 = _mm_add_pd(_mm_loadu_pd(tfx->c0[s1]), _mm_mul_pd(ww1, _mm_loadu_pd(tfx->dc[s1])));
                __m128d bk1 = _mm_add_pd(_mm_loadu_pd(tfx->c0[s1] + 2), _mm_mul_pd(ww1, _mm_loadu_pd(tfx->dc[s1] + 2)));
                _mm_storeu_pd(rgb[0] + 2 * pr, _mm_unpacklo_pd(rg0, rg1));
                _mm_storeu_pd(rgb[1] + 2 * pr, _mm_unpackhi_pd(rg0, rg1));
                _mm_storeu_pd(rgb[2] + 2 * pr, _mm_unpacklo_pd(bk0, bk1));
                _mm_storeu_pd(kappa + 2 * pr, _mm_unpackhi_pd(bk0, bk1));
                if (pr == (nb - 1) / 2) /* the last sample's segment, as the next block's guess */
                    r->seg = (nb - 1) & 1 ? s1 : s0;
            }
            if (r->seg > tfx->n - 2) r->seg = tfx->n - 2; /* a segment's index: at most n - 2 */
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
        if (mode == WVOL_RENDER_MODE_ABSORPTION) {
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
                if (mode != WVOL_RENDER_MODE_ABSORPTION) {
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
static inline __attribute__((always_inline)) int run(const wvol__source *s, const wvol__view *view,
                                                     const tf_fast *tfx, const wvol_render_params *p,
                                                     const wvol_render_mode mode, const int shading,
                                                     const int colors, const int inside, const double x0[3],
                                                     const double e[3], const double d[3], double t0, double dt,
                                                     long *k, long ke, ray_acc *r)
{
    long kk;
#if defined(__SSE2__)
    if (inside && !shading && !colors && !p->preintegrate && view->blocked_ok && run_blocked(view, tfx, p, mode, x0, e, t0, dt, k, ke, r))
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

#endif
