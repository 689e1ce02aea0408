/* SPDX-License-Identifier: MIT
 * The reference integrator sampling f^ through the spline tables (wvol_fhat_eval): at a very
 * small step, the converged reference of the spline model (DESIGN.md section 8). */
#include "render_internal.h"

#include <string.h>

typedef struct fhat_ctx {
    const wvol_coeffs *c;
    const wvol_basis *b;
} fhat_ctx;

static double eval_fhat(const void *ctx, const double x[3], double grad[3])
{
    const fhat_ctx *f = ctx;
    return wvol_fhat_eval(f->c, f->b, x, grad);
}

/* No voxels, no brick grid: every sample evaluates f^. */
static const wvol__source_ops fhat_ops = {.eval = eval_fhat};

wvol_status wvol_render_reference_fhat(wvol_image *img, const wvol_coeffs *c, const wvol_basis *b,
                                       const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *params,
                                       wvol_render_stats *stats, wvol_error *err)
{
    wvol__source s;
    fhat_ctx f;
    int a;
    WVOL_RETURN_IF(!c || !c->data || !b, err, WVOL_ERR_ARG, "render: no coefficients or basis tables");
    WVOL_RETURN_IF(b->filter != c->filter, err, WVOL_ERR_ARG, "render: basis tables of %s for coefficients of %s",
                   b->filter ? b->filter->name : "?", c->filter ? c->filter->name : "?");
    memset(&s, 0, sizeof s);
    f.c = c;
    f.b = b;
    s.ops = &fhat_ops;
    s.ctx = &f;
    s.n[0] = c->nx;
    s.n[1] = c->ny;
    s.n[2] = c->nz;
    for (a = 0; a < 3; a++) {
        s.spacing[a] = c->spacing[a];
        s.origin[a] = c->origin[a];
    }
    return wvol__render_sampled(img, &s, cam, tf, params, stats, err);
}
