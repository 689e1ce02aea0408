/* SPDX-License-Identifier: MIT */
/* Partial reconstruction: a coarser volume (stop at level s) and one brick of the finest
 * level from only the coefficients whose support reaches it. */
#include <math.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/clones.h"
#include "core/finite.h"
#include "wavelet/wavelet_internal.h"

wvol_status wvol_idwt3_level(wvol_volume **out, const wvol_coeffs *c, int stop_level, wvol_error *err)
{
    size_t pad[3], dims[3], n;
    float *d;
    wvol_volume *v;
    wvol_status st;
    double scale = 1.0;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_idwt3_level: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__coeffs_check(c, err));
    WVOL_RETURN_IF(stop_level < 0 || stop_level > c->levels, err, WVOL_ERR_ARG,
                   "wvol_idwt3_level: level %d outside 0..%d", stop_level, c->levels);
    if (stop_level == 0) return wvol_idwt3(out, c, err);
    WVOL_FORWARD(wvol_check_finite(c->data, c->px, c->py, c->pz, "wvol_idwt3_level: coefficients", err));
    pad[0] = c->px, pad[1] = c->py, pad[2] = c->pz;
    dims[0] = c->nx, dims[1] = c->ny, dims[2] = c->nz;
    n = c->px * c->py * c->pz;
    d = malloc(n * sizeof *d);
    WVOL_RETURN_IF(!d, err, WVOL_ERR_NOMEM, "wvol_idwt3_level: no memory for %zu floats", n);
    memcpy(d, c->data, n * sizeof *d);
    st = wvol__idwt3_partial_f32(d, c->px, c->py, c->pz, c->filter, c->levels, stop_level, err);
    if (st != WVOL_OK) {
        free(d);
        return st;
    }
    size_t e[3];
    for (int a = 0; a < 3; a++) {
        size_t q = (size_t)1 << stop_level;
        e[a] = pad[a] == 1 ? 1 : (dims[a] + q - 1) / q; /* cells that touch the original grid */
        if (pad[a] > 1) scale *= pow(2.0, -0.5 * stop_level);
    }
    st = wvol_volume_create(&v, e[0], e[1], e[2], err);
    if (st != WVOL_OK) {
        free(d);
        return st;
    }
    {
        const size_t P[3] = {wvol__extent(pad[0], stop_level), wvol__extent(pad[1], stop_level),
                             wvol__extent(pad[2], stop_level)};
        wvol__level_crop(v->data, e, d, P, c->px, c->px * c->py, c->filter, stop_level, scale);
    }
    free(d);
    for (int a = 0; a < 3; a++) {
        const int tr = pad[a] != 1;
        v->spacing[a] = c->spacing[a] * (tr ? ldexp(1.0, stop_level) : 1.0);
        v->origin[a] = c->origin[a] + (tr ? c->spacing[a] * wvol_level_offset(c->filter, stop_level) : 0.0);
    }
    *out = v;
    return WVOL_OK;
}

void wvol__level_crop(float *dst, const size_t e[3], const float *src, const size_t P[3], size_t row, size_t slice,
                      const wvol_filter *f, int level, double scale)
{
    size_t sh[3]; /* i - shift, kept non-negative: i + (P - shift mod P) */
    for (int a = 0; a < 3; a++) sh[a] = P[a] == 1 ? 0 : P[a] - wvol_level_shift(f, level) % P[a];
    for (size_t k = 0; k < e[2]; k++)
        for (size_t j = 0; j < e[1]; j++) {
            const float *r = src + row * ((j + sh[1]) % P[1]) + slice * ((k + sh[2]) % P[2]);
            float *to = dst + e[0] * (j + e[1] * k);
            for (size_t i = 0; i < e[0]; i++) to[i] = (float)(scale * r[(i + sh[0]) % P[0]]);
        }
}

size_t wvol_level_shift(const wvol_filter *f, int level)
{
    double t, off;
    if (!f || level <= 0 || level > 62) return 0;
    t = ldexp(1.0, level);
    off = (t - 1.0) * f->center; /* in voxels; exact for the centres the filters have */
    return (size_t)floor(off / t);
}

double wvol_level_offset(const wvol_filter *f, int level)
{
    double t;
    if (!f || level <= 0 || level > 62) return 0.0;
    t = ldexp(1.0, level);
    return (t - 1.0) * f->center - t * (double)wvol_level_shift(f, level);
}

wvol_status wvol_volume_level(wvol_volume **out, const wvol_volume *v, const wvol_filter *f, int level,
                              double *energy, wvol_error *err)
{
    wvol_coeffs *c = NULL;
    wvol_status st;
    double total = 0.0, low = 0.0;
    size_t n, e[3];
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_volume_level: out is NULL");
    *out = NULL;
    if (energy) *energy = 0.0;
    WVOL_RETURN_IF(!v || !v->data || !f, err, WVOL_ERR_ARG, "wvol_volume_level: volume or filter is NULL");
    WVOL_RETURN_IF(level < 0 || level > wvol_dwt_max_levels(v->nx, v->ny, v->nz), err, WVOL_ERR_ARG,
                   "wvol_volume_level: level %d outside 0..%d for a %zu x %zu x %zu volume", level,
                   wvol_dwt_max_levels(v->nx, v->ny, v->nz), v->nx, v->ny, v->nz);
    if (level == 0) {
        /* the transform below tests the data (level > 0); the copy must refuse the same */
        WVOL_FORWARD(wvol_check_finite(v->data, v->nx, v->ny, v->nz, "wvol_volume_level: volume", err));
        return wvol_volume_clone(out, v, err);
    }
    WVOL_FORWARD(wvol_dwt3(&c, v, f, level, err));
    n = c->px * c->py * c->pz;
    e[0] = wvol__extent(c->px, level), e[1] = wvol__extent(c->py, level), e[2] = wvol__extent(c->pz, level);
    for (size_t i = 0; i < n; i++) total += (double)c->data[i] * c->data[i];
    for (size_t k = 0; k < e[2]; k++)
        for (size_t j = 0; j < e[1]; j++)
            for (size_t i = 0; i < e[0]; i++) {
                double x = c->data[i + c->px * (j + c->py * k)];
                low += x * x;
            }
    st = wvol_idwt3_level(out, c, level, err);
    wvol_coeffs_destroy(c);
    if (st == WVOL_OK && energy) *energy = total > low ? total - low : 0.0;
    return st;
}

/* ---- bricks -------------------------------------------------------------------- */

static ptrdiff_t floor_div2(ptrdiff_t a) { return a >= 0 ? a / 2 : -((-a + 1) / 2); }

static size_t region_count(const ptrdiff_t n[3]) { return (size_t)(n[0] * n[1] * n[2]); }

/* Dense source: band `band` of level m of a wvol_coeffs on the region (indices taken
 * periodically). Returns 0 when every value is zero. */
static int gather_dense(const void *ctx, float *dst, int m, int band, const ptrdiff_t lo[3], const ptrdiff_t n[3])
{
    const wvol_coeffs *c = ctx;
    size_t pad[3] = {c->px, c->py, c->pz}, e[3], off[3];
    int any = 0;
    for (int a = 0; a < 3; a++) {
        e[a] = wvol__extent(pad[a], m);
        off[a] = ((band >> a) & 1) ? e[a] : 0;
    }
    size_t t = 0;
    for (ptrdiff_t k = 0; k < n[2]; k++) {
        ptrdiff_t zk = (lo[2] + k) % (ptrdiff_t)e[2];
        size_t z = off[2] + (size_t)(zk < 0 ? zk + (ptrdiff_t)e[2] : zk);
        for (ptrdiff_t j = 0; j < n[1]; j++) {
            ptrdiff_t yj = (lo[1] + j) % (ptrdiff_t)e[1];
            size_t y = off[1] + (size_t)(yj < 0 ? yj + (ptrdiff_t)e[1] : yj);
            const float *row = c->data + c->px * (y + c->py * z) + off[0];
            ptrdiff_t xi = lo[0] % (ptrdiff_t)e[0];
            if (xi < 0) xi += (ptrdiff_t)e[0];
            for (ptrdiff_t i = 0; i < n[0]; i++) {
                dst[t] = row[xi];
                any |= dst[t++] != 0.0;
                if (++xi == (ptrdiff_t)e[0]) xi = 0;
            }
        }
    }
    return any;
}

void wvol__coef_source_of_coeffs(wvol__coef_source *src, const wvol_coeffs *c)
{
    src->gather = gather_dense;
    src->ctx = c;
    src->filter = c->filter;
    src->levels = c->levels;
    src->dims[0] = c->nx, src->dims[1] = c->ny, src->dims[2] = c->nz;
    src->pad[0] = c->px, src->pad[1] = c->py, src->pad[2] = c->pz;
    src->dc = wvol__lowpass_offset(c->data, src->pad, c->levels);
}

/* The coarser pyramid of a source: levels m + skip seen as m, the low-pass cube as is. */
static int gather_skip(const void *ctx, float *dst, int m, int band, const ptrdiff_t lo[3], const ptrdiff_t n[3])
{
    const wvol__coef_skip *k = ctx;
    if (m == 0) m = k->inner.levels, band = 0; /* a pyramid of no levels: the samples are the low-pass cube */
    else m += k->skip;
    return k->inner.gather(k->inner.ctx, dst, m, band, lo, n);
}

void wvol__coef_source_skip(wvol__coef_source *dst, wvol__coef_skip *ctx, const wvol__coef_source *src, int skip)
{
    ctx->inner = *src;
    ctx->skip = skip;
    *dst = *src;
    dst->gather = gather_skip;
    dst->ctx = ctx;
    dst->levels = src->levels - skip;
    for (int a = 0; a < 3; a++) {
        dst->dims[a] = src->pad[a] > 1 ? (src->dims[a] + ((size_t)1 << skip) - 1) >> skip : 1;
        dst->pad[a] = src->pad[a] > 1 ? src->pad[a] >> skip : 1;
    }
}

/* The taps of output gi: k in [*kmin, *kmax] with 0 <= gi - 2k <= L - 1, clipped to the
 * input region [k0, k0 + kn) unless it is a whole period (full); *rel = (kmin - k0) mod kn,
 * the input position of the first (a division only in the periodic case: clipped, kmin - k0
 * already lies in [0, kn)). */
static inline void tap_range(ptrdiff_t gi, ptrdiff_t L, ptrdiff_t k0, ptrdiff_t kn, int full, ptrdiff_t *kmin,
                             ptrdiff_t *kmax, ptrdiff_t *rel)
{
    *kmin = -floor_div2(L - 1 - gi);
    *kmax = floor_div2(gi);
    if (!full) {
        if (*kmin < k0) *kmin = k0;
        if (*kmax > k0 + kn - 1) *kmax = k0 + kn - 1;
    }
    *rel = *kmin - k0;
    if (full) {
        *rel %= kn;
        if (*rel < 0) *rel += kn;
    }
}

/* The short filters' synthesis kernels, for tap counts 1..4 per output (Haar 1, db2 2,
 * coif1 3, db4 4; longer filters take the general loops): NT and which of the two input
 * bands exist (WHICH: 1 low, 2 high, 3 both) are constants, so the tap loops unroll and the
 * output loops vectorise. Each output is summed as the general loops sum it, 0.0 first, then
 * tap by tap in the order of k, each tap's two products added before they join the sum: the
 * same operations in the same order, so the same results bit for bit. */
#define SYNTH_FIXED_MAX 4

/* The synthesis passes are multi-versioned (core/clones.h: AVX2 rows where the CPU has them)
 * with contraction off, so that no clone fuses a multiply and an add into an FMA: every
 * clone rounds each product and each sum as the baseline does, the same samples bit for bit
 * on every CPU. */
#define WVOL__SYNTH WVOL__CLONES WVOL__NO_CONTRACT

/* A run of outputs along y or z (inner > 1): o[x] = sum_j wh[j] l[j][x] + wg[j] h[j][x]
 * over whole inner rows, in one pass (the general loop adds each tap into o in its own pass). */
static inline __attribute__((always_inline)) void synth_rows_fixed(float *restrict o, const float *const *l,
                                                                   const float *const *h, const float *wh,
                                                                   const float *wg, ptrdiff_t inner, const int NT,
                                                                   const int WHICH)
{
    const float *lr[SYNTH_FIXED_MAX], *hr[SYNTH_FIXED_MAX];
    for (int j = 0; j < NT; j++) {
        lr[j] = WHICH & 1 ? l[j] : NULL;
        hr[j] = WHICH & 2 ? h[j] : NULL;
    }
    for (ptrdiff_t x = 0; x < inner; x++) {
        float acc = 0.0;
        for (int j = 0; j < NT; j++) {
            if (WHICH == 3) acc += wh[j] * lr[j][x] + wg[j] * hr[j][x];
            else if (WHICH == 1) acc += wh[j] * lr[j][x];
            else acc += wg[j] * hr[j][x];
        }
        o[x] = acc;
    }
}

/* Outputs i0, i0 + 1, ... < i1 of one x row taken in pairs (even, odd output index): in the
 * interior both read the same NT consecutive inputs from r0[i], with taps that depend only on
 * the parity (eh, eg for the first of a pair, oh, og for the second), so a pair is two sums
 * side by side over shared loads instead of two gathers of their own. */
static inline __attribute__((always_inline)) void synth_x_pairs(float *restrict o, const float *lu,
                                                                const float *hu, const ptrdiff_t *r0,
                                                                const float *eh, const float *eg,
                                                                const float *oh, const float *og, ptrdiff_t i0,
                                                                ptrdiff_t i1, const int NT, const int WHICH)
{
    ptrdiff_t i = i0;
#if defined(__SSE2__)
    /* four pairs at once where their inputs start at consecutive positions (the interior):
     * the same sums in the same order, lane by lane, the pairs' even and odd outputs then
     * interleaved (as eight scalar sums this pass would be a third of a brick's build) */
    const __m128 zero = _mm_setzero_ps();
    for (; i + 7 < i1 && r0[i + 2] == r0[i] + 1 && r0[i + 4] == r0[i] + 2 && r0[i + 6] == r0[i] + 3; i += 8) {
        const float *l = WHICH & 1 ? lu + r0[i] : NULL, *h = WHICH & 2 ? hu + r0[i] : NULL;
        __m128 e = zero, d = zero;
        for (int j = 0; j < NT; j++) {
            if (WHICH == 3) {
                const __m128 lj = _mm_loadu_ps(l + j), hj = _mm_loadu_ps(h + j);
                e = _mm_add_ps(e, _mm_add_ps(_mm_mul_ps(_mm_set1_ps(eh[j]), lj), _mm_mul_ps(_mm_set1_ps(eg[j]), hj)));
                d = _mm_add_ps(d, _mm_add_ps(_mm_mul_ps(_mm_set1_ps(oh[j]), lj), _mm_mul_ps(_mm_set1_ps(og[j]), hj)));
            } else if (WHICH == 1) {
                const __m128 lj = _mm_loadu_ps(l + j);
                e = _mm_add_ps(e, _mm_mul_ps(_mm_set1_ps(eh[j]), lj));
                d = _mm_add_ps(d, _mm_mul_ps(_mm_set1_ps(oh[j]), lj));
            } else {
                const __m128 hj = _mm_loadu_ps(h + j);
                e = _mm_add_ps(e, _mm_mul_ps(_mm_set1_ps(eg[j]), hj));
                d = _mm_add_ps(d, _mm_mul_ps(_mm_set1_ps(og[j]), hj));
            }
        }
        _mm_storeu_ps(o + i, _mm_unpacklo_ps(e, d));
        _mm_storeu_ps(o + i + 4, _mm_unpackhi_ps(e, d));
    }
#endif
    for (; i + 1 < i1; i += 2) {
        const float *l = WHICH & 1 ? lu + r0[i] : NULL, *h = WHICH & 2 ? hu + r0[i] : NULL;
        float e = 0.0, d = 0.0;
        for (int j = 0; j < NT; j++) {
            if (WHICH == 3) {
                e += eh[j] * l[j] + eg[j] * h[j];
                d += oh[j] * l[j] + og[j] * h[j];
            } else if (WHICH == 1) {
                e += eh[j] * l[j];
                d += oh[j] * l[j];
            } else {
                e += eg[j] * h[j];
                d += og[j] * h[j];
            }
        }
        o[i] = e;
        o[i + 1] = d;
    }
}

/* Dispatch on (NT, WHICH) for the two kernels above; 0 when NT is outside 1..SYNTH_FIXED_MAX. */
#define SYNTH_CASES(CALL)                                                                                    \
    switch (nt) {                                                                                            \
    case 1: if (which == 3) CALL(1, 3); else if (which == 1) CALL(1, 1); else CALL(1, 2); return 1;          \
    case 2: if (which == 3) CALL(2, 3); else if (which == 1) CALL(2, 1); else CALL(2, 2); return 1;          \
    case 3: if (which == 3) CALL(3, 3); else if (which == 1) CALL(3, 1); else CALL(3, 2); return 1;          \
    case 4: if (which == 3) CALL(4, 3); else if (which == 1) CALL(4, 1); else CALL(4, 2); return 1;          \
    default: return 0;                                                                                       \
    }

WVOL__SYNTH static int synth_rows_any(float *o, const float *const *l, const float *const *h, const float *wh,
                          const float *wg, ptrdiff_t inner, int nt, int which)
{
#define ROWS_CALL(N, W) synth_rows_fixed(o, l, h, wh, wg, inner, N, W)
    SYNTH_CASES(ROWS_CALL)
#undef ROWS_CALL
}

WVOL__SYNTH static int synth_x_pairs_any(float *o, const float *lu, const float *hu, const ptrdiff_t *r0, const float *eh,
                             const float *eg, const float *oh, const float *og, ptrdiff_t i0, ptrdiff_t i1,
                             int nt, int which)
{
#define PAIRS_CALL(N, W) synth_x_pairs(o, lu, hu, r0, eh, eg, oh, og, i0, i1, N, W)
    SYNTH_CASES(PAIRS_CALL)
#undef PAIRS_CALL
}
#undef SYNTH_CASES

/* The x axis of synth_axis (inner stride 1: one output per row position) with its taps
 * planned once for all rows: per output i, the input positions (rel), and the two filters'
 * taps, in the order of k, which synth_axis's general loop recomputes for every row (index
 * arithmetic outweighed the two or so multiply-adds per output of a short filter). Same sums
 * in the same order, so the same results. A plan of up to SYNTH_PLAN_MAX taps lives on the
 * stack; a longer one (a whole 1024-sample row of db2 has 2048) in one heap block. */
#define SYNTH_PLAN_MAX 1024

/* Output i of a planned x row: its taps first[i] .. first[i + 1] - 1 summed in the order of k
 * (which: 1 low band only, 2 high only, 3 both). */
static inline float planned_sum(const float *lu, const float *hu, const ptrdiff_t *rel, const float *wh,
                                 const float *wg, const ptrdiff_t *first, ptrdiff_t i, int which)
{
    float acc = 0.0;
    for (ptrdiff_t t = first[i]; t < first[i + 1]; t++) {
        if (which == 3) acc += wh[t] * lu[rel[t]] + wg[t] * hu[rel[t]];
        else if (which == 1) acc += wh[t] * lu[rel[t]];
        else acc += wg[t] * hu[rel[t]];
    }
    return acc;
}

/* Returns 0 (nothing written) when a plan longer than the stack's finds no memory: the
 * caller's general loop then computes the same values. */
WVOL__SYNTH static int synth_x_planned(float *out, const float *lo, const float *hi, ptrdiff_t kn, ptrdiff_t k0,
                                       ptrdiff_t o0, ptrdiff_t on, ptrdiff_t outer, int full, const wvol_filter *f)
{
    ptrdiff_t rel_s[SYNTH_PLAN_MAX], first_s[SYNTH_PLAN_MAX + 1], r0_s[SYNTH_PLAN_MAX], L = f->length, nt = 0;
    ptrdiff_t p0 = (o0 & 1) ? 1 : 0, p1; /* the pairs: outputs p0 .. p1 - 1, the first of each even */
    ptrdiff_t off = 0, span = 0;
    float wh_s[SYNTH_PLAN_MAX], wg_s[SYNTH_PLAN_MAX], ext_s[2][SYNTH_PLAN_MAX];
    /* cap: the most taps (each output has at most (L + 1) / 2) and the longest unwrapped row */
    const ptrdiff_t cap = on * ((L + 1) / 2) > on + 1 ? on * ((L + 1) / 2) : on + 1;
    ptrdiff_t *rel = rel_s, *first = first_s, *r0 = r0_s;
    float *wh = wh_s, *wg = wg_s, *ext[2] = {ext_s[0], ext_s[1]};
    void *heap = NULL;
    int paired, taps, which = (lo ? 1 : 0) | (hi ? 2 : 0), unwrap = 0;
    if (cap > SYNTH_PLAN_MAX) {
        size_t n = (size_t)cap;
        heap = malloc(n * (3 * sizeof(ptrdiff_t) + 4 * sizeof(float)) + sizeof(ptrdiff_t));
        if (!heap) return 0;
        rel = heap, first = rel + n, r0 = first + n + 1;
        wh = (float *)(r0 + n), wg = wh + n, ext[0] = wg + n, ext[1] = ext[0] + n;
    }
    /* A whole period (full): the taps wrap around the row. Planned on the unwrapped
     * positions instead, each row copied first into ext with its wrap-around continued
     * (span positions from -off), the taps become consecutive and the pairs apply: the
     * same values summed in the same order, without the scalar loop at every output. */
    if (full) {
        ptrdiff_t rmin = 0, rmax = 0;
        for (ptrdiff_t i = 0; i < on; i++) {
            ptrdiff_t kmin, kmax, r;
            tap_range(o0 + i, L, k0, kn, full, &kmin, &kmax, &r);
            if (i == 0 || kmin - k0 < rmin) rmin = kmin - k0;
            if (i == 0 || kmax - k0 > rmax) rmax = kmax - k0;
        }
        off = -rmin;
        span = rmax - rmin + 1;
        unwrap = span <= (heap ? cap : SYNTH_PLAN_MAX);
    }
    for (ptrdiff_t i = 0; i < on; i++) {
        ptrdiff_t gi = o0 + i, kmin, kmax, r;
        tap_range(gi, L, k0, kn, full, &kmin, &kmax, &r);
        if (unwrap) r = kmin - k0 + off; /* the position in the unwrapped copy, not mod kn */
        first[i] = nt;
        r0[i] = r;
        for (ptrdiff_t k = kmin; k <= kmax; k++) {
            rel[nt] = r;
            wh[nt] = f->h[gi - 2 * k];
            wg[nt++] = f->g[gi - 2 * k];
            if (++r == kn && !unwrap) r = 0;
        }
    }
    first[on] = nt;
    /* pairs apply where every paired output has the same tap count at consecutive positions
     * (no wrap) from its pair's shared start, with its parity's taps (the interior) */
    p1 = p0 + ((on - p0) & ~(ptrdiff_t)1);
    taps = p1 > p0 ? (int)(first[p0 + 1] - first[p0]) : 0;
    paired = taps >= 1 && taps <= SYNTH_FIXED_MAX;
    for (ptrdiff_t i = p0; paired && i < p1; i++) {
        ptrdiff_t par = (i - p0) & 1, ref = first[p0 + par];
        if (first[i + 1] - first[i] != taps || r0[i] != r0[i - par]) paired = 0;
        for (int j = 0; paired && j < taps; j++)
            if (rel[first[i] + j] != r0[i] + j || wh[first[i] + j] != wh[ref + j] || wg[first[i] + j] != wg[ref + j])
                paired = 0;
    }
    for (ptrdiff_t u = 0; u < outer; u++) {
        const float *lu = lo ? lo + u * kn : NULL, *hu = hi ? hi + u * kn : NULL;
        float *restrict o = out + u * on;
        if (unwrap) {
            /* ext[.][t] = row[(t - off) mod kn], copied in runs up to the row's end */
            ptrdiff_t x = (-off) % kn;
            if (x < 0) x += kn;
            for (ptrdiff_t t = 0, run; t < span; t += run, x = 0) {
                run = kn - x < span - t ? kn - x : span - t;
                if (lu) memcpy(ext[0] + t, lu + x, (size_t)run * sizeof *lu);
                if (hu) memcpy(ext[1] + t, hu + x, (size_t)run * sizeof *hu);
            }
            lu = lu ? ext[0] : NULL;
            hu = hu ? ext[1] : NULL;
        }
        if (paired && synth_x_pairs_any(o, lu, hu, r0, wh + first[p0], wg + first[p0], wh + first[p0 + 1],
                                        wg + first[p0 + 1], p0, p1, taps, which)) {
            /* the unpaired first and last outputs */
            if (p0 == 1) o[0] = planned_sum(lu, hu, rel, wh, wg, first, 0, which);
            if (p1 < on) o[p1] = planned_sum(lu, hu, rel, wh, wg, first, p1, which);
            continue;
        }
        /* which is the same for every row: one copy of the loop per value, the test hoisted */
        if (which == 3)
            for (ptrdiff_t i = 0; i < on; i++) o[i] = planned_sum(lu, hu, rel, wh, wg, first, i, 3);
        else if (which == 1)
            for (ptrdiff_t i = 0; i < on; i++) o[i] = planned_sum(lu, hu, rel, wh, wg, first, i, 1);
        else
            for (ptrdiff_t i = 0; i < on; i++) o[i] = planned_sum(lu, hu, rel, wh, wg, first, i, 2);
    }
    free(heap);
    return 1;
}

/* Synthesis along `axis` on unwrapped indices: in arrays lo/hi (either may be NULL: all
 * zero) cover the region (in_lo, in_n) (along the axis [k0, k0+kn)), out covers [o0, o0+on)
 * along the axis and in's extent along the others. out[i] = sum_k h[i-2k] lo[k] + g[i-2k]
 * hi[k], 0 <= i-2k < L. When the input region is a whole period (full), k is taken modulo it. */
WVOL__SYNTH static void synth_axis(float *out, const float *lo, const float *hi, const ptrdiff_t in_lo[3],
                       const ptrdiff_t in_n[3], ptrdiff_t o0, ptrdiff_t on, int axis, int full, const wvol_filter *f)
{
    /* [outer][axis][inner] view, inner contiguous: the tap loop adds whole inner rows
     * (x for the y axis, xy-planes for z), which the compiler vectorises */
    ptrdiff_t inner = 1, outer = 1, kn = in_n[axis], k0 = in_lo[axis], L = f->length;
    for (int a = 0; a < axis; a++) inner *= in_n[a];
    for (int a = axis + 1; a < 3; a++) outer *= in_n[a];
    if (inner == 1 && synth_x_planned(out, lo, hi, kn, k0, o0, on, outer, full, f)) return;
    for (ptrdiff_t u = 0; u < outer; u++) {
        const float *lu = lo ? lo + u * kn * inner : NULL, *hu = hi ? hi + u * kn * inner : NULL;
        for (ptrdiff_t i = 0; i < on; i++) {
            float *restrict o = out + (u * on + i) * inner;
            ptrdiff_t gi = o0 + i, kmin, kmax, k, rel; /* rel: stepped without a division per tap */
            tap_range(gi, L, k0, kn, full, &kmin, &kmax, &rel);
            if (inner == 1) {
                /* the x axis: one output per row position, summed in a register (adding
                 * into o[0] tap by tap made every tap wait for the last one's store) */
                float acc = 0.0;
                for (k = kmin; k <= kmax; k++) {
                    float wh = f->h[gi - 2 * k], wg = f->g[gi - 2 * k];
                    if (lu && hu) acc += wh * lu[rel] + wg * hu[rel]; /* the order below: same sums */
                    else if (lu) acc += wh * lu[rel];
                    else acc += wg * hu[rel];
                    if (++rel == kn) rel = 0;
                }
                o[0] = acc;
                continue;
            }
            if (kmax - kmin < SYNTH_FIXED_MAX) { /* a short filter: its rows in one pass */
                const float *lr[SYNTH_FIXED_MAX], *hr[SYNTH_FIXED_MAX];
                float wh[SYNTH_FIXED_MAX], wg[SYNTH_FIXED_MAX];
                int nt = 0;
                for (k = kmin; k <= kmax; k++, nt++) {
                    wh[nt] = f->h[gi - 2 * k], wg[nt] = f->g[gi - 2 * k];
                    lr[nt] = lu ? lu + rel * inner : NULL;
                    hr[nt] = hu ? hu + rel * inner : NULL;
                    if (++rel == kn) rel = 0;
                }
                /* nt 0 (no tap) left kmin, kmax and rel as they were: the loop below writes zeros */
                if (synth_rows_any(o, lr, hr, wh, wg, inner, nt, (lu ? 1 : 0) | (hu ? 2 : 0))) continue;
            }
            for (ptrdiff_t x = 0; x < inner; x++) o[x] = 0.0;
            for (k = kmin; k <= kmax; k++) {
                float wh = f->h[gi - 2 * k], wg = f->g[gi - 2 * k];
                if (lu && hu) {
                    const float *restrict l = lu + rel * inner, *restrict hh = hu + rel * inner;
                    for (ptrdiff_t x = 0; x < inner; x++) o[x] += wh * l[x] + wg * hh[x];
                } else if (lu) {
                    const float *restrict l = lu + rel * inner;
                    for (ptrdiff_t x = 0; x < inner; x++) o[x] += wh * l[x];
                } else {
                    const float *restrict hh = hu + rel * inner;
                    for (ptrdiff_t x = 0; x < inner; x++) o[x] += wg * hh[x];
                }
                if (++rel == kn) rel = 0;
            }
        }
    }
}

/* Scratch arrays: grown, never shrunk; freed by wvol__brick_scratch_free. A slot's contents
 * are dead when it is taken (every user writes it whole first), so a slot too small is
 * replaced, not copied, by whole huge pages where it is large (core/alloc.h): a fresh
 * reconstruction's first touches of its band arrays were a visible part of a store's first
 * marching cubes. */
static float *scratch_get(wvol__brick_scratch *s, int slot, size_t n)
{
    if (s->cap[slot] < n) {
        size_t bytes = n * sizeof(float);
        float *p;
        if (n > SIZE_MAX / sizeof(float)) return NULL;
        free(s->buf[slot]);
        s->buf[slot] = NULL;
        s->cap[slot] = 0;
        if (!(p = wvol__malloc_pages(&bytes))) return NULL;
        s->buf[slot] = p;
        s->cap[slot] = bytes / sizeof(float);
    }
    return s->buf[slot];
}

void wvol__brick_scratch_free(wvol__brick_scratch *s)
{
    for (int i = 0; i < WVOL__BRICK_SCRATCH; i++) free(s->buf[i]);
    memset(s, 0, sizeof *s);
}

size_t wvol__brick_scratch_bytes(const wvol__brick_scratch *s)
{
    size_t b = 0;
    for (int i = 0; i < WVOL__BRICK_SCRATCH; i++) b += s->cap[i] * sizeof(float);
    return b;
}

/* R_m, m = 0..M: the level-m coefficients that reach R_{m-1} (0 <= i - 2k <= L-1), R_0 the
 * box; a region at least one period long is the whole period (long filters, deep levels):
 * its synthesis indexes the coefficients periodically. */
static void brick_regions(const wvol__coef_source *src, const size_t lo[3], const size_t hi[3], ptrdiff_t rlo[][3],
                          ptrdiff_t rn[][3])
{
    const size_t *pad = src->pad;
    for (int a = 0; a < 3; a++) {
        rlo[0][a] = (ptrdiff_t)lo[a];
        rn[0][a] = (ptrdiff_t)(hi[a] - lo[a]);
    }
    for (int m = 1; m <= src->levels; m++)
        for (int a = 0; a < 3; a++) {
            if (pad[a] == 1) {
                rlo[m][a] = 0, rn[m][a] = 1;
                continue;
            }
            ptrdiff_t l0 = rlo[m - 1][a], h0 = l0 + rn[m - 1][a];
            ptrdiff_t kl = -floor_div2(src->filter->length - 1 - l0), kh = floor_div2(h0 - 1) + 1;
            ptrdiff_t e = (ptrdiff_t)wvol__extent(pad[a], m);
            if (kh - kl >= e) kl = 0, kh = e;
            rlo[m][a] = kl, rn[m][a] = kh - kl;
        }
}

size_t wvol__idwt3_brick_positions(const wvol__coef_source *src, const size_t lo[3], const size_t hi[3])
{
    ptrdiff_t rlo[33][3], rn[33][3];
    size_t n = 0;
    if (src->levels < 0 || src->levels > 32) return 0;
    brick_regions(src, lo, hi, rlo, rn);
    for (int m = 1; m <= src->levels; m++) {
        int bands = 1;
        for (int a = 0; a < 3; a++) bands *= src->pad[a] > 1 ? 2 : 1;
        n += (size_t)(bands - (m < src->levels)) * region_count(rn[m]);
    }
    return n;
}

wvol_status wvol__idwt3_brick_src(float *out, const wvol__coef_source *src, const size_t lo[3], const size_t hi[3],
                                  wvol__brick_scratch *scr, wvol_error *err)
{
    const size_t *pad = src->pad;
    ptrdiff_t rlo[33][3], rn[33][3];
    /* bands[b] is scratch slot slot[b] or NULL (all zero); slots 0..7 hold bands, 8..15 spare */
    float *bands[8];
    int slot[8], free_slots[16], nfree = 0, M = src->levels, a, last_ax = -1;
    double back = 0.0; /* the offset taken out of the low-pass band, in sample units */
    size_t outn = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    WVOL_RETURN_IF(M < 0 || M > 32, err, WVOL_ERR_ARG, "brick: %d levels", M);
    brick_regions(src, lo, hi, rlo, rn);
    for (int i = 15; i >= 0; i--) free_slots[nfree++] = i;
    /* the last synthesis pass (level 1's lowest transformed axis) writes into out itself */
    for (a = 2; a >= 0; a--)
        if (pad[a] != 1) last_ax = a;
#define TAKE(b, n)                                                                                          \
    do {                                                                                                    \
        slot[b] = free_slots[--nfree];                                                                      \
        bands[b] = scratch_get(scr, slot[b], (n));                                                          \
        if (!bands[b]) return wvol_error_set(err, WVOL_ERR_NOMEM, "brick: out of memory");                  \
    } while (0)
#define DROP(b)                                                                                             \
    do {                                                                                                    \
        if (bands[b] && slot[b] >= 0) free_slots[nfree++] = slot[b];                                        \
        bands[b] = NULL;                                                                                    \
    } while (0)
    for (int b = 0; b < 8; b++) bands[b] = NULL;
    if (M == 0) {
        TAKE(0, region_count(rn[0]));
        if (!src->gather(src->ctx, bands[0], 0, 0, rlo[0], rn[0])) DROP(0);
    } else {
        TAKE(0, region_count(rn[M]));
        if (!src->gather(src->ctx, bands[0], M, 0, rlo[M], rn[M])) DROP(0);
        if (src->dc != 0.0f && bands[0]) { /* the offset out (exact: the band lies within a factor 2 of it) */
            const size_t cnt = region_count(rn[M]);
            for (size_t i = 0; i < cnt; i++) bands[0][i] -= src->dc;
            back = (double)src->dc / wvol__dc_gain_f32(src->filter, M, pad);
        }
    }
    for (int m = M; m >= 1; m--) {
        size_t cnt = region_count(rn[m]);
        for (int b = 1; b < 8; b++) {
            int valid = 1;
            for (a = 0; a < 3; a++)
                if (((b >> a) & 1) && pad[a] == 1) valid = 0;
            if (!valid) continue;
            TAKE(b, cnt);
            if (!src->gather(src->ctx, bands[b], m, b, rlo[m], rn[m])) DROP(b);
        }
        /* z, then y, then x: each halves the number of band arrays */
        ptrdiff_t cl[3], cn[3];
        int nb = 8;
        for (a = 0; a < 3; a++) cl[a] = rlo[m][a], cn[a] = rn[m][a];
        for (int ax = 2; ax >= 0; ax--) {
            if (pad[ax] == 1) continue; /* untransformed: only the low band exists */
            ptrdiff_t nl[3] = {cl[0], cl[1], cl[2]}, nn[3] = {cn[0], cn[1], cn[2]};
            nl[ax] = rlo[m - 1][ax], nn[ax] = rn[m - 1][ax];
            size_t ncnt = region_count(nn);
            int half = 1 << ax; /* band bit of this axis */
            for (int b = 0; b < nb; b++) {
                if (b & half) continue;
                if (!bands[b] && !bands[b | half]) continue; /* both zero: the output is zero */
                const int into_out = m == 1 && ax == last_ax; /* then b is 0, the only band left */
                int so = into_out ? -1 : free_slots[--nfree];
                float *o = into_out ? out : scratch_get(scr, so, ncnt);
                if (!o) return wvol_error_set(err, WVOL_ERR_NOMEM, "brick: out of memory");
                synth_axis(o, bands[b], bands[b | half], cl, cn, rlo[m - 1][ax], rn[m - 1][ax], ax,
                           cn[ax] == (ptrdiff_t)wvol__extent(pad[ax], m), src->filter);
                DROP(b);
                DROP(b | half);
                bands[b] = o;
                slot[b] = so;
            }
            for (a = 0; a < 3; a++) cl[a] = nl[a], cn[a] = nn[a];
        }
    }
    if (bands[0] == out) {
        /* synthesised in place */
    } else if (bands[0]) {
        for (size_t i = 0; i < outn; i++) out[i] = (float)bands[0][i];
    } else {
        memset(out, 0, outn * sizeof *out);
    }
    if (back != 0.0)
        for (size_t i = 0; i < outn; i++) out[i] = (float)((double)out[i] + back);
#undef TAKE
#undef DROP
    return WVOL_OK;
}

wvol_status wvol_idwt3_brick(wvol_volume **out, const wvol_coeffs *c, const size_t lo[3], const size_t hi[3],
                             wvol_error *err)
{
    size_t dims[3];
    wvol_volume *v = NULL;
    wvol__coef_source src;
    wvol__brick_scratch scr;
    wvol_status st;
    int a;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_idwt3_brick: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__coeffs_check(c, err));
    WVOL_RETURN_IF(!lo || !hi, err, WVOL_ERR_ARG, "wvol_idwt3_brick: box is NULL");
    dims[0] = c->nx, dims[1] = c->ny, dims[2] = c->nz;
    for (a = 0; a < 3; a++)
        WVOL_RETURN_IF(lo[a] >= hi[a] || hi[a] > dims[a], err, WVOL_ERR_ARG,
                       "wvol_idwt3_brick: box [%zu, %zu) along %c is empty or outside 0..%zu", lo[a], hi[a],
                       "xyz"[a], dims[a]);
    WVOL_FORWARD(wvol_volume_create(&v, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], err));
    wvol__coef_source_of_coeffs(&src, c);
    memset(&scr, 0, sizeof scr);
    st = wvol__idwt3_brick_src(v->data, &src, lo, hi, &scr, err);
    wvol__brick_scratch_free(&scr);
    if (st != WVOL_OK) {
        wvol_volume_destroy(v);
        return st;
    }
    for (a = 0; a < 3; a++) {
        v->spacing[a] = c->spacing[a];
        v->origin[a] = c->origin[a] + c->spacing[a] * (double)lo[a];
    }
    *out = v;
    return WVOL_OK;
}
