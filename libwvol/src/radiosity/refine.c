/* SPDX-License-Identifier: MIT
 * Link refinement: the paper's ProjectKernel / AskOracle recursion over pairs of quadtree nodes,
 * splitting the larger of the two cells until the oracle calls the kernel smooth (or both are at
 * the finest level); the link's coefficients reuse the oracle's kernel samples.
 * Based on: Gortler et al. 1993 section 7.2-7.3; Hanrahan, Salzman, Aupperle 1991 (refinement). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "radiosity_internal.h"

static wvol_status add_link(struct wvol_radiosity *r, size_t recv, size_t src, double **kout, wvol_error *err)
{
    size_t nbb = (size_t)r->basis.nb * r->basis.nb;
    if (r->nlinks == r->caplinks) {
        size_t cap = r->caplinks ? 2 * r->caplinks : 1024;
        rad_link *l = realloc(r->links, cap * sizeof *l);
        WVOL_RETURN_IF(!l, err, WVOL_ERR_NOMEM, "radiosity: %zu links", cap);
        r->links = l, r->caplinks = cap;
    }
    if (r->nk + nbb > r->capk) {
        size_t cap = r->capk ? 2 * r->capk : 1024 * nbb;
        double *k = realloc(r->k, cap * sizeof *k);
        WVOL_RETURN_IF(!k, err, WVOL_ERR_NOMEM, "radiosity: %zu link coefficients", cap);
        r->k = k, r->capk = cap;
    }
    r->links[r->nlinks].recv = recv;
    r->links[r->nlinks].src = src;
    r->links[r->nlinks].koff = r->nk;
    *kout = r->k + r->nk;
    r->nlinks++;
    r->nk += nbb;
    return WVOL_OK;
}

/* Largest channel of the mean radiosity over a node's cell (brightness refinement). */
static double mean_brightness(const struct wvol_radiosity *r, size_t node, double h)
{
    const rad_basis *b = &r->basis;
    double best = 0;
    for (int c = 0; c < 3; c++) {
        double s = 0;
        for (int a = 0; a < b->nb; a++) s += r->b[(node * 3 + c) * b->nb + a] * b->mean[a / b->m] * b->mean[a % b->m];
        best = fmax(best, fabs(s) / h);
    }
    return best;
}

static wvol_status project_kernel(struct wvol_radiosity *r, size_t pn, size_t qn, wvol_error *err)
{
    const wvol_radiosity_scene *s = r->scene;
    const rad_basis *b = &r->basis;
    rad_cell p, q;
    const rad_patch *pp;
    double rho = 0, weight, est, *kout = NULL;
    int leafp, leafq, smooth, split_p;
    wvol__rad_node_cell(r, pn, &p);
    wvol__rad_node_cell(r, qn, &q);
    pp = &s->p[p.patch];
    if (wvol__rad_kernel_samples(s, b, &p, &q, r->samples, &r->cnt) == 0) return WVOL_OK; /* no transport */
    for (int c = 0; c < 3; c++) rho = fmax(rho, pp->q.reflectance[c]);
    leafp = p.level >= r->par.max_level;
    leafq = q.level >= r->par.max_level;
    if (rho <= 0) {
        /* a black receiver reflects nothing: one link at the level reached carries the light it absorbs
         * (for the energy account) and no solution depends on it, in both modes */
        smooth = 1;
    } else if (r->par.full_matrix) {
        smooth = leafp && leafq;
    } else {
        /* AskOracle: the fit error, in power per unit source radiosity, or weighted by the reflected
         * brightness (the paper's second oracle) */
        weight = r->par.brightness ? rho * mean_brightness(r, qn, q.h) : 1;
        est = wvol__rad_oracle(b, &p, &q, r->samples) *
              wvol__rad_jacobian(pp, p.u0 + 0.5 * p.h, p.v0 + 0.5 * p.h);
        smooth = weight * est <= r->par.epsilon || (leafp && leafq);
    }
    if (smooth) {
        WVOL_FORWARD(add_link(r, pn, qn, &kout, err));
        if ((b->flat || b->kind == WVOL_RADIOSITY_BASIS_HAAR) && wvol__rad_cells_near(s, &p, &q))
            wvol__rad_link_closed_form(s, b, &p, &q, r->samples, kout, &r->cnt);
        else
            wvol__rad_link_quadrature(b, &p, &q, r->samples, kout);
        return WVOL_OK;
    }
    split_p = !leafp && (leafq || pp->area * p.h * p.h >= s->p[q.patch].area * q.h * q.h);
    if (split_p) {
        if (r->nodes[pn].child < 0) WVOL_FORWARD(wvol__rad_split(r, pn, err));
        for (int c = 0; c < 4; c++) WVOL_FORWARD(project_kernel(r, (size_t)r->nodes[pn].child + c, qn, err));
    } else {
        if (r->nodes[qn].child < 0) WVOL_FORWARD(wvol__rad_split(r, qn, err));
        for (int c = 0; c < 4; c++) WVOL_FORWARD(project_kernel(r, pn, (size_t)r->nodes[qn].child + c, err));
    }
    return WVOL_OK;
}

wvol_status wvol__rad_refine_all(struct wvol_radiosity *r, wvol_error *err)
{
    size_t n = r->scene->n;
    r->nlinks = 0;
    r->nk = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++)
            if (i != j) WVOL_FORWARD(project_kernel(r, r->root[i], r->root[j], err));
    return WVOL_OK;
}
