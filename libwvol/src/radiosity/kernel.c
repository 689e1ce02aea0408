/* SPDX-License-Identifier: MIT
 * The radiosity kernel between two cells: point-to-point samples with visibility, the link
 * coefficients by tensor Gauss-Legendre quadrature or, near the singularity for piecewise-constant
 * sources, by the closed-form point-to-polygon form factor; and the paper's smoothness oracle.
 * Based on: Gortler et al. 1993 sections 7.3-7.4. */
#include <math.h>
#include <string.h>

#include "core/quadrature.h"
#include "radiosity_internal.h"

static void cell_point(const wvol_radiosity_scene *s, const rad_basis *b, const rad_cell *c, int iu, int iv,
                       double x[3])
{
    wvol__rad_point(&s->p[c->patch], c->u0 + c->h * b->qx[iu], c->v0 + c->h * b->qx[iv], x);
}

size_t wvol__rad_kernel_samples(const wvol_radiosity_scene *s, const rad_basis *b, const rad_cell *p,
                                const rad_cell *q, double *k, rad_counters *cnt)
{
    const rad_patch *pp = &s->p[p->patch], *pq = &s->p[q->patch];
    int nq = b->nq, nq2 = nq * nq, sp, tq;
    double xs[RAD_MAXNQ * RAD_MAXNQ][3], yt[RAD_MAXNQ * RAD_MAXNQ][3], jq[RAD_MAXNQ * RAD_MAXNQ];
    size_t nonzero = 0;
    for (sp = 0; sp < nq2; sp++) cell_point(s, b, p, sp / nq, sp % nq, xs[sp]);
    for (tq = 0; tq < nq2; tq++) {
        cell_point(s, b, q, tq / nq, tq % nq, yt[tq]);
        jq[tq] = wvol__rad_jacobian(pq, q->u0 + q->h * b->qx[tq / nq], q->v0 + q->h * b->qx[tq % nq]);
    }
    for (sp = 0; sp < nq2; sp++)
        for (tq = 0; tq < nq2; tq++) {
            double d[3], r2, cp, cq, val = 0;
            d[0] = yt[tq][0] - xs[sp][0], d[1] = yt[tq][1] - xs[sp][1], d[2] = yt[tq][2] - xs[sp][2];
            r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            cp = d[0] * pp->n[0] + d[1] * pp->n[1] + d[2] * pp->n[2];
            cq = -(d[0] * pq->n[0] + d[1] * pq->n[1] + d[2] * pq->n[2]);
            if (cp > 0 && cq > 0 && r2 > 0) {
                val = cp * cq / (M_PI * r2 * r2) * jq[tq];
                cnt->rays++;
                if (wvol__rad_occluded(s, xs[sp], yt[tq], p->patch, q->patch)) val = 0;
            }
            k[sp * nq2 + tq] = val;
            nonzero += val > 0;
        }
    cnt->kernel_evals += (size_t)nq2 * nq2;
    return nonzero;
}

/* Basis function A (2D index au * m + av) at sample sp (iu * nq + iv), times the sample weight. */
static double weighted_phi(const rad_basis *b, int a, int sp)
{
    int iu = sp / b->nq, iv = sp % b->nq;
    return b->phi[a / b->m][iu] * b->phi[a % b->m][iv] * b->qw[iu] * b->qw[iv];
}

/* K[A][B] = h_p sum_s w_s Phi_A(s) G[s][B] for G = the source side already integrated. */
static void receiver_side(const rad_basis *b, const rad_cell *p, const double *g, double *kout)
{
    int nq2 = b->nq * b->nq, A, B, sp;
    for (A = 0; A < b->nb; A++)
        for (B = 0; B < b->nb; B++) {
            double sum = 0;
            for (sp = 0; sp < nq2; sp++) sum += weighted_phi(b, A, sp) * g[sp * b->nb + B];
            kout[A * b->nb + B] = p->h * sum;
        }
}

void wvol__rad_link_quadrature(const rad_basis *b, const rad_cell *p, const rad_cell *q, const double *k,
                               double *kout)
{
    int nq2 = b->nq * b->nq, B, sp, tq;
    double g[RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNB];
    for (sp = 0; sp < nq2; sp++)
        for (B = 0; B < b->nb; B++) {
            double sum = 0;
            for (tq = 0; tq < nq2; tq++) sum += k[sp * nq2 + tq] * weighted_phi(b, B, tq);
            g[sp * b->nb + B] = q->h * sum;
        }
    receiver_side(b, p, g, kout);
}

void wvol__rad_link_closed_form(const wvol_radiosity_scene *s, const rad_basis *b, const rad_cell *p,
                                const rad_cell *q, const double *k, double *kout, rad_counters *cnt)
{
    const rad_patch *pp = &s->p[p->patch], *pq = &s->p[q->patch];
    int nq = b->nq, nq2 = nq * nq, m = b->flat ? b->m : 1, sp, tq, bu, bv, B;
    double g[RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNB];
    /* constant value of the source's basis function B on its box: sqrt(m)^2 / h (Haar: 1 / h) */
    double c = (double)m / q->h;
    memset(g, 0, sizeof g);
    for (sp = 0; sp < nq2; sp++) {
        double x[3], y[3], d[3], frac;
        int vis = 0, geo = 0;
        cell_point(s, b, p, sp / nq, sp % nq, x);
        for (tq = 0; tq < nq2; tq++) {
            cell_point(s, b, q, tq / nq, tq % nq, y);
            for (int a = 0; a < 3; a++) d[a] = y[a] - x[a];
            geo += d[0] * pp->n[0] + d[1] * pp->n[1] + d[2] * pp->n[2] > 0 &&
                   d[0] * pq->n[0] + d[1] * pq->n[1] + d[2] * pq->n[2] < 0;
            vis += k[sp * nq2 + tq] > 0;
        }
        frac = geo ? (double)vis / geo : 1.0;
        /* x behind the source's plane sees none of it */
        for (int a = 0; a < 3; a++) d[a] = x[a] - pq->o[a];
        if (frac <= 0 || d[0] * pq->n[0] + d[1] * pq->n[1] + d[2] * pq->n[2] <= 0) continue;
        for (bu = 0; bu < m; bu++)
            for (bv = 0; bv < m; bv++) {
                double poly[4][3], u0 = q->u0 + q->h * bu / m, v0 = q->v0 + q->h * bv / m, hb = q->h / m;
                wvol__rad_point(pq, u0, v0, poly[0]);
                wvol__rad_point(pq, u0 + hb, v0, poly[1]);
                wvol__rad_point(pq, u0 + hb, v0 + hb, poly[2]);
                wvol__rad_point(pq, u0, v0 + hb, poly[3]);
                B = b->flat ? bu * m + bv : 0;
                g[sp * b->nb + B] = c * frac * wvol__rad_polygon_ff((const double(*)[3])poly, 4, x, pp->n);
                cnt->closed_form_evals++;
            }
    }
    receiver_side(b, p, g, kout);
}

double wvol__rad_oracle(const rad_basis *b, const rad_cell *p, const rad_cell *q, const double *k)
{
    int nq = b->nq, n4 = nq * nq * nq * nq, axis, i, j;
    double r[RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNQ], tmp[RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNQ], est = 0;
    memcpy(r, k, sizeof(double) * n4);
    /* the projection onto tensor polynomials of degree < M: the 1D projector I - resid along each of
     * the four sample axes (u_p, v_p, u_q, v_q); the residual is then k minus it */
    for (axis = 0; axis < 4; axis++) {
        int stride = 1;
        for (i = axis + 1; i < 4; i++) stride *= nq;
        for (i = 0; i < n4; i++) {
            int ci = (i / stride) % nq, base = i - ci * stride;
            double sum = 0;
            for (j = 0; j < nq; j++) sum += ((ci == j) - b->resid[ci][j]) * r[base + j * stride];
            tmp[i] = sum;
        }
        memcpy(r, tmp, sizeof(double) * n4);
    }
    for (i = 0; i < n4; i++) {
        int iup = i / (nq * nq * nq), ivp = (i / (nq * nq)) % nq, iuq = (i / nq) % nq, ivq = i % nq;
        est += b->qw[iup] * b->qw[ivp] * b->qw[iuq] * b->qw[ivq] * fabs(k[i] - r[i]);
    }
    /* the samples hold k J_q; the receiver's area element is about constant over the cell */
    return est * p->h * p->h * q->h * q->h;
}

int wvol__rad_cells_near(const wvol_radiosity_scene *s, const rad_cell *p, const rad_cell *q)
{
    double lo[2][3], hi[2][3], x[3], d2 = 0, size = 0;
    const rad_cell *c[2] = {p, q};
    for (int n = 0; n < 2; n++) {
        double diag = 0;
        for (int k = 0; k < 4; k++) {
            wvol__rad_point(&s->p[c[n]->patch], c[n]->u0 + c[n]->h * (k & 1), c[n]->v0 + c[n]->h * (k >> 1), x);
            for (int a = 0; a < 3; a++) {
                lo[n][a] = k ? fmin(lo[n][a], x[a]) : x[a];
                hi[n][a] = k ? fmax(hi[n][a], x[a]) : x[a];
            }
        }
        for (int a = 0; a < 3; a++) diag += (hi[n][a] - lo[n][a]) * (hi[n][a] - lo[n][a]);
        size = fmax(size, sqrt(diag));
    }
    for (int a = 0; a < 3; a++) {
        double gap = fmax(0, fmax(lo[0][a] - hi[1][a], lo[1][a] - hi[0][a]));
        d2 += gap * gap;
    }
    return d2 < size * size;
}

wvol_status wvol_radiosity_form_factor(const wvol_radiosity_scene *s, size_t i, size_t j, int n, double *out,
                                       wvol_error *err)
{
    double x[16], w[16], sum = 0;
    const rad_patch *pi, *pj;
    WVOL_RETURN_IF(!s || !out, err, WVOL_ERR_ARG, "radiosity form factor: NULL argument");
    WVOL_RETURN_IF(i >= s->n || j >= s->n, err, WVOL_ERR_ARG, "radiosity form factor: patch %zu or %zu of %zu", i, j,
                   s->n);
    WVOL_RETURN_IF(n < 1 || n > 16, err, WVOL_ERR_ARG, "radiosity form factor: n = %d must be in 1..16", n);
    *out = 0;
    if (i == j) return WVOL_OK;
    pi = &s->p[i], pj = &s->p[j];
    wvol__gauss_legendre(n, x, w);
    for (int a = 0; a < n * n; a++) {
        double xs[3], js = wvol__rad_jacobian(pi, x[a / n], x[a % n]) * w[a / n] * w[a % n];
        wvol__rad_point(pi, x[a / n], x[a % n], xs);
        for (int b = 0; b < n * n; b++) {
            double yt[3], d[3], r2, cp, cq;
            wvol__rad_point(pj, x[b / n], x[b % n], yt);
            for (int k = 0; k < 3; k++) d[k] = yt[k] - xs[k];
            r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            cp = d[0] * pi->n[0] + d[1] * pi->n[1] + d[2] * pi->n[2];
            cq = -(d[0] * pj->n[0] + d[1] * pj->n[1] + d[2] * pj->n[2]);
            if (!(cp > 0 && cq > 0 && r2 > 0) || wvol__rad_occluded(s, xs, yt, i, j)) continue;
            sum += js * wvol__rad_jacobian(pj, x[b / n], x[b % n]) * w[b / n] * w[b % n] * cp * cq / (M_PI * r2 * r2);
        }
    }
    *out = sum / pi->area;
    return WVOL_OK;
}
