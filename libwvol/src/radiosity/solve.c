/* SPDX-License-Identifier: MIT
 * The wavelet radiosity solver: quadtrees of scaling coefficients, gather over the links, push-pull
 * with the basis's two-scale relation, Jacobi sweeps to convergence, the energy balance, and
 * evaluation of the radiosity from the leaves' basis functions.
 * Based on: Gortler et al. 1993 section 7.2 (pull, push and gather); Hanrahan et al. 1991. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/clock.h"
#include "radiosity_internal.h"

void wvol_radiosity_params_default(wvol_radiosity_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->basis = WVOL_RADIOSITY_BASIS_HAAR;
    p->epsilon = 1e-3;
    p->max_level = 5;
    p->brightness = 0;
    p->refine_passes = 2;
    p->full_matrix = 0;
    p->max_iterations = 200;
    p->tolerance = 1e-7;
}

void wvol__rad_node_cell(const struct wvol_radiosity *r, size_t node, rad_cell *c)
{
    const rad_node *n = &r->nodes[node];
    c->patch = n->patch;
    c->level = n->level;
    c->h = ldexp(1.0, -n->level);
    c->u0 = n->iu * c->h;
    c->v0 = n->iv * c->h;
}

void wvol__rad_push(const rad_basis *b, int cu, int cv, const double *parent, double *child)
{
    int m = b->m;
    for (int a = 0; a < b->nb; a++) {
        double s = 0;
        for (int bb = 0; bb < b->nb; bb++) s += b->push[cu][a / m][bb / m] * b->push[cv][a % m][bb % m] * parent[bb];
        child[a] = s;
    }
}

void wvol__rad_pull(const rad_basis *b, int cu, int cv, const double *child, double *parent)
{
    int m = b->m;
    for (int bb = 0; bb < b->nb; bb++) {
        double s = 0;
        for (int a = 0; a < b->nb; a++) s += b->push[cu][a / m][bb / m] * b->push[cv][a % m][bb % m] * child[a];
        parent[bb] += s;
    }
}

static wvol_status new_node(struct wvol_radiosity *r, size_t patch, int level, int iu, int iv, wvol_error *err)
{
    size_t nb3 = 3 * (size_t)r->basis.nb;
    if (r->nnodes == r->capnodes) {
        size_t cap = r->capnodes ? 2 * r->capnodes : 256;
        rad_node *n = realloc(r->nodes, cap * sizeof *n);
        double *b, *h;
        WVOL_RETURN_IF(!n, err, WVOL_ERR_NOMEM, "radiosity: %zu nodes", cap);
        r->nodes = n;
        b = realloc(r->b, cap * nb3 * sizeof *b);
        WVOL_RETURN_IF(!b, err, WVOL_ERR_NOMEM, "radiosity: %zu nodes", cap);
        r->b = b;
        h = realloc(r->h, cap * nb3 * sizeof *h);
        WVOL_RETURN_IF(!h, err, WVOL_ERR_NOMEM, "radiosity: %zu nodes", cap);
        r->h = h;
        r->capnodes = cap;
    }
    r->nodes[r->nnodes] = (rad_node){patch, level, iu, iv, -1};
    memset(r->b + r->nnodes * nb3, 0, nb3 * sizeof(double));
    memset(r->h + r->nnodes * nb3, 0, nb3 * sizeof(double));
    r->nnodes++;
    return WVOL_OK;
}

wvol_status wvol__rad_split(struct wvol_radiosity *r, size_t node, wvol_error *err)
{
    size_t first = r->nnodes, nb = (size_t)r->basis.nb;
    rad_node n = r->nodes[node];
    for (int c = 0; c < 4; c++) WVOL_FORWARD(new_node(r, n.patch, n.level + 1, 2 * n.iu + (c >> 1), 2 * n.iv + (c & 1), err));
    r->nodes[node].child = (long)first;
    for (int c = 0; c < 4; c++)
        for (int ch = 0; ch < 3; ch++)
            wvol__rad_push(&r->basis, c >> 1, c & 1, r->b + (node * 3 + ch) * nb, r->b + ((first + c) * 3 + ch) * nb);
    return WVOL_OK;
}

/* Integral over a node's cell of basis function A times the area element. */
static double phi_area(const struct wvol_radiosity *r, const rad_cell *c, int a)
{
    const rad_basis *b = &r->basis;
    const rad_patch *p = &r->scene->p[c->patch];
    double s = 0;
    for (int iu = 0; iu < b->nq; iu++)
        for (int iv = 0; iv < b->nq; iv++)
            s += b->qw[iu] * b->qw[iv] * b->phi[a / b->m][iu] * b->phi[a % b->m][iv] *
                 wvol__rad_jacobian(p, c->u0 + c->h * b->qx[iu], c->v0 + c->h * b->qx[iv]);
    return s * c->h;
}

typedef struct pp_state {
    double change, largest;
    double absorbed[3];
} pp_state;

/* Push the gathered irradiance down (plus `down` from the ancestors), form B = E + rho H at the
 * leaves, pull B back up. */
static void push_pull(struct wvol_radiosity *r, size_t node, const double *down, pp_state *st)
{
    const rad_basis *b = &r->basis;
    int nb = b->nb;
    const rad_node *n = &r->nodes[node];
    const rad_patch *p = &r->scene->p[n->patch];
    double tot[3 * RAD_MAXNB], nb_new[3 * RAD_MAXNB];
    rad_cell cell;
    int c, a;
    wvol__rad_node_cell(r, node, &cell);
    for (a = 0; a < 3 * nb; a++) tot[a] = down[a] + r->h[node * 3 * nb + a];
    memset(nb_new, 0, sizeof nb_new);
    if (n->child < 0) {
        for (c = 0; c < 3; c++)
            for (a = 0; a < nb; a++) {
                double e = p->q.emission[c] * cell.h * b->mean[a / b->m] * b->mean[a % b->m];
                nb_new[c * nb + a] = e + p->q.reflectance[c] * tot[c * nb + a];
                st->absorbed[c] += (1 - p->q.reflectance[c]) * tot[c * nb + a] * phi_area(r, &cell, a);
            }
    } else {
        for (int ch = 0; ch < 4; ch++) {
            double cd[3 * RAD_MAXNB];
            size_t child = (size_t)n->child + ch;
            for (c = 0; c < 3; c++) wvol__rad_push(b, ch >> 1, ch & 1, tot + c * nb, cd + c * nb);
            push_pull(r, child, cd, st);
            for (c = 0; c < 3; c++) wvol__rad_pull(b, ch >> 1, ch & 1, r->b + (child * 3 + c) * nb, nb_new + c * nb);
        }
    }
    for (a = 0; a < 3 * nb; a++) {
        double *old = &r->b[node * 3 * nb + a];
        st->change = fmax(st->change, fabs(nb_new[a] - *old));
        st->largest = fmax(st->largest, fabs(nb_new[a]));
        *old = nb_new[a];
    }
}

static void gather(struct wvol_radiosity *r)
{
    const rad_basis *b = &r->basis;
    int nb = b->nb;
    memset(r->h, 0, r->nnodes * 3 * nb * sizeof(double));
    for (size_t l = 0; l < r->nlinks; l++) {
        const rad_link *lk = &r->links[l];
        const double *k = r->k + lk->koff;
        for (int c = 0; c < 3; c++) {
            const double *src = r->b + (lk->src * 3 + c) * nb;
            double *dst = r->h + (lk->recv * 3 + c) * nb;
            for (int a = 0; a < nb; a++) {
                double s = 0;
                for (int bb = 0; bb < nb; bb++) s += k[a * nb + bb] * src[bb];
                dst[a] += s;
            }
        }
    }
}

static pp_state sweep(struct wvol_radiosity *r)
{
    double zero[3 * RAD_MAXNB] = {0};
    pp_state st = {0, 0, {0, 0, 0}};
    for (size_t i = 0; i < r->scene->n; i++) push_pull(r, r->root[i], zero, &st);
    return st;
}

/* Jacobi sweeps until the largest change is within the tolerance; 0 when max_iterations ran out
 * first (a closed scene whose reflectances are 1 never settles: its light bounces forever). */
static int iterate(struct wvol_radiosity *r, wvol_radiosity_stats *stats)
{
    pp_state st = {0, 0, {0, 0, 0}};
    int it, converged = 0;
    for (it = 0; it < r->par.max_iterations; it++) {
        gather(r);
        st = sweep(r);
        if (st.change <= r->par.tolerance * st.largest) {
            it++;
            converged = 1;
            break;
        }
    }
    stats->iterations = it;
    stats->change = st.largest > 0 ? st.change / st.largest : 0;
    memcpy(stats->absorbed, st.absorbed, sizeof st.absorbed);
    return converged;
}

void wvol_radiosity_destroy(wvol_radiosity *r)
{
    if (!r) return;
    free(r->nodes);
    free(r->b);
    free(r->h);
    free(r->root);
    free(r->links);
    free(r->k);
    free(r);
}

wvol_status wvol_radiosity_solve(wvol_radiosity **out, const wvol_radiosity_scene *scene,
                                 const wvol_radiosity_params *par, wvol_radiosity_stats *stats_out, wvol_error *err)
{
    wvol_radiosity *r;
    wvol_radiosity_stats stats;
    wvol_status s = WVOL_OK;
    double t0, t1;
    int pass, passes;
    WVOL_RETURN_IF(!out || !scene || !par, err, WVOL_ERR_ARG, "radiosity: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF((unsigned)par->basis > WVOL_RADIOSITY_BASIS_F3, err, WVOL_ERR_ARG, "radiosity: basis %d unknown",
                   (int)par->basis);
    WVOL_RETURN_IF(!(par->epsilon >= 0) || !isfinite(par->epsilon), err, WVOL_ERR_ARG,
                   "radiosity: epsilon = %g must be finite and >= 0", par->epsilon);
    WVOL_RETURN_IF(par->max_level < 0 || par->max_level > 12, err, WVOL_ERR_ARG,
                   "radiosity: max_level = %d must be in 0..12", par->max_level);
    WVOL_RETURN_IF(par->max_iterations < 1, err, WVOL_ERR_ARG, "radiosity: max_iterations = %d must be >= 1",
                   par->max_iterations);
    WVOL_RETURN_IF(!(par->tolerance >= 0), err, WVOL_ERR_ARG, "radiosity: tolerance = %g must be >= 0",
                   par->tolerance);
    WVOL_RETURN_IF(par->brightness != 0 && par->brightness != 1, err, WVOL_ERR_ARG,
                   "radiosity: brightness = %d must be 0 or 1", par->brightness);
    WVOL_RETURN_IF(par->refine_passes < 1, err, WVOL_ERR_ARG, "radiosity: refine_passes = %d must be >= 1",
                   par->refine_passes);
    r = calloc(1, sizeof *r);
    WVOL_RETURN_IF(!r, err, WVOL_ERR_NOMEM, "radiosity: solution");
    r->scene = scene;
    r->par = *par;
    wvol__rad_basis_init(&r->basis, par->basis);
    r->root = malloc(scene->n * sizeof *r->root);
    if (!r->root) s = wvol_error_set(err, WVOL_ERR_NOMEM, "radiosity: %zu patches", scene->n);
    for (size_t i = 0; s == WVOL_OK && i < scene->n; i++) {
        r->root[i] = r->nnodes;
        s = new_node(r, i, 0, 0, 0, err);
    }
    if (s != WVOL_OK) {
        wvol_radiosity_destroy(r);
        return s;
    }
    memset(&stats, 0, sizeof stats);
    sweep(r); /* B = E on every node, for the brightness oracle */
    passes = par->brightness && !par->full_matrix ? par->refine_passes : 1;
    for (pass = 0; pass < passes; pass++) {
        t0 = wvol__now();
        s = wvol__rad_refine_all(r, err);
        t1 = wvol__now();
        stats.seconds_refine += t1 - t0;
        if (s != WVOL_OK) break;
        if (!iterate(r, &stats))
            s = wvol_error_set(err, WVOL_ERR_NUMERIC,
                               "radiosity: no solution after %d sweeps (the largest change is still %.3g of the "
                               "largest coefficient, above the tolerance %g): a scene whose light is not absorbed "
                               "(reflectances near 1 all round) has none; lower the reflectances or raise "
                               "max_iterations",
                               stats.iterations, stats.change, r->par.tolerance);
        stats.seconds_solve += wvol__now() - t1;
        if (s != WVOL_OK) break;
    }
    if (s != WVOL_OK) {
        wvol_radiosity_destroy(r);
        return s;
    }
    stats.links = r->nlinks;
    stats.link_terms = r->nk;
    stats.nodes = r->nnodes;
    for (size_t i = 0; i < r->nnodes; i++) stats.leaves += r->nodes[i].child < 0;
    stats.kernel_evals = r->cnt.kernel_evals;
    stats.closed_form_evals = r->cnt.closed_form_evals;
    stats.rays = r->cnt.rays;
    for (size_t i = 0; i < scene->n; i++)
        for (int c = 0; c < 3; c++) stats.emitted[c] += scene->p[i].q.emission[c] * scene->p[i].area;
    for (int c = 0; c < 3; c++)
        if (stats.emitted[c] > 0)
            stats.energy_error = fmax(stats.energy_error, fabs(stats.absorbed[c] - stats.emitted[c]) / stats.emitted[c]);
    if (stats_out) *stats_out = stats;
    *out = r;
    return WVOL_OK;
}

/* Radiosity at (u, v) of a patch from its leaf's basis functions. */
static void eval_point(const wvol_radiosity *r, size_t patch, double u, double v, double *rgb)
{
    const rad_basis *b = &r->basis;
    size_t node = r->root[patch];
    rad_cell c;
    double xu, xv, pu[RAD_MAXM], pv[RAD_MAXM];
    u = fmin(fmax(u, 0), 1), v = fmin(fmax(v, 0), 1);
    while (r->nodes[node].child >= 0) {
        wvol__rad_node_cell(r, node, &c);
        node = (size_t)r->nodes[node].child + 2 * (u >= c.u0 + 0.5 * c.h) + (v >= c.v0 + 0.5 * c.h);
    }
    wvol__rad_node_cell(r, node, &c);
    xu = fmin(fmax((u - c.u0) / c.h, 0), 1), xv = fmin(fmax((v - c.v0) / c.h, 0), 1);
    for (int a = 0; a < b->m; a++) pu[a] = wvol__rad_phi(b, a, xu), pv[a] = wvol__rad_phi(b, a, xv);
    for (int ch = 0; ch < 3; ch++) {
        double s = 0;
        for (int a = 0; a < b->nb; a++) s += r->b[(node * 3 + ch) * b->nb + a] * pu[a / b->m] * pv[a % b->m];
        rgb[ch] = s / c.h;
    }
}

wvol_status wvol_radiosity_eval(const wvol_radiosity *r, size_t patch, size_t n, const double *uv, double *rgb,
                                wvol_error *err)
{
    WVOL_RETURN_IF(!r || (n && (!uv || !rgb)), err, WVOL_ERR_ARG, "radiosity eval: NULL argument");
    WVOL_RETURN_IF(patch >= r->scene->n, err, WVOL_ERR_ARG, "radiosity eval: patch %zu of %zu", patch, r->scene->n);
    for (size_t i = 0; i < n; i++) {
        WVOL_RETURN_IF(!isfinite(uv[2 * i]) || !isfinite(uv[2 * i + 1]), err, WVOL_ERR_NONFINITE,
                       "radiosity eval: point %zu is not finite", i);
        eval_point(r, patch, uv[2 * i], uv[2 * i + 1], rgb + 3 * i);
    }
    return WVOL_OK;
}

wvol_status wvol_radiosity_sample(const wvol_radiosity *r, int res, double *rgb, wvol_error *err)
{
    WVOL_RETURN_IF(!r || !rgb, err, WVOL_ERR_ARG, "radiosity sample: NULL argument");
    WVOL_RETURN_IF(res < 1 || res > 65536, err, WVOL_ERR_ARG, "radiosity sample: res = %d must be in 1..65536", res);
    for (size_t i = 0; i < r->scene->n; i++)
        for (int iv = 0; iv < res; iv++)
            for (int iu = 0; iu < res; iu++)
                eval_point(r, i, (iu + 0.5) / res, (iv + 0.5) / res,
                           rgb + (((i * (size_t)res + iv) * res) + iu) * 3);
    return WVOL_OK;
}
