/* SPDX-License-Identifier: MIT
 * First-pass statistics of a streamed encoder (wvc_stream.h): per-section magnitude
 * histograms filled row by row, and the step they predict, with the checks and bounds
 * of wvol_wvc_encode (wvc_encode.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "codec/wvc_stream.h"
#include "core/alloc.h"
#include "wvc_format.h"
#include "wvc_internal.h"

struct wvc_stream_stats {
    wvc_layout L;
    uint64_t *H;      /* nsec x WVC_HBINS */
    uint32_t maxbits; /* of |c| over everything counted */
};

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
        size_t bytes = (size_t)s->L.nsec * WVC_HBINS * sizeof *s->H;
        s->H = wvol__malloc_large(bytes);
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
    free(s->H);
    free(s);
}

void wvol__wvc_stream_stats_add(wvc_stream_stats *s, int level, size_t nz, const wvc2_planes *pl)
{
    /* the level's bands in parallel: each counts into its own section's histogram, so the
     * counts do not depend on the threads; a small row is not worth waking them */
    const int first = level == s->L.levels ? 0 : 1 + 7 * (s->L.levels - level);
    const int last = first + (level == s->L.levels ? 8 : 7);
    const size_t plane = s->L.sec[last - 1].ext[0] * s->L.sec[last - 1].ext[1] * nz;
    uint32_t mb = s->maxbits;
    int i;
#pragma omp parallel for schedule(dynamic, 1) reduction(max : mb) if (plane >= 8192)
    for (i = first; i < last; i++) {
        const wvc_band *b = &s->L.sec[i];
        uint32_t m = 0;
        if (!b->count || !pl->band[b->band]) continue;
        for (size_t k = 0; k < nz; k++)
            wvol__wvc_slice_hist(s->H + (size_t)i * WVC_HBINS, pl->band[b->band] + k * pl->sz[b->band], b->ext[0],
                                 b->ext[1], pl->sy[b->band], &m);
        mb = m > mb ? m : mb;
    }
    s->maxbits = mb;
}

double wvol__wvc_stream_predict(const wvc_stream_stats *s, double step, double rounding)
{
    wvc_hist_est *e = wvol__wvc_hist_prepare(s->H, &s->L);
    double v = e ? wvol__wvc_hist_error(e, &s->L, step, rounding) : NAN;
    wvol__wvc_hist_free(e);
    return v;
}

wvol_status wvol__wvc_stream_step(const wvc_stream_stats *s, const wvol_wvc_params *p, double target_scale,
                                  double *step, double *maxabs_out, wvol_error *err)
{
    double maxabs, min_step, d;
    float m;
    WVOL_RETURN_IF(!s || !p || !step, err, WVOL_ERR_ARG, "wvc stream step: NULL argument");
    WVOL_RETURN_IF(s->maxbits >= 0x7F800000u, err, WVOL_ERR_NONFINITE, "wvc encode: coefficients hold NaN or Inf");
    memcpy(&m, &s->maxbits, 4);
    maxabs = m;
    if (maxabs_out) *maxabs_out = maxabs;
    WVOL_RETURN_IF(!(p->rounding >= 0 && p->rounding <= 0.5), err, WVOL_ERR_ARG,
                   "wvc encode: rounding %g outside [0, 0.5]", p->rounding);
    WVOL_RETURN_IF(!(p->step >= 0) || !isfinite(p->step) || !(p->target_sse >= 0) || !isfinite(p->target_sse) ||
                       (p->step == 0 && p->target_sse <= 0),
                   err, WVOL_ERR_ARG, "wvc encode: give a step > 0 or an error target > 0");
    /* |q| stays below WVC_QMAX/2 so that the quantiser never clips (as wvol_wvc_encode) */
    min_step = maxabs > 0 ? maxabs / (double)(WVC_QMAX / 2) : WVC_MIN_STEP;
    if (min_step < WVC_MIN_STEP) min_step = WVC_MIN_STEP;
    if (p->step > 0) {
        d = p->step;
        WVOL_RETURN_IF(d > WVC_MAX_STEP, err, WVOL_ERR_ARG, "wvc encode: step %g is above %g", d, WVC_MAX_STEP);
        WVOL_RETURN_IF(d < min_step, err, WVOL_ERR_ARG,
                       "wvc encode: step %g is below %g, the smallest this range allows", d, min_step);
    } else if (maxabs == 0) {
        d = 1.0; /* every coefficient is zero: any step is exact */
    } else {
        wvc_hist_est *e = wvol__wvc_hist_prepare(s->H, &s->L);
        WVOL_RETURN_IF(!e, err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        d = wvol__wvc_hist_step(e, &s->L, target_scale * p->target_sse, p->rounding, min_step, 4 * maxabs);
        wvol__wvc_hist_free(e);
        if (d > WVC_MAX_STEP) d = WVC_MAX_STEP;
    }
    WVOL_RETURN_IF((floor(maxabs / d + 0.5) + 1.0) * d > WVC_MAX_STEP, err, WVOL_ERR_NONFINITE,
                   "wvc encode: coefficients reach %g: with step %g a dequantised value could exceed float32's "
                   "3.4e38; scale the volume down (or give a smaller step)",
                   maxabs, d);
    *step = d;
    return WVOL_OK;
}
