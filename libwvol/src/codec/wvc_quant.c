/* SPDX-License-Identifier: MIT
 * .wvc quantiser statistics and the choice of the step: per-section sums of the
 * dead-zone quantiser's error for a step (one parallel pass, explicit vectors), and
 * the search for the largest step that meets an error target.
 * Based on: Sullivan 1996 (dead-zone uniform quantiser with centroid
 * reconstruction for Laplacian sources); Parseval for orthonormal transforms
 * (the coefficient error is the volume error, DESIGN.md section 5). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wvc_quant.h"

/* Sums over rows of one band (serial; the caller spreads work items over threads,
 * wvol__wvc_rows_stats). Q (may be NULL) receives the quantised values; with `sparse` Q is known
 * to be all zero and only groups with a non-zero are written (the pages of an
 * all-zero stretch are never touched: fresh pages cost more to write than to read).
 *
 * Most coefficients quantise to zero: a group of eight whose |c| all lie below the
 * dead zone (float test, with a margin far above rounding) only adds c^2 to the
 * zeroed energy; the others get the full arithmetic, in double. Explicit vectors
 * (AVX2 in the x86-64-v3 clone; GCC will not reorder a double reduction itself),
 * branch-free selects; counts are summed as doubles within a row (exact below
 * 2^53); the scalar tail does the same arithmetic. The file is compiled without
 * contracted multiply-adds (CMakeLists.txt): the sums and the quantised values are the
 * same whichever clone or kernel runs. */
typedef double wvc_v4d __attribute__((vector_size(32)));
typedef int64_t wvc_v4l __attribute__((vector_size(32)));
typedef int32_t wvc_v4i __attribute__((vector_size(16)));
typedef float wvc_v4f __attribute__((vector_size(16)));
typedef float wvc_v8f __attribute__((vector_size(32)));
typedef int32_t wvc_v8i __attribute__((vector_size(32)));
#define SEL(v, m) ((wvc_v4d)((wvc_v4l)(v) & (m))) /* v where the mask is set, else 0 */

typedef struct row_acc {
    wvc_v4d rz, re, r1, rr1, r2, rr2, c1, c2;
} row_acc;

/* The full arithmetic on four coefficients; writes their q when qrow is given. */
static inline __attribute__((always_inline)) void quad_stats(row_acc *A, wvc_v4f cf, double inv, double f,
                                                               int32_t *qrow, int sparse)
{
    const wvc_v4d vinv = {inv, inv, inv, inv}, vf = {f, f, f, f};
    const wvc_v4d vq = {WVC_QMAX, WVC_QMAX, WVC_QMAX, WVC_QMAX}, one = {1, 1, 1, 1}, two = {2, 2, 2, 2};
    const wvc_v4l absmask = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
    wvc_v4d c = __builtin_convertvector(cf, wvc_v4d), ac = (wvc_v4d)((wvc_v4l)c & absmask);
    wvc_v4d a = ac * vinv, tt = a + vf;
    wvc_v4l big = tt >= vq;
    /* truncation, not floor(): t >= 0; the step's lower bound keeps t < 2^30 anyway */
    tt = (wvc_v4d)(((wvc_v4l)tt & ~big) | ((wvc_v4l)vq & big));
    wvc_v4i qi = __builtin_convertvector(tt, wvc_v4i);
    wvc_v4d q = __builtin_convertvector(qi, wvc_v4d), r = a - q, cc = c * c;
    wvc_v4l is0 = q < one, is1 = q == one, is2 = q >= two;
    A->re += cc;
    A->rz += SEL(cc, is0);
    A->c1 += SEL(one, is1);
    A->r1 += SEL(r, is1);
    A->rr1 += SEL(r * r, is1);
    A->c2 += SEL(one, is2);
    A->r2 += SEL(r, is2);
    A->rr2 += SEL(r * r, is2);
    if (qrow && (!sparse || (qi[0] | qi[1] | qi[2] | qi[3]))) {
        wvc_v4i neg = cf < (wvc_v4f){0, 0, 0, 0};
        qi = (qi ^ neg) - neg;
        memcpy(qrow, &qi, sizeof qi);
    }
}

/* The end of a row, shared by the kernels: the largest |c| from the vector lanes' maxima (their
 * bits as floats) and the values from x on, then those values' arithmetic one by one (the
 * same operations as a group's, in double). */
static inline __attribute__((always_inline)) float row_end(double t[8], const float lanes[8], const float *row,
                                                            int32_t *qrow, size_t x, size_t ex, double inv, double f,
                                                            int sparse)
{
    const double qmax = WVC_QMAX;
    float m = 0.0f;
    for (int k = 0; k < 8; k++) m = lanes[k] > m ? lanes[k] : m;
    for (size_t k = x; k < ex; k++) m = fabsf(row[k]) > m ? fabsf(row[k]) : m;
    for (; x < ex; x++) {
        double c = row[x], ac = fabs(c), a = ac * inv, tt = a + f;
        double q = (double)(int32_t)(tt < qmax ? tt : qmax), r = a - q, cc = c * c;
        t[1] += cc;
        if (q == 0) t[0] += cc;
        else if (q == 1) t[2] += r, t[3] += r * r, t[6] += 1;
        else t[4] += r, t[5] += r * r, t[7] += 1;
        if (qrow && (!sparse || q != 0)) qrow[x] = c < 0 ? -(int32_t)q : (int32_t)q;
    }
    return m;
}

/* Sums of one row of n coefficients into t[8] (zeroed energy, energy, r and r^2 for
 * |q| = 1, r and r^2 for |q| >= 2, counts of |q| = 1 and |q| >= 2); qrow as in wvol__wvc_rows_stats,
 * or the row itself (every group is loaded before its q is stored, so no restrict); the
 * largest |c| into *amax when given. */
static inline __attribute__((always_inline)) void row_kernel(double t[8], float *amax, const float *row,
                                                              int32_t *qrow, size_t ex, double step, double f,
                                                              int sparse)
{
    const double inv = 1.0 / step;
    /* below this |c| / step + f < 1 for sure: the relative margin 1e-6 dwarfs float rounding */
    const float thr = (float)((1.0 - f) * step * (1.0 - 1e-6));
    const wvc_v8f vthr = {thr, thr, thr, thr, thr, thr, thr, thr};
    const wvc_v8i absmask = {INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX};
    size_t x;
    row_acc A;
    wvc_v4d zq = {0, 0, 0, 0};
    wvc_v8i vmax = {0, 0, 0, 0, 0, 0, 0, 0}; /* max |c|: as non-negative floats' bits, ordered as integers */
    memset(&A, 0, sizeof A);
    memset(t, 0, 8 * sizeof *t);
    for (x = 0; x + 8 <= ex; x += 8) {
        wvc_v8f cf;
        /* a run of all-zero groups: only their energy, in a loop of its own (with the full
         * arithmetic's accumulators live, GCC keeps zq on the stack and each group waits on
         * the previous one's store); the same operations in the same order */
        {
            wvc_v4d z = zq;
            for (; x + 8 <= ex; x += 8) {
                wvc_v8i hit;
                wvc_v4l h4;
                memcpy(&cf, row + x, sizeof cf);
                {
                    wvc_v8i ab = (wvc_v8i)cf & absmask, up = ab > vmax;
                    vmax = (ab & up) | (vmax & ~up);
                    hit = (wvc_v8f)ab >= vthr;
                }
                h4 = (wvc_v4l)hit;
                if (h4[0] | h4[1] | h4[2] | h4[3]) break;
                wvc_v4f lo = __builtin_shufflevector(cf, cf, 0, 1, 2, 3);
                wvc_v4f hi = __builtin_shufflevector(cf, cf, 4, 5, 6, 7);
                wvc_v4d dl = __builtin_convertvector(lo, wvc_v4d), dh = __builtin_convertvector(hi, wvc_v4d);
                z += dl * dl + dh * dh;
                if (qrow && !sparse) memset(qrow + x, 0, 8 * sizeof *qrow);
            }
            zq = z;
            if (x + 8 > ex) break;
        }
        {
            wvc_v4f lo = __builtin_shufflevector(cf, cf, 0, 1, 2, 3);
            wvc_v4f hi = __builtin_shufflevector(cf, cf, 4, 5, 6, 7);
            quad_stats(&A, lo, inv, f, qrow ? qrow + x : NULL, sparse);
            quad_stats(&A, hi, inv, f, qrow ? qrow + x + 4 : NULL, sparse);
        }
    }
    for (int k = 0; k < 4; k++) {
        t[0] += A.rz[k] + zq[k], t[1] += A.re[k] + zq[k], t[2] += A.r1[k], t[3] += A.rr1[k];
        t[4] += A.r2[k], t[5] += A.rr2[k], t[6] += A.c1[k], t[7] += A.c2[k];
    }
    {
        float lanes[8], m;
        memcpy(lanes, &vmax, sizeof lanes); /* the lanes' bits as floats */
        m = row_end(t, lanes, row, qrow, x, ex, inv, f, sparse);
        if (amax) *amax = m;
    }
}

#if WVOL__HAVE_V4
#include <immintrin.h>

/* acc += lo where the mask's lanes 0-3 are set, then += hi where lanes 4-7 are */
#define MADD2(acc, k, lo, hi) \
    ((acc) = _mm256_mask_add_pd((acc), (k), (acc), (lo)), \
     (acc) = _mm256_mask_add_pd((acc), (__mmask8)((k) >> 4), (acc), (hi)))

/* row_kernel for x86-64-v4 CPUs, in its intrinsics: eight coefficients per step in one
 * 512-bit vector, each accumulator's selects as masked adds. The values are row_kernel's
 * operation for operation (this file is compiled without contracted multiply-adds, so
 * neither fuses a product), and each accumulator adds the group's lower four lanes and then
 * its upper four, as row_kernel adds its two quads: the same sums, bit for bit
 * (tests/c/test_wvc.c, wvc_quant_kernels_agree). */
WVOL__TARGET_V4 static float row_kernel_v4(double t[8], const float *row, int32_t *qrow, size_t ex, double step,
                                           double f, int sparse)
{
    const double inv = 1.0 / step;
    const float thr = (float)((1.0 - f) * step * (1.0 - 1e-6));
    const __m512d vinv = _mm512_set1_pd(inv), vf = _mm512_set1_pd(f), vq = _mm512_set1_pd(WVC_QMAX);
    const __m512d one = _mm512_set1_pd(1.0), two = _mm512_set1_pd(2.0);
    const __m256 vthr = _mm256_set1_ps(thr);
    const __m256i absmask = _mm256_set1_epi32(INT32_MAX);
    const __m256d one4 = _mm256_set1_pd(1.0);
    __m256d rz = _mm256_setzero_pd(), re = rz, r1 = rz, rr1 = rz, r2 = rz, rr2 = rz, c1 = rz, c2 = rz, zq = rz;
    __m256i vmax = _mm256_setzero_si256();
    size_t x;
    float lanes[8];
    memset(t, 0, 8 * sizeof *t);
    for (x = 0; x + 8 <= ex; x += 8) {
        const __m256 cf = _mm256_loadu_ps(row + x);
        const __m256i ab = _mm256_and_si256(_mm256_castps_si256(cf), absmask);
        vmax = _mm256_max_epu32(vmax, ab);
        const __m512d c = _mm512_cvtps_pd(cf);
        if (!_mm256_cmp_ps_mask(_mm256_castsi256_ps(ab), vthr, _CMP_GE_OQ)) {
            /* a group below the dead zone: its energy only */
            const __m256d dl = _mm512_castpd512_pd256(c), dh = _mm512_extractf64x4_pd(c, 1);
            zq = _mm256_add_pd(zq, _mm256_add_pd(_mm256_mul_pd(dl, dl), _mm256_mul_pd(dh, dh)));
            if (qrow && !sparse) _mm256_storeu_si256((__m256i *)(qrow + x), _mm256_setzero_si256());
            continue;
        }
        const __m512d a = _mm512_mul_pd(_mm512_abs_pd(c), vinv);
        /* truncation, not floor(): t >= 0; min with the clamp as row_kernel's select */
        const __m512d tt = _mm512_min_pd(_mm512_add_pd(a, vf), vq);
        const __m256i qi = _mm512_cvttpd_epi32(tt);
        const __m512d q = _mm512_cvtepi32_pd(qi);
        const __m512d r = _mm512_sub_pd(a, q), cc = _mm512_mul_pd(c, c), rr = _mm512_mul_pd(r, r);
        const __mmask8 k0 = _mm512_cmp_pd_mask(q, one, _CMP_LT_OQ), k1 = _mm512_cmp_pd_mask(q, one, _CMP_EQ_OQ);
        const __mmask8 k2 = _mm512_cmp_pd_mask(q, two, _CMP_GE_OQ);
        const __m256d cl = _mm512_castpd512_pd256(cc), ch = _mm512_extractf64x4_pd(cc, 1);
        const __m256d rl = _mm512_castpd512_pd256(r), rh = _mm512_extractf64x4_pd(r, 1);
        const __m256d sl = _mm512_castpd512_pd256(rr), sh = _mm512_extractf64x4_pd(rr, 1);
        re = _mm256_add_pd(_mm256_add_pd(re, cl), ch);
        MADD2(rz, k0, cl, ch);
        MADD2(c1, k1, one4, one4);
        MADD2(r1, k1, rl, rh);
        MADD2(rr1, k1, sl, sh);
        MADD2(c2, k2, one4, one4);
        MADD2(r2, k2, rl, rh);
        MADD2(rr2, k2, sl, sh);
        if (qrow) {
            const __m256i neg = _mm256_castps_si256(_mm256_cmp_ps(cf, _mm256_setzero_ps(), _CMP_LT_OQ));
            const __m256i sq = _mm256_sub_epi32(_mm256_xor_si256(qi, neg), neg);
            if (!sparse) {
                _mm256_storeu_si256((__m256i *)(qrow + x), sq);
            } else {
                /* only the quads holding a non-zero (q is known to be all zero) */
                const __mmask8 nz = _mm256_test_epi32_mask(qi, qi);
                if (nz & 0x0F) _mm_storeu_si128((__m128i *)(qrow + x), _mm256_castsi256_si128(sq));
                if (nz & 0xF0) _mm_storeu_si128((__m128i *)(qrow + x + 4), _mm256_extracti128_si256(sq, 1));
            }
        }
    }
    {
        double a[8][4];
        _mm256_storeu_pd(a[0], rz), _mm256_storeu_pd(a[1], re), _mm256_storeu_pd(a[2], r1);
        _mm256_storeu_pd(a[3], rr1), _mm256_storeu_pd(a[4], r2), _mm256_storeu_pd(a[5], rr2);
        _mm256_storeu_pd(a[6], c1), _mm256_storeu_pd(a[7], c2);
        double z[4];
        _mm256_storeu_pd(z, zq);
        for (int k = 0; k < 4; k++) {
            t[0] += a[0][k] + z[k], t[1] += a[1][k] + z[k], t[2] += a[2][k], t[3] += a[3][k];
            t[4] += a[4][k], t[5] += a[5][k], t[6] += a[6][k], t[7] += a[7][k];
        }
    }
    _mm256_storeu_si256((__m256i *)lanes, vmax); /* the lanes' bits as floats */
    return row_end(t, lanes, row, qrow, x, ex, inv, f, sparse);
}
#undef MADD2
#endif

/* A row's sums: one of the kernels (the same sums, bit for bit). */
typedef float (*row_fn)(double t[8], const float *row, int32_t *qrow, size_t n, double step, double f, int sparse);

/* row_kernel, as compiled for the running CPU's level */
WVOL__CLONES_V4 static float row_generic(double t[8], const float *row, int32_t *qrow, size_t n, double step,
                                         double f, int sparse)
{
    float amax;
    row_kernel(t, &amax, row, qrow, n, step, f, sparse);
    return amax;
}

/* The kernel for this CPU: the x86-64-v4 one where it runs, else row_generic. */
static row_fn row_best(void)
{
#if WVOL__HAVE_V4
    if (WVOL__CPU_V4()) return row_kernel_v4;
#endif
    return row_generic;
}

/* wvol__wvc_rows_stats with the kernel fn */
static void rows_with(row_fn fn, sec_stats *st, const float *c, int32_t *q, size_t ex, size_t ey, size_t nz,
                      size_t sy, size_t sz, double step, double f, int sparse)
{
    memset(st, 0, sizeof *st);
    for (size_t z = 0; z < nz; z++)
        for (size_t y = 0; y < ey; y++) {
            const size_t at = y * sy + z * sz;
            double t[8];
            fn(t, c + at, q ? q + at : NULL, ex, step, f, sparse);
            wvol__wvc_sec_add_row(st, t);
        }
}

float wvol__wvc_row_stats(double t[8], const float *row, int32_t *qrow, size_t n, double step, double f)
{
    return row_best()(t, row, qrow, n, step, f, 0);
}

float wvol__wvc_row_stats_generic(double t[8], const float *row, int32_t *qrow, size_t n, double step, double f)
{
    return row_generic(t, row, qrow, n, step, f, 0);
}

void wvol__wvc_rows_stats(sec_stats *st, const float *c, int32_t *q, size_t ex, size_t ey, size_t nz, size_t sy,
                          size_t sz, double step, double f, int sparse)
{
    rows_with(row_best(), st, c, q, ex, ey, nz, sy, sz, step, f, sparse);
}

void wvol__wvc_rows_stats_generic(sec_stats *st, const float *c, int32_t *q, size_t ex, size_t ey, size_t nz,
                                  size_t sy, size_t sz, double step, double f, int sparse)
{
    rows_with(row_generic, st, c, q, ex, ey, nz, sy, sz, step, f, sparse);
}
#undef SEL
work_item *wvol__wvc_work_items(const wvc_layout *L, int *count)
{
    int s, n = 0;
    work_item *w;
    size_t total = 0;
    for (s = 0; s < L->nsec; s++) {
        const wvc_band *b = &L->sec[s];
        size_t slab = b->ext[0] * b->ext[1], per = slab ? (65536 + slab - 1) / slab : 1;
        if (b->count) total += (b->ext[2] + per - 1) / per;
    }
    w = malloc((total ? total : 1) * sizeof *w);
    if (!w) return NULL;
    for (s = 0; s < L->nsec; s++) {
        const wvc_band *b = &L->sec[s];
        size_t slab = b->ext[0] * b->ext[1], per = slab ? (65536 + slab - 1) / slab : 1, z;
        if (!b->count) continue;
        for (z = 0; z < b->ext[2]; z += per) {
            w[n].sec = s;
            w[n].z0 = z;
            w[n].z1 = z + per < b->ext[2] ? z + per : b->ext[2];
            n++;
        }
    }
    *count = n;
    return w;
}

/* Per-section sums over the whole pyramid in one parallel pass; Q as in wvol__wvc_rows_stats
 * (*qzero: Q is all zero, cleared once written). */
int wvol__wvc_all_stats(sec_stats *st, const wvc_layout *L, const float *C, int32_t *Q, double step, double f,
                        int *qzero)
{
    int n = 0, i, sparse = Q && *qzero;
    work_item *w = wvol__wvc_work_items(L, &n);
    sec_stats *part;
    if (!w) return -1;
    part = malloc((n ? n : 1) * sizeof *part);
    if (!part) {
        free(w);
        return -1;
    }
#pragma omp parallel for schedule(dynamic, 1) if (n > 2)
    for (i = 0; i < n; i++) {
        const wvc_band *b = &L->sec[w[i].sec];
        const size_t at = wvc_index(L->p, b, 0, 0, w[i].z0);
        wvol__wvc_rows_stats(&part[i], C + at, Q ? Q + at : NULL, b->ext[0], b->ext[1], w[i].z1 - w[i].z0, L->p[0],
                             L->p[0] * L->p[1], step, wvol__wvc_sec_rounding(b, f), sparse);
    }
    if (Q) *qzero = 0;
    memset(st, 0, (size_t)L->nsec * sizeof *st);
    for (i = 0; i < n; i++) wvol__wvc_sec_merge(&st[w[i].sec], &part[i]);
    free(part);
    free(w);
    return 0;
}

/* The offsets as stored (float32) and the section's exact squared error with them. */
double wvol__wvc_sec_error(const sec_stats *st, double step, float *d1, float *d2)
{
    double e = st->zero_sse;
    float a = st->n1 ? (float)(st->s1 / (double)st->n1) : 0.0f;
    float b = st->n2 ? (float)(st->s2 / (double)st->n2) : 0.0f;
    e += step * step * (st->ss1 - 2.0 * a * st->s1 + (double)st->n1 * a * a);
    e += step * step * (st->ss2 - 2.0 * b * st->s2 + (double)st->n2 * b * b);
    if (d1) *d1 = a;
    if (d2) *d2 = b;
    return e < 0 ? 0 : e;
}

/* The in-memory pyramid's exact error for a step (wvc_step_error_fn): one pass that also
 * quantises into Q and leaves the sums in st. */
typedef struct pyramid_pass {
    const wvc_layout *L;
    const float *C;
    double f;
    sec_stats *st;
    int32_t *Q;
    int *qzero;
} pyramid_pass;

static double total_error(void *ctx, double step)
{
    pyramid_pass *c = ctx;
    double e = 0;
    int s;
    if (wvol__wvc_all_stats(c->st, c->L, c->C, c->Q, step, c->f, c->qzero)) return NAN;
    for (s = 0; s < c->L->nsec; s++) e += wvol__wvc_sec_error(&c->st[s], step, NULL, NULL);
    return e;
}

/* Finds the largest step (to within ~0.2%) whose error lies in [accept, 1] x target:
 * secant iterations on log(error) against log(step) from d0, each an exact pass.
 * *last: the step of the last pass. */
static double search_step(wvc_step_error_fn error, void *ctx, double target, double maxabs, double min_step,
                          int *iters, double d0, double accept, double *last)
{
    double e0, d1, e1, best_ok = 0, best_bad = INFINITY, slope = 2.0;
    int it;
    if (d0 < min_step) d0 = min_step;
    if (maxabs > 0 && d0 > 4 * maxabs) d0 = 4 * maxabs;
    e0 = error(ctx, d0);
    if (!isfinite(e0)) return NAN;
    *last = d0;
    (*iters)++;
    if (e0 <= target) best_ok = d0; else best_bad = d0;
    d1 = d0;
    e1 = e0;
    for (it = 0; it < 14; it++) {
        double ratio, next, aim = 0.5 * (1 + accept) * target;
        if (e1 <= target && e1 >= accept * target) break;
        if (e1 <= 0) {
            next = d1 * 4;
        } else {
            ratio = pow(aim / e1, 1.0 / slope);
            if (ratio > 8) ratio = 8;
            if (ratio < 0.125) ratio = 0.125;
            next = d1 * ratio;
        }
        /* stay inside the bracket; bisect (geometrically) when the secant leaves it */
        if (best_ok > 0 && isfinite(best_bad) && (next <= best_ok || next >= best_bad))
            next = sqrt(best_ok * best_bad);
        if (next < min_step) next = min_step;
        if (next > 4 * maxabs && maxabs > 0) next = 4 * maxabs;
        /* the error is a staircase in the step: changes below 0.05% are noise */
        if (fabs(next / d1 - 1) < 5e-4) {
            if (e1 <= target) break;
            next = d1 * 0.995;
        }
        d0 = d1;
        e0 = e1;
        d1 = next;
        e1 = error(ctx, d1);
        if (!isfinite(e1)) return NAN;
        *last = d1;
        (*iters)++;
        if (e1 <= target) {
            if (d1 > best_ok) best_ok = d1;
        } else if (d1 < best_bad) {
            best_bad = d1;
        }
        if (e0 > 0 && e1 > 0 && fabs(log(d1 / d0)) > 1e-9) {
            slope = log(e1 / e0) / log(d1 / d0);
            if (!(slope >= 0.3)) slope = 0.3;
            if (slope > 3) slope = 3;
        }
        if (isfinite(best_bad) && best_ok > 0 && best_bad / best_ok < 1.002) break;
    }
    if (best_ok > 0) return best_ok;
    /* not reached even at the smallest step the quantiser allows */
    return min_step;
}

double wvol__wvc_refine_step(wvc_hist_est *est, const wvc_layout *L, double f, double target, double maxabs,
                             double min_step, wvc_step_error_fn error, void *ctx, int *iters, double *last)
{
    const double aim = 0.9925, accept = 0.985;
    double d = wvol__wvc_hist_step(est, L, aim * target, f, min_step, 4 * maxabs), e = error(ctx, d);
    *iters = 1;
    *last = d;
    if (!isfinite(e)) return NAN;
    if (!(e <= target && e >= accept * target)) {
        double predicted = wvol__wvc_hist_error(est, L, d, f), k = predicted > 0 && e > 0 ? e / predicted : 1;
        d = wvol__wvc_hist_step(est, L, aim * target / k, f, min_step, 4 * maxabs);
        d = search_step(error, ctx, target, maxabs, min_step, iters, d, accept, last);
    }
    return d;
}

/* The largest step whose error stays within [0.985, 1] x target (PSNR at most
 * 0.066 dB above the target): the step the histograms predict for 0.9925 x target
 * (no pass over the data); an exact pass that also quantises into Q; if that misses,
 * the prediction again, scaled by what the pass measured against what was
 * predicted at that step, then secant iterations on exact passes (rarely needed).
 * On return Q and st hold the quantisation with the returned step. */
double wvol__wvc_choose_step(const wvc_layout *L, const float *C, const uint64_t *H, double target, double f,
                             double maxabs, double min_step, sec_stats *st, int *iters, int32_t *Q, int *qzero)
{
    pyramid_pass pass = {L, C, f, st, Q, qzero};
    double d, last = 0;
    wvc_hist_est *est = wvol__wvc_hist_prepare(H, L);
    if (!est) return NAN;
    d = wvol__wvc_refine_step(est, L, f, target, maxabs, min_step, total_error, &pass, iters, &last);
    wvol__wvc_hist_free(est);
    if (isfinite(d) && last != d) { /* Q and st hold the last pass: quantise with d again */
        (*iters)++;
        if (!isfinite(total_error(&pass, d))) return NAN;
    }
    return d;
}
