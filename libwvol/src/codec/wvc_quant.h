/* SPDX-License-Identifier: MIT
 * The .wvc encoder's quantiser, shared by its files (not installed): per-section
 * statistics for a step (wvc_quant.c), the choice of the step from an error target
 * (wvc_quant.c) and the spending of the budget the step leaves (wvc_slack.c). */
#ifndef WVOL_CODEC_WVC_QUANT_H
#define WVOL_CODEC_WVC_QUANT_H

#include <stdint.h>

#include "wvc_internal.h"

/* Per-section sums for one step: the zeroed coefficients' energy, and for
 * |q| = 1 and |q| >= 2 the count, sum and sum of squares of r = |c|/step - |q|. */
typedef struct sec_stats {
    double zero_sse, energy;
    double s1, ss1, s2, ss2;
    uint64_t n1, n2;
} sec_stats;

/* s += a row's sums t[8] as wvol__wvc_row_stats gives them. */
static inline void wvol__wvc_sec_add_row(sec_stats *s, const double t[8])
{
    s->zero_sse += t[0];
    s->energy += t[1];
    s->s1 += t[2];
    s->ss1 += t[3];
    s->s2 += t[4];
    s->ss2 += t[5];
    s->n1 += (uint64_t)t[6];
    s->n2 += (uint64_t)t[7];
}

/* d += a. */
static inline void wvol__wvc_sec_merge(sec_stats *d, const sec_stats *a)
{
    d->zero_sse += a->zero_sse;
    d->energy += a->energy;
    d->s1 += a->s1;
    d->ss1 += a->ss1;
    d->s2 += a->s2;
    d->ss2 += a->ss2;
    d->n1 += a->n1;
    d->n2 += a->n2;
}

/* Work items: slabs of about 64K coefficients of one section each. */
typedef struct work_item {
    int sec;
    size_t z0, z1;
} work_item;

/* The work items covering every non-empty section (malloc'ed; NULL: out of memory). */
work_item *wvol__wvc_work_items(const wvc_layout *L, int *count);
/* Per-section sums over the whole pyramid for one step, in one parallel pass; Q (may
 * be NULL) receives the quantised values (*qzero: Q is all zero, cleared once
 * written). Returns 0, or -1 when out of memory. */
int wvol__wvc_all_stats(sec_stats *st, const wvc_layout *L, const float *C, int32_t *Q, double step, double f,
                        int *qzero);
/* One row of n coefficients quantised into qrow (may be NULL), its sums into t[8]:
 * zeroed energy, energy, sum r and r^2 over |q| = 1, the same over |q| >= 2, the
 * counts of |q| = 1 and of |q| >= 2 (exact in double). The same arithmetic as the
 * whole-pyramid pass, for the v2 writer's rows. Returns the row's largest |c| (a zero
 * as +0). qrow may be the row itself (a quantisation in place: each value is read
 * before its q is written). */
float wvol__wvc_row_stats(double t[8], const float *row, int32_t *qrow, size_t n, double step, double f);
/* The sums of nz planes of ey rows of ex coefficients (row y of plane z at c + y sy + z sz)
 * into st, each row as wvol__wvc_row_stats sums it, added in z then y order; q (may be NULL)
 * receives the quantised values at the same offsets, written only where a group has a
 * non-zero when `sparse` (q is known to be all zero). */
void wvol__wvc_rows_stats(sec_stats *st, const float *c, int32_t *q, size_t ex, size_t ey, size_t nz, size_t sy,
                          size_t sz, double step, double f, int sparse);
/* The same without the x86-64-v4 kernel (its intrinsics), for the tests that compare them:
 * row_kernel as compiled for the running CPU's level. */
float wvol__wvc_row_stats_generic(double t[8], const float *row, int32_t *qrow, size_t n, double step, double f);
void wvol__wvc_rows_stats_generic(sec_stats *st, const float *c, int32_t *q, size_t ex, size_t ey, size_t nz,
                                  size_t sy, size_t sz, double step, double f, int sparse);
/* The offsets as stored (float32) and the section's exact squared error with them. */
double wvol__wvc_sec_error(const sec_stats *st, double step, float *d1, float *d2);
/* A section's rounding offset: the low-pass cube rounds to nearest, details with f. */
static inline double wvol__wvc_sec_rounding(const wvc_band *b, double f) { return b->band == 0 ? 0.5 : f; }
/* The exact squared error of the quantisation with a step, by a pass over the coefficients
 * (NAN when out of memory). */
typedef double (*wvc_step_error_fn)(void *ctx, double step);
/* The largest step whose exact error stays within [0.985, 1] x target (PSNR at most 0.066 dB
 * above it): the step the histograms (est, over layout L) predict for 0.9925 x target, one
 * exact pass; if that misses, the prediction again, scaled by what the pass measured against
 * what was predicted at that step, then secant iterations on exact passes (rarely needed).
 * *iters counts the passes, *last is the step of the last one. NAN when a pass fails. */
double wvol__wvc_refine_step(wvc_hist_est *est, const wvc_layout *L, double f, double target, double maxabs,
                             double min_step, wvc_step_error_fn error, void *ctx, int *iters, double *last);
/* The largest step whose error stays within [0.985, 1] x target (wvol__wvc_refine_step over
 * the in-memory pyramid C); on return Q and st hold the quantisation with it. NAN when out of
 * memory. */
double wvol__wvc_choose_step(const wvc_layout *L, const float *C, const uint64_t *H, double target, double f,
                             double maxabs, double min_step, sec_stats *st, int *iters, int32_t *Q, int *qzero);
/* Zeroes the cheapest |q| = 1 coefficients within `slack` and updates the sums in st
 * to match; returns how many. */
uint64_t wvol__wvc_spend_slack(const wvc_layout *L, const float *C, int32_t *Q, double step, double f,
                               const float *d1, double slack, sec_stats *st);

#endif
