/* SPDX-License-Identifier: MIT */
/* Local level of detail: a weight w(x) in [0, 1] from Gaussian ellipsoids of
 * interest, evaluated at the support centre of every coefficient position.
 * Based on: Gross, Lippert, Dreger, Koch (wavelet-space volume analysis), Fig. 20. */
#include <math.h>
#include <stdlib.h>

#include "store/store_internal.h"

wvol_status wvol__lod_validate(const wvol_select_params *prm, wvol_error *err)
{
    WVOL_RETURN_IF(prm->n_ellipsoids < 0 || prm->n_ellipsoids > WVOL_LOD_MAX_ELLIPSOIDS, err, WVOL_ERR_ARG,
                   "level of detail: %d ellipsoids (0..%d)", prm->n_ellipsoids, WVOL_LOD_MAX_ELLIPSOIDS);
    WVOL_RETURN_IF(!(prm->lod_floor >= 0.0 && prm->lod_floor <= 1.0), err, WVOL_ERR_ARG,
                   "level of detail: floor weight %g is not in [0, 1]", prm->lod_floor);
    for (int e = 0; e < prm->n_ellipsoids; e++) {
        const wvol_lod_ellipsoid *el = prm->ellipsoids + e;
        for (int a = 0; a < 3; a++) {
            WVOL_RETURN_IF(!isfinite(el->center[a]), err, WVOL_ERR_ARG,
                           "level of detail: ellipsoid %d has a non-finite centre", e);
            WVOL_RETURN_IF(!(el->radii[a] > 0.0) || !isfinite(el->radii[a]), err, WVOL_ERR_ARG,
                           "level of detail: ellipsoid %d radius %g on axis %d must be > 0", e, el->radii[a], a);
        }
        WVOL_RETURN_IF(!(el->power == 0.0 || (el->power >= 1.0 && el->power <= 64.0)), err, WVOL_ERR_ARG,
                       "level of detail: ellipsoid %d power %g (1..64, 0 = 1)", e, el->power);
    }
    return WVOL_OK;
}

/* Normalised squared distance along one axis: the same expression serves the
 * per-axis tables and wvol_lod_weight, so both give bit-identical weights. */
static inline double axis_term(const wvol_lod_ellipsoid *el, int a, double world)
{
    double t = (world - el->center[a]) / el->radii[a];
    return t * t;
}

/* The Gaussian (power 1) is separable: the product of three 1D factors, which
 * the tables below precompute per axis. Other powers go through d^2. Both
 * wvol_lod_weight and the tables use these same expressions. */
static inline int separable(const wvol_lod_ellipsoid *el) { return !(el->power > 1.0); }
static inline double gauss_axis(double t2) { return exp(-0.5 * t2); }
static inline double gauss_d2(const wvol_lod_ellipsoid *el, double d2) { return exp(-0.5 * pow(d2, el->power)); }

double wvol_lod_weight(const wvol_select_params *prm, const double world[3])
{
    double g = 0.0;
    if (!prm || prm->n_ellipsoids <= 0) return 1.0;
    for (int e = 0; e < prm->n_ellipsoids && e < WVOL_LOD_MAX_ELLIPSOIDS; e++) {
        const wvol_lod_ellipsoid *el = prm->ellipsoids + e;
        double t0 = axis_term(el, 0, world[0]), t1 = axis_term(el, 1, world[1]), t2 = axis_term(el, 2, world[2]);
        double ge = separable(el) ? gauss_axis(t0) * gauss_axis(t1) * gauss_axis(t2) : gauss_d2(el, t0 + t1 + t2);
        if (ge > g) g = ge;
    }
    return prm->lod_floor + (1.0 - prm->lod_floor) * g;
}

void wvol__lod_free(wvol__lodw *lw)
{
    for (int m = 0; m <= WVOL_SELECT_MAX_LEVELS; m++) free(lw->w[m]), lw->w[m] = NULL;
}

wvol_status wvol__lod_weights(wvol__lodw *out, const wvol_coeffs *c, const wvol__layout *ly,
                              const wvol_select_params *prm, wvol_error *err)
{
    int ne = prm->n_ellipsoids;
    for (int m = 0; m <= WVOL_SELECT_MAX_LEVELS; m++) out->w[m] = NULL;
    if (ne <= 0) return WVOL_OK;
    for (int m = 1; m <= ly->levels; m++) {
        size_t e0 = wvol__ext(ly, 0, m), e1 = wvol__ext(ly, 1, m), e2 = wvol__ext(ly, 2, m);
        size_t emax = e0 > e1 ? e0 : e1;
        double *t;
        float *w;
        if (e2 > emax) emax = e2;
        w = malloc(e0 * e1 * e2 * sizeof *w);
        t = malloc((size_t)ne * 3 * emax * sizeof *t);
        if (!w || !t) {
            free(w), free(t);
            wvol__lod_free(out);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "level of detail: out of memory");
        }
        out->w[m] = w;
        /* per ellipsoid and axis: the normalised squared distance of each position's
           centre, or for the Gaussian directly its 1D factor */
        for (int e = 0; e < ne; e++)
            for (int a = 0; a < 3; a++) {
                const wvol_lod_ellipsoid *el = prm->ellipsoids + e;
                size_t ea = a == 0 ? e0 : a == 1 ? e1 : e2;
                for (size_t p = 0; p < ea; p++) {
                    double world = c->origin[a] + wvol__support_centre(ly, a, m, p) * c->spacing[a];
                    double tt = axis_term(el, a, world);
                    t[((size_t)e * 3 + a) * emax + p] = separable(el) ? gauss_axis(tt) : tt;
                }
            }
#pragma omp parallel for schedule(static)
        for (long long rr = 0; rr < (long long)e2; rr++) {
            size_t r = (size_t)rr;
            for (size_t q = 0; q < e1; q++) {
                float *row = w + e0 * (q + e1 * r);
                for (size_t p = 0; p < e0; p++) {
                    double g = 0.0;
                    for (int e = 0; e < ne; e++) {
                        const wvol_lod_ellipsoid *el = prm->ellipsoids + e;
                        const double *te = t + (size_t)e * 3 * emax;
                        double ge = separable(el) ? te[p] * te[emax + q] * te[2 * emax + r]
                                                  : gauss_d2(el, te[p] + te[emax + q] + te[2 * emax + r]);
                        if (ge > g) g = ge;
                    }
                    row[p] = (float)(prm->lod_floor + (1.0 - prm->lod_floor) * g);
                }
            }
        }
        free(t);
    }
    return WVOL_OK;
}
