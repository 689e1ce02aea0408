/* SPDX-License-Identifier: MIT
 * Projection of a radiance function onto the finest Haar cells, and surface interaction as the
 * product of the Haar projections of the incident radiance and the BRDF (Lewis & Fournier 2002,
 * §6.4, eqs. 22-27). For Haar the delta tensors D^{st}_{jk} vanish unless the supports nest, so
 * at the finest level the product is, per position cell P and reflected direction cell R,
 *   L_r(P, R) = 4 sum_S L_i(P, S) |S| fbar(S, R),
 * fbar the BRDF's mean over S x R (zero for reflected directions outside the unit disc; incident
 * cells already carry their disc share), |S| = 4^-L: the 4 is the
 * Nusselt Jacobian of eq. 5. */
#include "transport_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/quadrature.h"

wvol_status wvol_transport_project(wvol_transport_tree **out, int levels, wvol_transport_radiance_fn fn, void *user,
                                   int g, double threshold, wvol_error *err)
{
    size_t nc = wvol_transport_cells_count(levels);
    double x[8], w[8], h;
    float *cells;
    int n;
    wvol_status s;
    WVOL_RETURN_IF(!out || !fn, err, WVOL_ERR_ARG, "transport project: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(levels < 1 || levels > WVOL_TRANSPORT_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "transport project: levels %d outside 1..%d", levels, WVOL_TRANSPORT_MAX_LEVELS);
    WVOL_RETURN_IF(g < 1 || g > 8, err, WVOL_ERR_ARG, "transport project: %d Gauss points per axis, 1..8 allowed", g);
    wvol__gauss_legendre(g, x, w);
    cells = calloc(3 * nc, sizeof *cells);
    if (!cells) return wvol_error_set(err, WVOL_ERR_NOMEM, "transport project: out of memory for %zu cells", nc);
    n = 1 << levels;
    h = 1.0 / n;
    for (size_t ci = 0; ci < nc; ci++) {
        int m[4];
        size_t r = ci;
        double acc[3] = {0, 0, 0};
        for (int a = 0; a < 4; a++) {
            m[a] = (int)(r % (size_t)n);
            r /= (size_t)n;
        }
        for (int i = 0; i < g * g * g * g; i++) {
            int id[4] = {i % g, i / g % g, i / (g * g) % g, i / (g * g * g)};
            double q[4], wt = 1;
            float rgb[3];
            for (int a = 0; a < 4; a++) {
                q[a] = (m[a] + x[id[a]]) * h;
                wt *= w[id[a]];
            }
            if (fn(user, q, rgb)) {
                free(cells);
                return wvol_error_set(err, WVOL_ERR_ARG, "transport project: the radiance function failed at "
                                                         "(%g, %g, %g, %g)", q[0], q[1], q[2], q[3]);
            }
            for (int c = 0; c < 3; c++) acc[c] += wt * rgb[c];
        }
        for (int c = 0; c < 3; c++) cells[3 * ci + c] = (float)acc[c];
    }
    s = wvol_transport_tree_from_cells(out, cells, levels, threshold, err);
    free(cells);
    return s;
}

static wvol_status brdf_check(const wvol_transport_brdf *b, wvol_error *err)
{
    WVOL_RETURN_IF(!b, err, WVOL_ERR_ARG, "transport reflect: NULL BRDF");
    WVOL_RETURN_IF(b->kind != WVOL_TRANSPORT_BRDF_LAMBERT && b->kind != WVOL_TRANSPORT_BRDF_PHONG, err, WVOL_ERR_ARG,
                   "transport reflect: unknown BRDF kind %d", (int)b->kind);
    for (int c = 0; c < 3; c++) {
        WVOL_RETURN_IF(!(b->kd[c] >= 0) || !isfinite(b->kd[c]), err, WVOL_ERR_ARG,
                       "transport reflect: kd[%d] = %g must be finite and >= 0", c, b->kd[c]);
        WVOL_RETURN_IF(!(b->ks[c] >= 0) || !isfinite(b->ks[c]), err, WVOL_ERR_ARG,
                       "transport reflect: ks[%d] = %g must be finite and >= 0", c, b->ks[c]);
    }
    WVOL_RETURN_IF(!(b->exponent >= 0) || !isfinite(b->exponent), err, WVOL_ERR_ARG,
                   "transport reflect: exponent %g must be finite and >= 0", b->exponent);
    return WVOL_OK;
}

/* M[(S * nd + R) * 3 + c] = 4 |S| fbar(S, R), by a 4-point Gauss rule per axis of each cell */
static float *brdf_matrix(const wvol_transport_brdf *b, int levels)
{
    enum { G = 4 };
    int n = 1 << levels, nd = n * n;
    double x[G], w[G], h = 1.0 / n;
    float *M = malloc((size_t)nd * nd * 3 * sizeof *M);
    if (!M) return NULL;
    wvol__gauss_legendre(G, x, w);
    for (int S = 0; S < nd; S++)
        for (int R = 0; R < nd; R++) {
            double acc[3] = {0, 0, 0};
            for (int a = 0; a < G * G; a++) {
                double mx = 2 * ((S % n + x[a % G]) * h) - 1, my = 2 * ((S / n + x[a / G]) * h) - 1;
                double r2 = mx * mx + my * my, mz = 0, wa = w[a % G] * w[a / G];
                /* the incident cell mean already holds the disc's share (zero radiance outside
                 * it): extend the BRDF there by its rim value rather than count the share twice */
                if (r2 >= 1) mx /= sqrt(r2), my /= sqrt(r2);
                else mz = sqrt(1 - r2);
                for (int bq = 0; bq < G * G; bq++) {
                    double nx = 2 * ((R % n + x[bq % G]) * h) - 1, ny = 2 * ((R / n + x[bq / G]) * h) - 1;
                    double s2 = nx * nx + ny * ny, nz, wt = wa * w[bq % G] * w[bq / G], spec = 0;
                    if (s2 >= 1) continue;
                    nz = sqrt(1 - s2);
                    if (b->kind == WVOL_TRANSPORT_BRDF_PHONG) {
                        double ca = -mx * nx - my * ny + mz * nz; /* mirror of the incident . reflected */
                        spec = ca > 0 ? (b->exponent + 2) / (2 * M_PI) * pow(ca, b->exponent) : 0;
                    }
                    for (int c = 0; c < 3; c++) acc[c] += wt * (b->kd[c] / M_PI + b->ks[c] * spec);
                }
            }
            for (int c = 0; c < 3; c++) M[((size_t)S * nd + R) * 3 + c] = (float)(4 * h * h * acc[c]);
        }
    return M;
}

wvol_status wvol_transport_reflect(wvol_transport_tree **out, const wvol_transport_tree *incident,
                                   const wvol_transport_brdf *brdf, wvol_transport_brdf_at brdf_of, void *user,
                                   double threshold, wvol_error *err)
{
    enum { MAXB = 8 };
    const wvol_transport_brdf *seen[MAXB];
    float *mats[MAXB] = {0}, *li = NULL, *lr = NULL;
    int nb = 0, L, n, nd;
    size_t nc;
    wvol_status s = WVOL_OK;
    WVOL_RETURN_IF(!out || !incident, err, WVOL_ERR_ARG, "transport reflect: NULL argument");
    *out = NULL;
    WVOL_FORWARD(brdf_check(brdf, err));
    L = incident->levels;
    n = 1 << L;
    nd = n * n;
    nc = wvol_transport_cells_count(L);
    li = malloc(3 * nc * sizeof *li);
    lr = calloc(3 * nc, sizeof *lr);
    if (!li || !lr) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "transport reflect: out of memory");
        goto done;
    }
    if ((s = wvol_transport_tree_to_cells(li, 3 * nc, incident, err)) != WVOL_OK) goto done;
    for (int P = 0; P < nd; P++) {
        const wvol_transport_brdf *b = brdf_of ? brdf_of(user, (P % n + 0.5) / n, (P / n + 0.5) / n) : brdf;
        float *M = NULL;
        int bi;
        if (!b) b = brdf;
        for (bi = 0; bi < nb; bi++)
            if (seen[bi] == b) M = mats[bi];
        if (!M) {
            if (nb == MAXB) {
                s = wvol_error_set(err, WVOL_ERR_ARG, "transport reflect: more than %d distinct BRDFs", MAXB);
                goto done;
            }
            if ((s = brdf_check(b, err)) != WVOL_OK) goto done;
            M = mats[nb] = brdf_matrix(b, L);
            seen[nb++] = b;
            if (!M) {
                s = wvol_error_set(err, WVOL_ERR_NOMEM, "transport reflect: out of memory for the BRDF matrix");
                goto done;
            }
        }
        /* cell (mu, mv, mk, ml) = mu + n mv + n^2 (mk + n ml): position P = mu + n mv, direction D */
        for (int S = 0; S < nd; S++) {
            const float *in = li + 3 * ((size_t)P + (size_t)nd * S);
            if (in[0] == 0 && in[1] == 0 && in[2] == 0) continue;
            for (int R = 0; R < nd; R++) {
                float *o = lr + 3 * ((size_t)P + (size_t)nd * R);
                const float *m = M + ((size_t)S * nd + R) * 3;
                for (int c = 0; c < 3; c++) o[c] += in[c] * m[c];
            }
        }
    }
    s = wvol_transport_tree_from_cells(out, lr, L, threshold, err);
done:
    for (int i = 0; i < nb; i++) free(mats[i]);
    free(li);
    free(lr);
    return s;
}
