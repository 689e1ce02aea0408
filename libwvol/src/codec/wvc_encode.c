/* SPDX-License-Identifier: MIT
 * .wvc encoder: dead-zone quantiser with the step chosen from an error target,
 * centroid reconstruction offsets, per-section coding, header and section table.
 * Based on: Sullivan 1996 (dead-zone uniform quantiser with centroid
 * reconstruction for Laplacian sources); Parseval for orthonormal transforms
 * (the coefficient error is the volume error, DESIGN.md section 5). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#include "wvc_format.h"
#include "wvc_internal.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void wvol_wvc_params_default(wvol_wvc_params *p)
{
    memset(p, 0, sizeof *p);
    p->rounding = WVC_DEFAULT_ROUNDING;
    p->coder = WVOL_WVC_CODER_AUTO;
    p->zstd_level = 3;
}

static size_t band_extent(size_t pa, int level, int high)
{
    if (pa == 1) return high ? 0 : 1;
    return pa >> level;
}

void wvol__wvc_layout(wvc_layout *L, size_t px, size_t py, size_t pz, int levels)
{
    const size_t p[3] = {px, py, pz};
    int m, l, a, s = 0;
    memset(L, 0, sizeof *L);
    L->levels = levels;
    memcpy(L->p, p, sizeof p);
    /* low-pass cube */
    L->sec[s].level = levels;
    L->sec[s].band = 0;
    for (a = 0; a < 3; a++) L->sec[s].ext[a] = band_extent(p[a], levels, 0);
    s++;
    for (m = levels; m >= 1; m--)
        for (l = 1; l <= 7; l++, s++) {
            wvc_band *b = &L->sec[s];
            b->level = m;
            b->band = l;
            b->has_parent = m < levels;
            for (a = 0; a < 3; a++) {
                int high = (l >> a) & 1;
                b->ext[a] = band_extent(p[a], m, high);
                b->off[a] = (high && p[a] > 1) ? p[a] >> m : 0;
                if (b->has_parent) {
                    b->pext[a] = band_extent(p[a], m + 1, high);
                    b->poff[a] = (high && p[a] > 1) ? p[a] >> (m + 1) : 0;
                }
            }
        }
    L->nsec = s;
    for (s = 0; s < L->nsec; s++) {
        wvc_band *b = &L->sec[s];
        b->count = (uint64_t)b->ext[0] * b->ext[1] * b->ext[2];
        if (b->count == 0) b->has_parent = 0;
    }
}

/* Per-section sums for one step: the zeroed coefficients' energy, and for
 * |q| = 1 and |q| >= 2 the count, sum and sum of squares of r = |c|/step - |q|. */
typedef struct sec_stats {
    double zero_sse, energy;
    double s1, ss1, s2, ss2;
    uint64_t n1, n2;
} sec_stats;

static double sec_rounding(const wvc_band *b, double f) { return b->band == 0 ? 0.5 : f; }

/* Sums over slices [z0, z1) of one band (serial; the caller spreads work items over
 * threads). Q (may be NULL) receives the quantised values; with `sparse` Q is known
 * to be all zero and only groups with a non-zero are written (the pages of an
 * all-zero stretch are never touched: fresh pages cost more to write than to read).
 *
 * Most coefficients quantise to zero: a group of eight whose |c| all lie below the
 * dead zone (float test, with a margin far above rounding) only adds c^2 to the
 * zeroed energy; the others get the full arithmetic, in double. Explicit vectors
 * (AVX2 in the x86-64-v3 clone; GCC will not reorder a double reduction itself),
 * branch-free selects; counts are summed as doubles within a row (exact below
 * 2^53); the scalar tail does the same arithmetic. */
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

WVOL__CLONES static void rows_stats(sec_stats *st, const float *C, int32_t *Q, const size_t p[3], const wvc_band *b,
                               double step, double f, size_t z0, size_t z1, int sparse)
{
    const double inv = 1.0 / step, qmax = WVC_QMAX;
    /* below this |c| / step + f < 1 for sure: the relative margin 1e-6 dwarfs float rounding */
    const float thr = (float)((1.0 - f) * step * (1.0 - 1e-6));
    const wvc_v8f vthr = {thr, thr, thr, thr, thr, thr, thr, thr};
    const wvc_v8i absmask = {INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX, INT32_MAX};
    double zero_sse = 0, energy = 0, s1 = 0, ss1 = 0, s2 = 0, ss2 = 0;
    uint64_t n1 = 0, n2 = 0;
    size_t x, y, z, ex = b->ext[0];
    for (z = z0; z < z1; z++)
        for (y = 0; y < b->ext[1]; y++) {
            size_t base = wvc_index(p, b, 0, y, z);
            const float *restrict row = C + base;
            int32_t *restrict qrow = Q ? Q + base : NULL;
            row_acc A;
            wvc_v4d zq = {0, 0, 0, 0};
            double t[8];
            memset(&A, 0, sizeof A);
            for (x = 0; x + 8 <= ex; x += 8) {
                wvc_v8f cf;
                wvc_v8i hit;
                wvc_v4l h4;
                memcpy(&cf, row + x, sizeof cf);
                hit = (wvc_v8f)((wvc_v8i)cf & absmask) >= vthr;
                h4 = (wvc_v4l)hit;
                if (!(h4[0] | h4[1] | h4[2] | h4[3])) {
                    /* all zero: only their energy */
                    wvc_v4f lo = {cf[0], cf[1], cf[2], cf[3]}, hi = {cf[4], cf[5], cf[6], cf[7]};
                    wvc_v4d dl = __builtin_convertvector(lo, wvc_v4d), dh = __builtin_convertvector(hi, wvc_v4d);
                    zq += dl * dl + dh * dh;
                    if (qrow && !sparse) memset(qrow + x, 0, 8 * sizeof *qrow);
                    continue;
                }
                {
                    wvc_v4f lo = {cf[0], cf[1], cf[2], cf[3]}, hi = {cf[4], cf[5], cf[6], cf[7]};
                    quad_stats(&A, lo, inv, f, qrow ? qrow + x : NULL, sparse);
                    quad_stats(&A, hi, inv, f, qrow ? qrow + x + 4 : NULL, sparse);
                }
            }
            memset(t, 0, sizeof t);
            for (int k = 0; k < 4; k++) {
                t[0] += A.rz[k] + zq[k], t[1] += A.re[k] + zq[k], t[2] += A.r1[k], t[3] += A.rr1[k];
                t[4] += A.r2[k], t[5] += A.rr2[k], t[6] += A.c1[k], t[7] += A.c2[k];
            }
            for (; x < ex; x++) {
                double c = row[x], ac = fabs(c), a = ac * inv, tt = a + f;
                double q = (double)(int32_t)(tt < qmax ? tt : qmax), r = a - q, cc = c * c;
                t[1] += cc;
                if (q == 0) t[0] += cc;
                else if (q == 1) t[2] += r, t[3] += r * r, t[6] += 1;
                else t[4] += r, t[5] += r * r, t[7] += 1;
                if (qrow && (!sparse || q != 0)) qrow[x] = c < 0 ? -(int32_t)q : (int32_t)q;
            }
            zero_sse += t[0];
            energy += t[1];
            s1 += t[2];
            ss1 += t[3];
            s2 += t[4];
            ss2 += t[5];
            n1 += (uint64_t)t[6];
            n2 += (uint64_t)t[7];
        }
    memset(st, 0, sizeof *st);
    st->zero_sse = zero_sse;
    st->energy = energy;
    st->s1 = s1;
    st->ss1 = ss1;
    st->s2 = s2;
    st->ss2 = ss2;
    st->n1 = n1;
    st->n2 = n2;
}
#undef SEL

/* Work items: slabs of about 64K coefficients of one section each. */
typedef struct work_item {
    int sec;
    size_t z0, z1;
} work_item;

static work_item *work_items(const wvc_layout *L, int *count)
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

/* Per-section sums over the whole pyramid in one parallel pass; Q as in rows_stats
 * (*qzero: Q is all zero, cleared once written). */
static int all_stats(sec_stats *st, const wvc_layout *L, const float *C, int32_t *Q, double step, double f,
                     int *qzero)
{
    int n = 0, i, sparse = Q && *qzero;
    work_item *w = work_items(L, &n);
    sec_stats *part;
    if (!w) return -1;
    part = malloc((n ? n : 1) * sizeof *part);
    if (!part) {
        free(w);
        return -1;
    }
#pragma omp parallel for schedule(dynamic, 1) if (n > 2)
    for (i = 0; i < n; i++)
        rows_stats(&part[i], C, Q, L->p, &L->sec[w[i].sec], step, sec_rounding(&L->sec[w[i].sec], f), w[i].z0,
                   w[i].z1, sparse);
    if (Q) *qzero = 0;
    memset(st, 0, (size_t)L->nsec * sizeof *st);
    for (i = 0; i < n; i++) {
        sec_stats *d = &st[w[i].sec], *a = &part[i];
        d->zero_sse += a->zero_sse;
        d->energy += a->energy;
        d->s1 += a->s1;
        d->ss1 += a->ss1;
        d->s2 += a->s2;
        d->ss2 += a->ss2;
        d->n1 += a->n1;
        d->n2 += a->n2;
    }
    free(part);
    free(w);
    return 0;
}

/* The offsets as stored (float32) and the section's exact squared error with them. */
static double sec_error(const sec_stats *st, double step, float *d1, float *d2)
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

static double total_error(const wvc_layout *L, const float *C, double step, double f, sec_stats *st, int32_t *Q,
                          int *qzero)
{
    double e = 0;
    int s;
    if (all_stats(st, L, C, Q, step, f, qzero)) return NAN;
    for (s = 0; s < L->nsec; s++) e += sec_error(&st[s], step, NULL, NULL);
    return e;
}

/* Finds the largest step (to within ~0.2%) whose error lies in [accept, 1] x target:
 * secant iterations on log(error) against log(step) from d0, each an exact pass
 * that also quantises into Q. *last: the step of the last pass (what Q holds). */
static double search_step(const wvc_layout *L, const float *C, double target, double f, double maxabs,
                          double min_step, sec_stats *st, int *iters, double d0, double accept, int32_t *Q,
                          int *qzero, double *last)
{
    double e0, d1, e1, best_ok = 0, best_bad = INFINITY, slope = 2.0;
    int it;
    if (d0 < min_step) d0 = min_step;
    if (maxabs > 0 && d0 > 4 * maxabs) d0 = 4 * maxabs;
    e0 = total_error(L, C, d0, f, st, Q, qzero);
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
        e1 = total_error(L, C, d1, f, st, Q, qzero);
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

/* ---- using the rest of the error budget ----------------------------------------
 * The error is a staircase in the step: when many coefficients share a magnitude
 * (piecewise-constant volumes), the largest step that meets the target can leave a
 * good part of the budget unused. The slack is spent by zeroing |q| = 1 detail
 * coefficients, those whose removal adds the least error first. Zeroing one adds
 * c^2 - (|c| - rec)^2 = 2 |c| rec - rec^2 (rec = (1 + d1) step, per section), which
 * grows with |c|: so each section gets a threshold, found from a histogram of the
 * |q| = 1 coefficients' position u = |c|/step - (1 - f) in [0, 1) (SLACK_BINS bins
 * with count, sum |c| and sum c^2, so a bin's added error is exact): bins are taken
 * cheapest first (mean added error per coefficient) while they fit, then the next
 * bin in part, coefficient by coefficient in index order (serial, so the result does
 * not depend on threads). No sort of the coefficients; one pass to count, one to
 * zero, and a scan of one section for the partial bin. */
#define SLACK_BINS 256

typedef struct slack_bin {
    double n, sa, sa2;
} slack_bin;

static inline int slack_index(double ac, double inv, double f)
{
    int k = (int)((ac * inv - (1.0 - f)) * SLACK_BINS);
    return k < 0 ? 0 : k >= SLACK_BINS ? SLACK_BINS - 1 : k;
}

static int slack_cmp(const void *pa, const void *pb)
{
    const double *a = pa, *b = pb;
    return a[0] < b[0] ? -1 : a[0] > b[0] ? 1 : (a[1] < b[1] ? -1 : a[1] > b[1]);
}

/* Zeroes the cheapest |q| = 1 coefficients within `slack` and updates the sums in
 * st to match (no further pass over the data); returns how many. */
static uint64_t spend_slack(const wvc_layout *L, const float *C, int32_t *Q, double step, double f, const float *d1,
                            double slack, sec_stats *st)
{
    int nw = 0, i, s, k, cut[WVOL_WVC_MAX_SECTIONS], part_sec = -1, part_bin = 0;
    work_item *w = work_items(L, &nw);
    slack_bin(*part)[SLACK_BINS] = NULL, (*tot)[SLACK_BINS] = NULL;
    double(*order)[2] = NULL, acc = 0;
    const double inv = 1.0 / step;
    uint64_t zeroed = 0;
    size_t nord = 0, j;
    if (!w || nw == 0) goto out;
    part = calloc((size_t)nw, sizeof *part);
    tot = calloc((size_t)L->nsec, sizeof *tot);
    order = malloc((size_t)L->nsec * SLACK_BINS * sizeof *order);
    if (!part || !tot || !order) goto out;
#pragma omp parallel for schedule(dynamic, 1) if (nw > 2)
    for (i = 0; i < nw; i++) {
        const wvc_band *b = &L->sec[w[i].sec];
        size_t x, y, z;
        if (b->band == 0) continue;
        for (z = w[i].z0; z < w[i].z1; z++)
            for (y = 0; y < b->ext[1]; y++) {
                size_t base = wvc_index(L->p, b, 0, y, z);
                for (x = 0; x < b->ext[0]; x++) {
                    int32_t q = Q[base + x];
                    if (q == 1 || q == -1) {
                        double ac = fabs((double)C[base + x]);
                        slack_bin *h = &part[i][slack_index(ac, inv, f)];
                        h->n += 1;
                        h->sa += ac;
                        h->sa2 += ac * ac;
                    }
                }
            }
    }
    for (i = 0; i < nw; i++) /* in work-item order: the sums do not depend on threads */
        for (k = 0; k < SLACK_BINS; k++) {
            tot[w[i].sec][k].n += part[i][k].n;
            tot[w[i].sec][k].sa += part[i][k].sa;
            tot[w[i].sec][k].sa2 += part[i][k].sa2;
        }
    for (s = 0; s < L->nsec; s++) {
        const double rec = (1.0 + d1[s]) * step;
        cut[s] = 0;
        for (k = 0; k < SLACK_BINS; k++)
            if (tot[s][k].n > 0) {
                order[nord][0] = (2 * rec * tot[s][k].sa - tot[s][k].n * rec * rec) / tot[s][k].n;
                order[nord][1] = (double)(s * SLACK_BINS + k);
                nord++;
            }
    }
    qsort(order, nord, sizeof *order, slack_cmp); /* at most 7 x levels x SLACK_BINS entries */
    /* whole bins, cheapest first, while they fit (within a section the order is that
     * of |c|, so each section's taken bins are a prefix) */
    for (j = 0; j < nord; j++) {
        int sk = (int)order[j][1];
        const slack_bin *h;
        double rec, add;
        s = sk / SLACK_BINS;
        k = sk % SLACK_BINS;
        h = &tot[s][k];
        rec = (1.0 + d1[s]) * step;
        add = 2 * rec * h->sa - h->n * rec * rec;
        if (acc + add > slack) break;
        acc += add;
        cut[s] = k + 1;
        /* the sums rows_stats made for these coefficients move to the zeroed energy */
        st[s].zero_sse += h->sa2;
        st[s].n1 -= (uint64_t)h->n;
        st[s].s1 -= inv * h->sa - h->n;
        st[s].ss1 -= inv * inv * h->sa2 - 2 * inv * h->sa + h->n;
    }
    if (j < nord) { /* the bin that did not fit, in part: its coefficients in index order */
        int sk = (int)order[j][1];
        part_sec = sk / SLACK_BINS;
        part_bin = sk % SLACK_BINS;
    }
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : zeroed) if (nw > 2)
    for (i = 0; i < nw; i++) {
        const wvc_band *b = &L->sec[w[i].sec];
        const int c = cut[w[i].sec];
        size_t x, y, z;
        if (b->band == 0 || c == 0) continue;
        for (z = w[i].z0; z < w[i].z1; z++)
            for (y = 0; y < b->ext[1]; y++) {
                size_t base = wvc_index(L->p, b, 0, y, z);
                for (x = 0; x < b->ext[0]; x++) {
                    int32_t q = Q[base + x];
                    if ((q == 1 || q == -1) && slack_index(fabs((double)C[base + x]), inv, f) < c) {
                        Q[base + x] = 0;
                        zeroed++;
                    }
                }
            }
    }
    if (part_sec >= 0) {
        const double rec = (1.0 + d1[part_sec]) * step;
        double left = slack - acc;
        sec_stats *d = &st[part_sec];
        for (i = 0; i < nw && left > 0; i++) {
            const wvc_band *b = &L->sec[w[i].sec];
            size_t x, y, z;
            if (w[i].sec != part_sec) continue;
            for (z = w[i].z0; z < w[i].z1 && left > 0; z++)
                for (y = 0; y < b->ext[1] && left > 0; y++) {
                    size_t base = wvc_index(L->p, b, 0, y, z);
                    for (x = 0; x < b->ext[0]; x++) {
                        int32_t q = Q[base + x];
                        double ac, e, r;
                        if (q != 1 && q != -1) continue;
                        ac = fabs((double)C[base + x]);
                        if (slack_index(ac, inv, f) != part_bin) continue;
                        e = 2 * ac * rec - rec * rec;
                        if (e > left) {
                            left = 0;
                            break;
                        }
                        left -= e;
                        Q[base + x] = 0;
                        zeroed++;
                        r = ac * inv - 1.0; /* as rows_stats summed it */
                        d->zero_sse += ac * ac;
                        d->n1--;
                        d->s1 -= r;
                        d->ss1 -= r * r;
                    }
                }
        }
    }
out:
    free(order);
    free(tot);
    free(part);
    free(w);
    return zeroed;
}

/* The largest step whose error stays within [0.985, 1] x target (PSNR at most
 * 0.066 dB above the target): the step the histograms predict for 0.9925 x target
 * (no pass over the data); an exact pass that also quantises into Q; if that misses,
 * the prediction again, scaled by what the pass measured against what was
 * predicted at that step, then secant iterations on exact passes (rarely needed).
 * On return Q and st hold the quantisation with the returned step. */
static double choose_step(const wvc_layout *L, const float *C, const uint64_t *H, double target, double f,
                          double maxabs, double min_step, sec_stats *st, int *iters, int32_t *Q, int *qzero)
{
    const double aim = 0.9925, accept = 0.985;
    double d, e, last = 0;
    wvc_hist_est *est = wvol__wvc_hist_prepare(H, L);
    if (!est) return NAN;
    *iters = 1;
    d = wvol__wvc_hist_step(est, L, aim * target, f, min_step, 4 * maxabs);
    e = total_error(L, C, d, f, st, Q, qzero);
    last = d;
    if (isfinite(e) && !(e <= target && e >= accept * target)) {
        double predicted = wvol__wvc_hist_error(est, L, d, f), k = predicted > 0 && e > 0 ? e / predicted : 1;
        d = wvol__wvc_hist_step(est, L, aim * target / k, f, min_step, 4 * maxabs);
        d = search_step(L, C, target, f, maxabs, min_step, st, iters, d, accept, Q, qzero, &last);
    }
    wvol__wvc_hist_free(est);
    if (!isfinite(e)) return NAN;
    if (isfinite(d) && last != d) {
        (*iters)++;
        if (!isfinite(total_error(L, C, d, f, st, Q, qzero))) return NAN;
    }
    return d;
}

static void header_write(uint8_t *h, const wvol_coeffs *c, const wvol_wvc_params *p, double step,
                         double sse, double energy, uint64_t nonzero, uint64_t payload,
                         const wvc_layout *L, const uint8_t coder[], const uint64_t bytes[],
                         const uint32_t crc[], const sec_stats st[], const float d1[], const float d2[],
                         const double err[])
{
    int s;
    size_t n;
    memset(h, 0, WVC_HEADER_SIZE + (size_t)L->nsec * WVC_SECTION_SIZE + 4);
    memcpy(h, WVC_MAGIC, 8);
    wvc_put_u16(h + 8, WVOL_WVC_FORMAT_VERSION);
    wvc_put_u16(h + 10, 0);
    wvc_put_u32(h + 12, (uint32_t)L->nsec);
    n = strlen(c->filter->name);
    memcpy(h + 16, c->filter->name, n < 15 ? n : 15);
    h[32] = (uint8_t)c->levels;
    wvc_put_u64(h + 40, c->nx);
    wvc_put_u64(h + 48, c->ny);
    wvc_put_u64(h + 56, c->nz);
    wvc_put_u64(h + 64, c->px);
    wvc_put_u64(h + 72, c->py);
    wvc_put_u64(h + 80, c->pz);
    for (s = 0; s < 3; s++) {
        wvc_put_f64(h + 88 + 8 * s, c->spacing[s]);
        wvc_put_f64(h + 112 + 8 * s, c->origin[s]);
    }
    wvc_put_f64(h + 136, p->value_min);
    wvc_put_f64(h + 144, p->value_max);
    wvc_put_f64(h + 152, step);
    wvc_put_f64(h + 160, p->rounding);
    wvc_put_f64(h + 168, sse);
    wvc_put_f64(h + 176, energy);
    wvc_put_f64(h + 184, p->dropped_energy);
    wvc_put_u64(h + 192, nonzero);
    wvc_put_u64(h + 200, payload);
    for (s = 0; s < L->nsec; s++) {
        uint8_t *e = h + WVC_HEADER_SIZE + (size_t)s * WVC_SECTION_SIZE;
        e[0] = (uint8_t)L->sec[s].level;
        e[1] = (uint8_t)L->sec[s].band;
        e[2] = coder[s];
        wvc_put_u32(e + 4, crc[s]);
        wvc_put_u64(e + 8, bytes[s]);
        wvc_put_u64(e + 16, st[s].n1 + st[s].n2);
        wvc_put_f32(e + 24, d1[s]);
        wvc_put_f32(e + 28, d2[s]);
        wvc_put_f64(e + 32, st[s].energy);
        wvc_put_f64(e + 40, err[s]);
    }
    n = WVC_HEADER_SIZE + (size_t)L->nsec * WVC_SECTION_SIZE;
    wvc_put_u32(h + n, (uint32_t)crc32(0L, h, (uInt)n));
}

wvol_status wvol_wvc_encode(void **out, size_t *out_size, const wvol_coeffs *c,
                            const wvol_wvc_params *p, wvol_wvc_report *report, wvol_error *err)
{
    wvc_layout *L = NULL;
    sec_stats *st = NULL;
    int32_t *Q = NULL;
    uint8_t *pay[WVOL_WVC_MAX_SECTIONS] = {0}, coder[WVOL_WVC_MAX_SECTIONS] = {0};
    uint64_t bytes[WVOL_WVC_MAX_SECTIONS] = {0};
    uint32_t crc[WVOL_WVC_MAX_SECTIONS] = {0};
    size_t alt_cabac[WVOL_WVC_MAX_SECTIONS] = {0}, alt_zstd[WVOL_WVC_MAX_SECTIONS] = {0};
    float d1[WVOL_WVC_MAX_SECTIONS], d2[WVOL_WVC_MAX_SECTIONS];
    double serr[WVOL_WVC_MAX_SECTIONS];
    size_t n, hsize, total;
    double step, maxabs = 0, energy = 0, sse = 0, t0, t1, t2;
    uint64_t nonzero = 0, payload = 0;
    int s, iters = 0, failed = 0, searched = 0, bad = 0, qzero = 1;
    uint64_t *H = NULL;
    uint8_t *file;
    wvol_status status = WVOL_OK;
    wvol_wvc_report rep;

    memset(&rep, 0, sizeof rep);
    *out = NULL;
    *out_size = 0;
    WVOL_RETURN_IF(!c || !c->data || !c->filter || !p, err, WVOL_ERR_ARG, "wvc encode: missing input");
    WVOL_RETURN_IF(c->levels < 1 || c->levels > WVOL_WVC_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "wvc encode: levels %d outside 1..%d", c->levels, WVOL_WVC_MAX_LEVELS);
    WVOL_RETURN_IF(!(p->rounding >= 0 && p->rounding <= 0.5), err, WVOL_ERR_ARG,
                   "wvc encode: rounding %g outside [0, 0.5]", p->rounding);
    WVOL_RETURN_IF(!(p->step >= 0) || !isfinite(p->step) || !(p->target_sse >= 0) ||
                       !isfinite(p->target_sse) || (p->step == 0 && p->target_sse <= 0),
                   err, WVOL_ERR_ARG, "wvc encode: give a step > 0 or an error target > 0");
    WVOL_RETURN_IF(!isfinite(p->value_min) || !isfinite(p->value_max) || p->value_min > p->value_max ||
                       !(p->dropped_energy >= 0) || !isfinite(p->dropped_energy),
                   err, WVOL_ERR_ARG, "wvc encode: bad value range or dropped energy");
    for (s = 0; s < 3; s++)
        WVOL_RETURN_IF(!(isfinite(c->spacing[s]) && c->spacing[s] > 0) || !isfinite(c->origin[s]), err,
                       WVOL_ERR_ARG, "wvc encode: spacing must be > 0 and origin finite");
    WVOL_RETURN_IF(!wvol_size_mul3(c->px, c->py, c->pz, sizeof(int32_t), &n), err, WVOL_ERR_DIMS,
                   "wvc encode: padded size overflows");
    n /= sizeof(int32_t);
    L = malloc(sizeof *L);
    st = calloc(WVOL_WVC_MAX_SECTIONS, sizeof *st);
    /* zero pages until written: the quantiser writes only where a row has non-zeros */
    Q = calloc(n, sizeof *Q);
    if (!L || !st || !Q) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        goto done;
    }
    wvol__wvc_layout(L, c->px, c->py, c->pz, c->levels);

    /* range and finiteness of the coefficients, and their magnitude histograms */
    t0 = now();
    H = malloc((size_t)L->nsec * WVC_HBINS * sizeof *H);
    if (!H || wvol__wvc_hist(H, L, c->data, &maxabs, &bad)) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        goto done;
    }
    if (bad) {
        status = wvol_error_set(err, WVOL_ERR_NONFINITE, "wvc encode: coefficients hold NaN or Inf");
        goto done;
    }
    {
        /* |q| stays below WVC_QMAX/2 so that the quantiser never clips */
        double min_step = maxabs > 0 ? maxabs / (double)(WVC_QMAX / 2) : 1e-30;
        if (min_step < 1e-30) min_step = 1e-30;
        if (p->step > 0) {
            step = p->step;
            if (step > WVC_MAX_STEP) {
                status = wvol_error_set(err, WVOL_ERR_ARG, "wvc encode: step %g is above %g", step, WVC_MAX_STEP);
                goto done;
            }
            if (step < min_step) {
                status = wvol_error_set(err, WVOL_ERR_ARG,
                                        "wvc encode: step %g is below %g, the smallest this range allows",
                                        step, min_step);
                goto done;
            }
        } else if (maxabs == 0) {
            step = 1.0; /* every coefficient is zero: any step is exact */
        } else {
            step = choose_step(L, c->data, H, p->target_sse, p->rounding, maxabs, min_step, st, &iters, Q, &qzero);
            if (!isfinite(step)) {
                status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
                goto done;
            }
            if (step > WVC_MAX_STEP) step = WVC_MAX_STEP, searched = 0;
            else searched = 1;
        }
    }
    t1 = now();
    rep.seconds_step = t1 - t0;

    /* quantise, with the exact error per section */
    if (!searched && all_stats(st, L, c->data, Q, step, p->rounding, &qzero)) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        goto done;
    }
    for (s = 0; s < L->nsec; s++) {
        serr[s] = sec_error(&st[s], step, &d1[s], &d2[s]);
        sse += serr[s];
    }
    if (p->step == 0 && sse < 0.99 * p->target_sse) {
        /* spend what the staircase left of the budget, then the exact sums again */
        if (spend_slack(L, c->data, Q, step, p->rounding, d1, p->target_sse - sse, st) > 0) {
            for (sse = 0, s = 0; s < L->nsec; s++) {
                serr[s] = sec_error(&st[s], step, &d1[s], &d2[s]);
                sse += serr[s];
            }
        }
    }
    for (s = 0; s < L->nsec; s++) {
        energy += st[s].energy;
        nonzero += st[s].n1 + st[s].n2;
    }
    t2 = now();
    rep.seconds_quantise = t2 - t1;

    /* code the sections (independent given Q), largest first */
#pragma omp parallel for schedule(dynamic, 1) reduction(| : failed) if (n > 65536)
    for (s = L->nsec - 1; s >= 0; s--) {
        const wvc_band *b = &L->sec[s];
        uint8_t *a = NULL, *z = NULL;
        size_t na = 0, nz = 0;
        if (st[s].n1 + st[s].n2 == 0) {
            coder[s] = WVOL_WVC_CODER_EMPTY; /* a zero low-pass cube too: everything quantised to 0 */
            continue;
        }
        if (p->coder != WVOL_WVC_CODER_ZSTD) {
            if (wvol__wvc_cabac_encode(&a, &na, Q, L->p, b)) failed = 1;
            alt_cabac[s] = na;
        }
        /* auto: both, the smaller wins (zstd's matches beat the contexts on small
         * sections and on some regular ones, e.g. Haar levels 1-2 of smooth volumes) */
        if (p->coder != WVOL_WVC_CODER_CABAC) {
            if (wvol__wvc_zstd_encode(&z, &nz, Q, L->p, b, p->zstd_level)) failed = 1;
            alt_zstd[s] = nz;
        }
        if (a && (!z || na <= nz)) {
            pay[s] = a;
            bytes[s] = na;
            coder[s] = WVOL_WVC_CODER_CABAC;
            free(z);
        } else {
            pay[s] = z;
            bytes[s] = nz;
            coder[s] = WVOL_WVC_CODER_ZSTD;
            free(a);
        }
        if (!pay[s] || bytes[s] == 0) failed = 1;
        else crc[s] = (uint32_t)crc32(0L, pay[s], (uInt)bytes[s]);
    }
    if (failed) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory while coding");
        goto done;
    }
    for (s = 0; s < L->nsec; s++) {
        payload += bytes[s];
        rep.bytes_cabac += alt_cabac[s];
        rep.bytes_zstd += alt_zstd[s];
    }
    hsize = WVC_HEADER_SIZE + (size_t)L->nsec * WVC_SECTION_SIZE + 4;
    total = hsize + (size_t)payload;
    file = malloc(total);
    if (!file) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory (%zu bytes)", total);
        goto done;
    }
    header_write(file, c, p, step, sse, energy, nonzero, payload, L, coder, bytes, crc, st, d1, d2, serr);
    {
        size_t off = hsize;
        for (s = 0; s < L->nsec; s++) {
            if (bytes[s]) memcpy(file + off, pay[s], (size_t)bytes[s]);
            off += (size_t)bytes[s];
        }
    }
    rep.seconds_code = now() - t2;
    rep.step = step;
    rep.step_iterations = iters;
    rep.sse_quant = sse;
    rep.nonzero = nonzero;
    rep.coefficients = n;
    rep.bytes = total;
    if (p->coder == WVOL_WVC_CODER_ZSTD) rep.bytes_cabac = 0;
    if (p->coder == WVOL_WVC_CODER_CABAC) rep.bytes_zstd = 0;
    *out = file;
    *out_size = total;
    if (report) *report = rep;
done:
    for (s = 0; s < WVOL_WVC_MAX_SECTIONS; s++) free(pay[s]);
    free(H);
    free(Q);
    free(st);
    free(L);
    return status;
}

double wvol_wvc_psnr(double sse, double n, double vmin, double vmax)
{
    double range = vmax - vmin;
    if (!(n > 0)) return NAN;
    if (sse <= 0) return INFINITY;
    if (!(range > 0)) return -INFINITY;
    return 20.0 * log10(range / sqrt(sse / n));
}

double wvol_wvc_sse_for_psnr(double psnr, double n, double vmin, double vmax)
{
    double range = vmax - vmin, rmse = range / pow(10.0, psnr / 20.0);
    return rmse * rmse * n;
}

wvol_status wvol_wvc_compare(double *sse, double *maxabs, const wvol_volume *a,
                             const wvol_volume *b, wvol_error *err)
{
    double s = 0, m = 0;
    long i, n;
    WVOL_RETURN_IF(!a || !b || a->nx != b->nx || a->ny != b->ny || a->nz != b->nz, err, WVOL_ERR_DIMS,
                   "compare: volumes differ in size");
    n = (long)wvol_volume_count(a);
#pragma omp parallel for reduction(+ : s) reduction(max : m) schedule(static)
    for (i = 0; i < n; i++) {
        double d = (double)a->data[i] - (double)b->data[i];
        s += d * d;
        if (fabs(d) > m) m = fabs(d);
    }
    if (sse) *sse = s;
    if (maxabs) *maxabs = m;
    return WVOL_OK;
}
