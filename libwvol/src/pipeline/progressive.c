/* SPDX-License-Identifier: MIT
 * Progressive rendering (wvol/progressive.h): one transform, then per pass a selection of the
 * largest coefficients through the pipeline (wvol_compress_coeffs, which also builds the
 * residual store of what it dropped), one render through wvol_render and its bound. */
#include "wvol/progressive.h"

#include "core/clock.h"
#include "core/status_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct wvol_progressive {
    wvol_compressed full;           /* every coefficient (no store) */
    wvol_compress_params cp;
    wvol_progressive_params pp;
    size_t lowpass, total, next_count;
    int index, done;
    double t_begin;
};

void wvol_progressive_params_default(wvol_progressive_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->growth = 4.0;
    p->bound = WVOL_BOUND_EXACT;
}

wvol_status wvol_progressive_begin(wvol_progressive **out, const wvol_volume *v, const wvol_compress_params *cp,
                                   const wvol_progressive_params *pp, wvol_error *err)
{
    wvol_progressive *pr;
    wvol_compress_params p;
    wvol_status s;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "progressive: no output");
    *out = NULL;
    pr = calloc(1, sizeof *pr);
    WVOL_RETURN_IF(!pr, err, WVOL_ERR_NOMEM, "progressive: out of memory");
    pr->t_begin = wvol__now();
    if (pp) pr->pp = *pp;
    else wvol_progressive_params_default(&pr->pp);
    if (!(pr->pp.growth > 1.0) || !isfinite(pr->pp.growth)) {
        s = wvol_error_set(err, WVOL_ERR_ARG, "progressive: growth %g: must be a finite number > 1", pr->pp.growth);
        goto fail;
    }
    if (!(pr->pp.max_error >= 0) || !isfinite(pr->pp.max_error) || !(pr->pp.seconds >= 0) ||
        !isfinite(pr->pp.seconds)) {
        s = wvol_error_set(err, WVOL_ERR_ARG, "progressive: the error target (%g) and the budget (%g s) must be "
                                              "finite and >= 0", pr->pp.max_error, pr->pp.seconds);
        goto fail;
    }
    if (pr->pp.bound != WVOL_BOUND_NONE && pr->pp.bound != WVOL_BOUND_EXACT && pr->pp.bound != WVOL_BOUND_COARSE) {
        s = wvol_error_set(err, WVOL_ERR_ARG, "progressive: unknown bound method %d", (int)pr->pp.bound);
        goto fail;
    }
    if (pr->pp.max_error > 0 && pr->pp.bound == WVOL_BOUND_NONE) {
        s = wvol_error_set(err, WVOL_ERR_ARG, "progressive: an error target needs a bound (params.bound)");
        goto fail;
    }
    if (cp) p = *cp;
    else wvol_compress_params_default(&p);
    wvol_select_params_default(&p.select);
    p.build_store = 0;
    p.build_residual = 0;
    if ((s = wvol_compress(&pr->full, v, &p, err)) != WVOL_OK) goto fail;
    pr->cp = p;
    pr->cp.wavelet = NULL; /* the coefficients carry their filter; the caller's string may go */
    pr->total = pr->full.report.total;
    pr->lowpass = pr->full.report.kept_lowpass;
    pr->next_count = pr->lowpass;
    *out = pr;
    return WVOL_OK;
fail:
    wvol_progressive_end(pr);
    return s;
}

static wvol_status one_pass(wvol_progressive *pr, wvol_compressed *c, wvol_image *img, wvol_image *bound,
                            const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *rp,
                            wvol_progressive_pass *pass, wvol_error *err)
{
    wvol_compress_params p = pr->cp;
    wvol_coeffs *copy = NULL;
    wvol_render_source src;
    wvol_render_stats st;
    wvol_render_bound_stats bs;
    WVOL_FORWARD(wvol_coeffs_clone(&copy, pr->full.coeffs, err));
    p.select.mode = WVOL_SELECT_COUNT;
    p.select.count = pr->next_count;
    p.build_store = 1;
    p.build_residual = pr->pp.bound != WVOL_BOUND_NONE;
    WVOL_FORWARD(wvol_compress_coeffs(c, &copy, &p, err));
    src = wvol_render_source_store(c->store);
    WVOL_FORWARD(wvol_render(img, &src, cam, tf, rp, &st, err));
    pass->method = st.method;
    pass->kept = c->report.kept;
    if (pr->pp.bound != WVOL_BOUND_NONE) {
        WVOL_FORWARD((pr->pp.bound == WVOL_BOUND_COARSE ? wvol_render_bound_coarse : wvol_render_bound)(
            bound, c->residual, 0.0, cam, tf, rp, &bs, err));
        pass->bound_max = bs.max;
        pass->bound_mean = bs.mean;
    }
    return WVOL_OK;
}

wvol_status wvol_progressive_next(wvol_progressive *pr, wvol_image *img, wvol_image *bound, const wvol_camera *cam,
                                  const wvol_tf *tf, const wvol_render_params *rp, wvol_progressive_pass *pass,
                                  wvol_error *err)
{
    wvol_compressed c;
    wvol_status s;
    double t0 = wvol__now(), next;
    WVOL_RETURN_IF(!pr || !img || !pass, err, WVOL_ERR_ARG, "progressive: NULL argument");
    WVOL_RETURN_IF(pr->done, err, WVOL_ERR_ARG, "progressive: the last pass has been rendered");
    WVOL_RETURN_IF(pr->pp.bound != WVOL_BOUND_NONE && (!bound || bound->width != img->width || bound->height != img->height), err,
                   WVOL_ERR_ARG, "progressive: the bound image must have the image's size");
    memset(pass, 0, sizeof *pass);
    pass->index = pr->index;
    pass->total = pr->total;
    pass->stop = "";
    memset(&c, 0, sizeof c);
    s = one_pass(pr, &c, img, bound, cam, tf, rp, pass, err);
    wvol_compressed_free(&c);
    if (s != WVOL_OK) return s;
    pass->seconds = wvol__now() - t0;
    pass->elapsed = wvol__now() - pr->t_begin;
    pr->index++;
    next = (double)pr->next_count * pr->pp.growth;
    pr->next_count = next >= (double)pr->total ? pr->total : (size_t)next;
    /* a growth so close to 1 that the count rounds back to itself still adds one coefficient
     * a pass, so that the passes end */
    if (pr->next_count <= pass->kept && pass->kept < pr->total) pr->next_count = pass->kept + 1;
    if (pass->kept >= pr->total) pass->stop = "complete";
    else if (pr->pp.max_error > 0 && pass->bound_max <= pr->pp.max_error) pass->stop = "max-error";
    else if (pr->pp.seconds > 0 && pass->elapsed + pass->seconds * pr->pp.growth > pr->pp.seconds)
        pass->stop = "budget";
    pass->last = pass->stop[0] != '\0';
    pr->done = pass->last;
    return WVOL_OK;
}

void wvol_progressive_end(wvol_progressive *pr)
{
    if (!pr) return;
    wvol_compressed_free(&pr->full);
    free(pr);
}
