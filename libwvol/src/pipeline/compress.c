/* SPDX-License-Identifier: MIT */
/* The compression pipeline (wvol/compress.h): transform -> selection -> store, and the
 * quantiser's error-target rule for .wvc files. */
#include "wvol/compress.h"

#include "core/clock.h"
#include "core/status_internal.h"
#include "store/store_build.h"
#include "pipeline/compress_floor.h"
#include "wavelet/wavelet_bricks.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


void wvol_compress_params_default(wvol_compress_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->wavelet = "db2";
    p->levels = 0;
    p->for_file = 0;
    wvol_select_params_default(&p->select);
    p->build_store = 1;
    wvol_store_params_default(&p->store);
    p->quant.psnr = 0;
    p->quant.share = 0.02;
    p->quant.step = 0;
    p->quant.rounding = -1;
    p->quant.coder = WVOL_WVC_CODER_AUTO;
}

void wvol_compressed_free(wvol_compressed *c)
{
    if (!c) return;
    wvol_store_destroy(c->store);
    wvol_store_destroy(c->residual);
    wvol_selection_destroy(c->selection);
    wvol_coeffs_destroy(c->coeffs);
    memset(c, 0, sizeof *c);
}

int wvol_compress_levels(const wvol_volume *v, const wvol_compress_params *p)
{
    int maxl, want;
    if (!v) return 0;
    maxl = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    if (maxl < 1) return 0;
    want = p && p->levels ? p->levels : p && p->for_file ? WVOL_COMPRESS_LEVELS_FILE : WVOL_COMPRESS_LEVELS_STORE;
    return maxl < want ? maxl : want;
}

/* Selection (zeroing what it drops) and the store. A selection that keeps everything stores
 * the nonzero coefficients only: a decoded file's quantised zeros are most of it. */
static wvol_status select_and_store(wvol_compressed *out, const wvol_volume *v, const wvol_compress_params *p,
                                    wvol_error *err)
{
    double t0 = wvol__now();
    wvol_coeffs *dropped = NULL;
    wvol_status s = wvol_select(&out->selection, out->coeffs, &p->select, v, &out->report, err);
    if (s == WVOL_OK && p->build_residual) s = wvol_coeffs_clone(&dropped, out->coeffs, err);
    if (s == WVOL_OK) s = wvol_selection_apply(out->selection, out->coeffs, err);
    out->seconds_select = wvol__now() - t0;
    t0 = wvol__now();
    if (s == WVOL_OK && p->build_store) {
        const wvol_selection *sel = out->report.kept < out->report.total ? out->selection : NULL;
        /* wvol_select has read every coefficient (refusing NaN and Inf) */
        s = wvol__store_build_tested(&out->store, out->coeffs, sel, &p->store, err);
    }
    if (s == WVOL_OK && dropped) {
        /* what the selection zeroed: the original minus the kept (exact: each entry is either
         * the original value or 0); its nonzero entries, as |c| on the majorants of |B|, are
         * the residual store whose X-ray is the per-pixel error bound */
        size_t i, n = dropped->px * dropped->py * dropped->pz;
        for (i = 0; i < n; i++)
            if (out->coeffs->data[i] != 0.0f) dropped->data[i] = 0.0f;
        wvol_store_params rp = p->store;
        rp.majorant = 1;
        s = wvol__store_build_tested(&out->residual, dropped, NULL, &rp, err);
    }
    wvol_coeffs_destroy(dropped);
    out->seconds_store = wvol__now() - t0;
    return s;
}

wvol_status wvol_compress(wvol_compressed *out, const wvol_volume *v, const wvol_compress_params *params,
                          wvol_error *err)
{
    wvol_compress_params p;
    const wvol_filter *f = NULL;
    wvol_status s;
    int maxl;
    double t0;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "compress: no output");
    memset(out, 0, sizeof *out);
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "compress: no volume");
    if (params) p = *params;
    else wvol_compress_params_default(&p);
    if (wvol_compress_wavelet_is_auto(p.wavelet)) {
        /* the trial reads the volume through a source, as the streamed path reads its own:
         * the same sample, so the same choice */
        wvol_source *src = NULL;
        wvol_wavelet_choice wc;
        WVOL_FORWARD(wvol_source_of_volume(&src, v, err));
        s = wvol_compress_choose_wavelet(&wc, src, &p, err);
        wvol_source_destroy(src);
        if (s != WVOL_OK) return s;
        p.wavelet = wc.wavelet;
    }
    WVOL_FORWARD(wvol_filter_get(&f, p.wavelet && p.wavelet[0] ? p.wavelet : "db2", err));
    maxl = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    WVOL_RETURN_IF(maxl < 1, err, WVOL_ERR_DIMS, "compress: a %zux%zux%zu volume cannot be transformed", v->nx,
                   v->ny, v->nz);
    if (p.levels == 0) p.levels = wvol_compress_levels(v, &p);
    WVOL_RETURN_IF(p.levels < 1 || p.levels > maxl, err, WVOL_ERR_ARG,
                   "compress: levels %d: a %zux%zux%zu volume allows 1..%d", p.levels, v->nx, v->ny, v->nz, maxl);
    WVOL_RETURN_IF(p.select.drop_levels < 0 || p.select.drop_levels >= p.levels, err, WVOL_ERR_ARG,
                   "compress: drop_levels %d: must be below the levels (%d)", p.select.drop_levels, p.levels);
    wvol_volume_range(v, &out->value_min, &out->value_max, NULL);
    out->value_min += 0.0, out->value_max += 0.0; /* a zero extreme as +0, as the streamed path */
    out->levels = p.levels;

    t0 = wvol__now();
    s = wvol_dwt3(&out->coeffs, v, f, p.levels, err);
    out->seconds_transform = wvol__now() - t0;
    if (s == WVOL_OK) s = select_and_store(out, v, &p, err);
    if (s != WVOL_OK) wvol_compressed_free(out);
    return s;
}

wvol_status wvol_compress_coeffs(wvol_compressed *out, wvol_coeffs **c, const wvol_compress_params *params,
                                 wvol_error *err)
{
    wvol_compress_params p;
    wvol_status s;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "compress: no output");
    memset(out, 0, sizeof *out);
    WVOL_RETURN_IF(!c || !*c, err, WVOL_ERR_ARG, "compress: no coefficients");
    out->coeffs = *c;
    *c = NULL;
    if (params) p = *params;
    else wvol_compress_params_default(&p);
    out->levels = out->coeffs->levels;
    s = select_and_store(out, NULL, &p, err);
    if (s != WVOL_OK) wvol_compressed_free(out);
    return s;
}

/* The smallest RMSE a .wvc error target may ask for: 64 spacings of float32's subnormal
 * grid (2^-149). Near it the decoded volume's own float32 rounding (the dequantised values and
 * the inverse transform's sums, each rounded to that grid) is no longer small against the
 * target: at 21 spacings (50 dB over a range of 1e-38) the measured PSNR missed by 0.02 dB. */
#define FLOAT_RMSE (64.0 * 1.401298464324817e-45)

wvol_status wvol_compress_wvc_params(wvol_wvc_params *wp, const wvol_compress_quant *q, double dropped,
                                     double voxels, double vmin, double vmax, wvol_error *err)
{
    WVOL_RETURN_IF(!wp || !q, err, WVOL_ERR_ARG, "compress: no parameters");
    WVOL_RETURN_IF(!(q->step >= 0) || !isfinite(q->step), err, WVOL_ERR_ARG,
                   "compress: quantiser step %g (must be finite and >= 0)", q->step);
    WVOL_RETURN_IF(q->rounding > 0.5 || isnan(q->rounding), err, WVOL_ERR_ARG,
                   "compress: rounding %g (must be in [0, 0.5], or < 0 for the default)", q->rounding);
    WVOL_RETURN_IF(q->format_version < 0 || q->format_version > 2, err, WVOL_ERR_ARG,
                   "compress: format version %d (must be 1, 2 or 0 for the default)", q->format_version);
    WVOL_RETURN_IF(!(q->psnr >= 0), err, WVOL_ERR_ARG, "compress: PSNR %g (must be > 0, or 0 for none)", q->psnr);
    WVOL_RETURN_IF(!(dropped >= 0) || !isfinite(dropped), err, WVOL_ERR_ARG,
                   "compress: dropped energy %g (must be finite and >= 0)", dropped);
    WVOL_RETURN_IF(!(voxels >= 1) || !isfinite(voxels), err, WVOL_ERR_ARG,
                   "compress: voxel count %g (must be finite and >= 1)", voxels);
    WVOL_RETURN_IF(!isfinite(vmin) || !isfinite(vmax) || vmin > vmax, err, WVOL_ERR_ARG,
                   "compress: value range [%g, %g] (must be finite, min <= max)", vmin, vmax);
    wvol_wvc_params_default(wp);
    wp->value_min = vmin;
    wp->value_max = vmax;
    wp->dropped_energy = dropped;
    wp->coder = q->coder;
    wp->version = q->format_version;
    wp->tile = q->tile;
    wp->tile_z = q->tile_z;
    if (q->rounding >= 0) wp->rounding = q->rounding;
    wp->step = q->step;
    if (q->step > 0) return WVOL_OK;
    if (q->psnr > 0) {
        double budget = wvol_wvc_sse_for_psnr(q->psnr, voxels, vmin, vmax);
        WVOL_RETURN_IF(!(vmax > vmin), err, WVOL_ERR_ARG,
                       "compress: the volume is constant; PSNR %g (peak = range) is undefined: give a quantiser step",
                       q->psnr);
        WVOL_RETURN_IF(dropped >= budget, err, WVOL_ERR_ARG,
                       "compress: the dropped levels alone lose more than PSNR %g allows (%.2f dB)", q->psnr,
                       wvol_wvc_psnr(dropped, voxels, vmin, vmax));
        wp->target_sse = budget - dropped;
        WVOL_RETURN_IF(!(wp->target_sse >= voxels * FLOAT_RMSE * FLOAT_RMSE), err, WVOL_ERR_ARG,
                       "compress: PSNR %g over the range %g asks for an RMSE of %.3g, below what float32 can hold "
                       "(%.3g: 64 subnormal spacings of 1.4e-45); give a lower PSNR or scale the volume up",
                       q->psnr, vmax - vmin, sqrt(wp->target_sse / voxels), FLOAT_RMSE);
    } else {
        /* a share of the dropped energy; never below what 120 dB would allow */
        double floor_sse = wvol_wvc_sse_for_psnr(120, voxels, vmin, vmax);
        WVOL_RETURN_IF(!(q->share > 0 && q->share <= 1), err, WVOL_ERR_ARG,
                       "compress: quantiser share %g (must be in (0, 1])", q->share);
        wp->target_sse = q->share * dropped;
        if (!(wp->target_sse > floor_sse)) wp->target_sse = floor_sse;
        /* a (near-)constant volume: 1e-12 of the peak's square (an absolute floor would zero
         * every coefficient of a volume of values ~1e-10, and keep noise at 1e10), and never
         * below what float32 can hold (FLOAT_RMSE) */
        {
            double peak = fmax(fabs(vmin), fabs(vmax)), tiny = peak > 0 ? 1e-12 * peak * peak : 1e-12;
            if (!(wp->target_sse > tiny)) wp->target_sse = tiny;
            if (!(wp->target_sse > voxels * FLOAT_RMSE * FLOAT_RMSE)) wp->target_sse = voxels * FLOAT_RMSE * FLOAT_RMSE;
        }
    }
    return WVOL_OK;
}

wvol_status wvol__compress_float_floors(wvol_wvc_params *wp, const wvol_compress_quant *q, const wvol_filter *f,
                                        int levels, const size_t pad[3], double voxels, double vmin, double vmax,
                                        wvol_error *err)
{
    double floor_sse;
    if (!(q->psnr > 0) || q->step > 0 || !(wp->target_sse > 0)) return WVOL_OK;
    floor_sse = wvol__f32_floor_sse(fmax(fabs(vmin), fabs(vmax)), voxels, f, levels, pad);
    if (!(floor_sse >= 1e-3 * wp->target_sse)) return WVOL_OK;
    WVOL_RETURN_IF(floor_sse > 0.5 * wp->target_sse, err, WVOL_ERR_ARG,
                   "compress: PSNR %g: the volume's values reach %g over a range of %g, where float32 alone rounds "
                   "the decoded samples and the low-pass coefficients to about %.1f dB; give a lower PSNR, or "
                   "compress the volume less its offset",
                   q->psnr, fmax(fabs(vmin), fabs(vmax)), vmax - vmin, wvol_wvc_psnr(floor_sse, voxels, vmin, vmax));
    wp->target_sse -= floor_sse;
    return WVOL_OK;
}

wvol_status wvol_compress_encode(void **buf, size_t *size, const wvol_compressed *c, const wvol_compress_params *params,
                                 wvol_wvc_report *report, wvol_error *err)
{
    wvol_compress_params p;
    wvol_wvc_params wp;
    double voxels;
    WVOL_RETURN_IF(!buf || !size || !c || !c->coeffs, err, WVOL_ERR_ARG, "compress: nothing to encode");
    if (params) p = *params;
    else wvol_compress_params_default(&p);
    voxels = (double)c->coeffs->nx * (double)c->coeffs->ny * (double)c->coeffs->nz;
    WVOL_FORWARD(wvol_compress_wvc_params(&wp, &p.quant, c->report.energy_dropped, voxels, c->value_min,
                                          c->value_max, err));
    {
        const size_t pad[3] = {c->coeffs->px, c->coeffs->py, c->coeffs->pz};
        WVOL_FORWARD(wvol__compress_float_floors(&wp, &p.quant, c->coeffs->filter, c->coeffs->levels, pad, voxels,
                                                 c->value_min, c->value_max, err));
    }
    return wvol_wvc_encode(buf, size, c->coeffs, &wp, report, err);
}
