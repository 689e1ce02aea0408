/* SPDX-License-Identifier: MIT
 * First-pass statistics of a streamed encoder (wvc_stream.h): per-section magnitude
 * histograms filled row by row, and the step they predict, with the checks and bounds
 * of wvol_wvc_encode (wvc_encode.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "codec/wvc_stream.h"
#include "core/alloc.h"
#include "wvc_format.h"
#include "wvc_internal.h"
#include "wvc_quant.h"

/* histogram sets at most (1.4 MiB each at 3 levels): a larger team's further threads take
 * turns in the first set */
enum { SETS_MAX = 16 };

struct wvc_stream_stats {
    wvc_layout L;
    uint64_t *H;      /* sets x nsec x WVC_HBINS: one set of histograms per thread, summed
                         into the first by merge() (counts: the same sums in any order) */
    int sets;
    /* of |c| over everything a set counted, per level (the low-pass cube with the coarsest);
     * [k][0]: over all levels, after merge() */
    uint32_t maxbits[SETS_MAX][WVOL_WVC_MAX_LEVELS + 1];
};

/* Rows y0 .. y1 - 1 of the planes of one transform row of a level (bands first .. last - 1
 * of the layout) into set k. */
static void stats_rows(wvc_stream_stats *s, int k, int level, int first, int last, size_t y0, size_t y1,
                       const wvc2_planes *pl)
{
    uint64_t *H = s->H + (size_t)k * s->L.nsec * WVC_HBINS;
    for (int i = first; i < last; i++) {
        const wvc_band *b = &s->L.sec[i];
        /* a band low along y holds the plane's rows 0 .. ey - 1, one high along y (y then
         * transformed: two halves) rows ey .. 2 ey - 1 */
        const size_t ey = b->ext[1], lo = (b->band & 2) ? ey : 0;
        size_t r0 = y0 > lo ? y0 - lo : 0, r1 = y1 > lo ? y1 - lo : 0;
        r0 = r0 < ey ? r0 : ey;
        r1 = r1 < ey ? r1 : ey;
        if (!b->count || !pl->band[b->band] || r0 >= r1) continue;
        wvol__wvc_slice_hist(H + (size_t)i * WVC_HBINS, pl->band[b->band] + r0 * pl->sy[b->band], b->ext[0], r1 - r0,
                             pl->sy[b->band], &s->maxbits[k][level]);
    }
}

/* Every set's counts added into the first, the others cleared (so a second call adds
 * nothing); the first set is then the pyramid's histograms. */
static const uint64_t *merge(wvc_stream_stats *s)
{
    const size_t n = (size_t)s->L.nsec * WVC_HBINS;
    for (int m = 1; m <= s->L.levels; m++) {
        for (int k = 1; k < s->sets; k++) {
            s->maxbits[0][m] = s->maxbits[k][m] > s->maxbits[0][m] ? s->maxbits[k][m] : s->maxbits[0][m];
            s->maxbits[k][m] = 0;
        }
        s->maxbits[0][0] = s->maxbits[0][m] > s->maxbits[0][0] ? s->maxbits[0][m] : s->maxbits[0][0];
    }
    for (int k = 1; k < s->sets; k++) {
        uint64_t *h = s->H + (size_t)k * n;
        for (size_t i = 0; i < n; i++) s->H[i] += h[i];
        memset(h, 0, n * sizeof *h);
    }
    return s->H;
}

wvol_status wvol__wvc_stream_stats_create(wvc_stream_stats **out, size_t px, size_t py, size_t pz, int levels,
                                          wvol_error *err)
{
    wvc_stream_stats *s;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvc stream statistics: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(levels < 1 || levels > WVOL_WVC_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "wvc stream statistics: levels %d outside 1..%d", levels, WVOL_WVC_MAX_LEVELS);
    s = calloc(1, sizeof *s);
    WVOL_RETURN_IF(!s, err, WVOL_ERR_NOMEM, "wvc stream statistics: out of memory");
    wvol__wvc_layout(&s->L, px, py, pz, levels);
    {
        /* histograms are sparse, but the estimator reads them whole: zeroed here in huge
         * pages, not met later as thousands of untouched 4 KiB pages */
        size_t bytes;
        s->sets = omp_get_max_threads() < SETS_MAX ? omp_get_max_threads() : SETS_MAX;
        if (s->sets < 1) s->sets = 1;
        bytes = (size_t)s->sets * s->L.nsec * WVC_HBINS * sizeof *s->H;
        s->H = wvol__reuse_get(bytes);
        if (s->H) memset(s->H, 0, bytes);
    }
    if (!s->H) {
        free(s);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc stream statistics: out of memory");
    }
    *out = s;
    return WVOL_OK;
}

void wvol__wvc_stream_stats_free(wvc_stream_stats *s)
{
    if (!s) return;
    wvol__reuse_put(s->H);
    free(s);
}

void wvol__wvc_stream_stats_add_rows(wvc_stream_stats *s, int level, size_t y0, size_t y1, const wvc2_planes *pl)
{
    const int first = level == s->L.levels ? 0 : 1 + 7 * (s->L.levels - level);
    const int last = first + (level == s->L.levels ? 8 : 7);
    const int tid = omp_get_thread_num();
    if (tid >= s->sets) {
        /* a team larger than the sets (not made by the pipeline): one at a time in set 0 */
#pragma omp critical(wvc_stream_stats)
        stats_rows(s, 0, level, first, last, y0, y1, pl);
        return;
    }
    stats_rows(s, tid, level, first, last, y0, y1, pl);
}

double wvol__wvc_stream_level_maxabs(wvc_stream_stats *s, int level)
{
    float m;
    if (level < 1 || level > s->L.levels) return 0.0;
    (void)merge(s);
    memcpy(&m, &s->maxbits[0][level], 4);
    return m;
}

double wvol__wvc_stream_predict(wvc_stream_stats *s, double step, double rounding)
{
    wvc_hist_est *e = wvol__wvc_hist_prepare(merge(s), &s->L);
    double v = e ? wvol__wvc_hist_error(e, &s->L, step, rounding) : NAN;
    wvol__wvc_hist_free(e);
    return v;
}

/* The pyramid's max |c| and the smallest step it allows (|q| stays below WVC_QMAX/2 so that
 * the quantiser never clips, as wvol_wvc_encode); 0 when it holds NaN or Inf. */
static int step_range(wvc_stream_stats *s, double *maxabs, double *min_step)
{
    float m;
    (void)merge(s);
    if (s->maxbits[0][0] >= 0x7F800000u) return 0;
    memcpy(&m, &s->maxbits[0][0], 4);
    *maxabs = m;
    *min_step = *maxabs > 0 ? *maxabs / (double)(WVC_QMAX / 2) : WVC_MIN_STEP;
    if (*min_step < WVC_MIN_STEP) *min_step = WVC_MIN_STEP;
    return 1;
}

/* Whether every value dequantised with step d stays within float32 (below WVC_MAX_STEP). */
static int step_fits(double maxabs, double d)
{
    return (floor(maxabs / d + 0.5) + 1.0) * d <= WVC_MAX_STEP;
}

wvol_status wvol__wvc_stream_step(wvc_stream_stats *s, const wvol_wvc_params *p, double target_scale,
                                  double *step, double *maxabs_out, wvol_error *err)
{
    double maxabs, min_step, d;
    WVOL_RETURN_IF(!s || !p || !step, err, WVOL_ERR_ARG, "wvc stream step: NULL argument");
    WVOL_RETURN_IF(!step_range(s, &maxabs, &min_step), err, WVOL_ERR_NONFINITE,
                   "wvc encode: coefficients hold NaN or Inf");
    if (maxabs_out) *maxabs_out = maxabs;
    WVOL_RETURN_IF(!(p->rounding >= 0 && p->rounding <= 0.5), err, WVOL_ERR_ARG,
                   "wvc encode: rounding %g outside [0, 0.5]", p->rounding);
    WVOL_RETURN_IF(!(p->step >= 0) || !isfinite(p->step) || !(p->target_sse >= 0) || !isfinite(p->target_sse) ||
                       (p->step == 0 && p->target_sse <= 0),
                   err, WVOL_ERR_ARG, "wvc encode: give a step > 0 or an error target > 0");
    if (p->step > 0) {
        d = p->step;
        WVOL_RETURN_IF(d > WVC_MAX_STEP, err, WVOL_ERR_ARG, "wvc encode: step %g is above %g", d, WVC_MAX_STEP);
        WVOL_RETURN_IF(d < min_step, err, WVOL_ERR_ARG,
                       "wvc encode: step %g is below %g, the smallest this range allows", d, min_step);
    } else if (maxabs == 0) {
        d = 1.0; /* every coefficient is zero: any step is exact */
    } else {
        wvc_hist_est *e = wvol__wvc_hist_prepare(merge(s), &s->L);
        WVOL_RETURN_IF(!e, err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        d = wvol__wvc_hist_step(e, &s->L, target_scale * p->target_sse, p->rounding, min_step, 4 * maxabs);
        wvol__wvc_hist_free(e);
        if (d > WVC_MAX_STEP) d = WVC_MAX_STEP;
    }
    WVOL_RETURN_IF(!step_fits(maxabs, d), err, WVOL_ERR_NONFINITE,
                   "wvc encode: coefficients reach %g: with step %g a dequantised value could exceed float32's "
                   "3.4e38; scale the volume down (or give a smaller step)",
                   maxabs, d);
    *step = d;
    return WVOL_OK;
}

/* ---- exact passes over a pyramid held as planes (wvol__wvc_stream_refine) ---- */

typedef struct planes_pass {
    const wvc_layout *L;
    const wvc2_planes *planes; /* [level]: the level's bands' first rows, z rows sz apart */
    double f;
    work_item *items;          /* one per (section, z row) */
    int nitems;
    sec_stats *part, *st;      /* per item, per section */
} planes_pass;

/* The z rows of section b the planes hold (0: an empty band, or one the planes leave out). */
static size_t section_rows(const wvc_band *b, const wvc2_planes *planes, const size_t *nz)
{
    if (!b->count || !planes[b->level].band[b->band]) return 0;
    return b->ext[2] < nz[b->level] ? b->ext[2] : nz[b->level];
}

static double planes_error(void *ctx, double step)
{
    planes_pass *c = ctx;
    double e = 0;
    int i;
#pragma omp parallel for schedule(dynamic, 4) if (c->nitems > 8)
    for (i = 0; i < c->nitems; i++) {
        const wvc_band *b = &c->L->sec[c->items[i].sec];
        const wvc2_planes *pl = &c->planes[b->level];
        const float *base = pl->band[b->band] + c->items[i].z0 * pl->sz[b->band];
        wvol__wvc_rows_stats(&c->part[i], base, NULL, b->ext[0], b->ext[1], 1, pl->sy[b->band], pl->sz[b->band], step,
                             wvol__wvc_sec_rounding(b, c->f), 0);
    }
    memset(c->st, 0, (size_t)c->L->nsec * sizeof *c->st);
    /* in item order: the same sums for any thread count */
    for (i = 0; i < c->nitems; i++) wvol__wvc_sec_merge(&c->st[c->items[i].sec], &c->part[i]);
    for (i = 0; i < c->L->nsec; i++) e += wvol__wvc_sec_error(&c->st[i], step, NULL, NULL);
    return e;
}

wvol_status wvol__wvc_stream_refine(wvc_stream_stats *s, const wvc2_planes *planes, const size_t *nz,
                                    const wvol_wvc_params *p, double *step, int *passes, wvol_error *err)
{
    planes_pass c;
    wvc_hist_est *est;
    double maxabs, min_step, d, last = 0;
    size_t n = 0;
    WVOL_RETURN_IF(!s || !planes || !nz || !p || !step || !passes, err, WVOL_ERR_ARG,
                   "wvc stream refine: NULL argument");
    *passes = 0;
    if (p->step > 0 || !(p->target_sse > 0)) return WVOL_OK;
    /* all zero: any step; NaN or Inf: wvol__wvc_stream_step refused them */
    if (!step_range(s, &maxabs, &min_step) || !(maxabs > 0)) return WVOL_OK;
    memset(&c, 0, sizeof c);
    c.L = &s->L, c.planes = planes, c.f = p->rounding;
    for (int i = 0; i < s->L.nsec; i++) n += section_rows(&s->L.sec[i], planes, nz);
    c.items = malloc((n ? n : 1) * sizeof *c.items);
    c.part = malloc((n ? n : 1) * sizeof *c.part);
    c.st = malloc((size_t)s->L.nsec * sizeof *c.st);
    est = wvol__wvc_hist_prepare(merge(s), &s->L);
    if (!c.items || !c.part || !c.st || !est) {
        free(c.items), free(c.part), free(c.st), wvol__wvc_hist_free(est);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
    }
    for (int i = 0; i < s->L.nsec; i++)
        for (size_t z = 0, zn = section_rows(&s->L.sec[i], planes, nz); z < zn; z++, c.nitems++)
            c.items[c.nitems].sec = i, c.items[c.nitems].z0 = z, c.items[c.nitems].z1 = z + 1;
    d = wvol__wvc_refine_step(est, &s->L, p->rounding, p->target_sse, maxabs, min_step, planes_error, &c, passes,
                              &last);
    wvol__wvc_hist_free(est);
    free(c.items), free(c.part), free(c.st);
    WVOL_RETURN_IF(!isfinite(d), err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
    /* the bounds wvol__wvc_stream_step keeps: else the histograms' guess stands */
    if (d <= WVC_MAX_STEP && step_fits(maxabs, d)) *step = d;
    return WVOL_OK;
}
