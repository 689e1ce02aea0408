/* SPDX-License-Identifier: MIT
 * .wvc encoder: spending the error budget the quantiser's step leaves unused. */
#include <math.h>
#include <stdlib.h>

#include "wvc_quant.h"

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
uint64_t wvol__wvc_spend_slack(const wvc_layout *L, const float *C, int32_t *Q, double step, double f,
                               const float *d1, double slack, sec_stats *st)
{
    int nw = 0, i, s, k, cut[WVOL_WVC_MAX_SECTIONS], part_sec = -1, part_bin = 0;
    work_item *w = wvol__wvc_work_items(L, &nw);
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
