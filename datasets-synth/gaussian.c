/* SPDX-License-Identifier: MIT
 * The Gaussian density of the paper's Fig. 15 (Gross et al., "volume data analysis
 * and visualization in wavelet space": a Gaussian voxelised at 32^3, iso-value 0.5)
 * and a non-symmetric sum of anisotropic Gaussians. */
#include <math.h>
#include <string.h>

#include "synth_internal.h"

/* ---- gaussian ------------------------------------------------------------ */

typedef struct gauss_ctx {
    double inv2s2; /* 1 / (2 sigma^2) */
} gauss_ctx;

static void gauss_row(const void *vctx, const synth_grid *g, size_t j, size_t k, float *row,
                      float *lab)
{
    const gauss_ctx *c = vctx;
    double uy = synth_u(g, 1, j), uz = synth_u(g, 2, k), ryz = uy * uy + uz * uz;
    size_t i;
    (void)lab;
    for (i = 0; i < g->nx; i++) {
        double ux = synth_u(g, 0, i);
        row[i] = (float)exp(-(ux * ux + ryz) * c->inv2s2);
    }
}

wvol_status wvol__synth_plan_gaussian(synth_plan *pl, const wvol_synth_params *p, wvol_error *err)
{
    gauss_ctx *c;
    double sigma;
    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "synth gaussian: NULL parameters");
    sigma = p->sigma == 0 ? 0.25 : p->sigma;
    WVOL_RETURN_IF(!(sigma > 0) || !isfinite(sigma), err, WVOL_ERR_ARG,
                   "synth gaussian: sigma %g must be finite and positive", p->sigma);
    WVOL_FORWARD(wvol__synth_geometry(&pl->g, p, NULL, "gaussian", err));
    WVOL_RETURN_IF(!(c = wvol__synth_plan_ctx(pl, sizeof *c, gauss_row)), err, WVOL_ERR_NOMEM,
                   "synth gaussian: out of memory");
    c->inv2s2 = 1.0 / (2.0 * sigma * sigma);
    return WVOL_OK;
}

wvol_status wvol_synth_gaussian(wvol_volume **out, const wvol_synth_params *p, wvol_error *err)
{
    return wvol__synth_whole(out, NULL, wvol__synth_plan_gaussian, p, "gaussian", err);
}

/* ---- blobs --------------------------------------------------------------- */

enum { MAX_BLOBS = 64 };

typedef struct blob {
    double c[3];     /* centre, normalised */
    double q[3][3];  /* quadratic form: exponent = -(u-c)^T Q (u-c) */
    double amp;
    double reach2;   /* squared distance beyond which the term is < 1e-9 * amp: skipped */
} blob;

typedef struct blobs_ctx {
    int n;
    blob b[MAX_BLOBS];
} blobs_ctx;

static void blobs_row(const void *vctx, const synth_grid *g, size_t j, size_t k, float *row,
                      float *lab)
{
    const blobs_ctx *c = vctx;
    double uy = synth_u(g, 1, j), uz = synth_u(g, 2, k);
    size_t i;
    int n;
    (void)lab;
    for (i = 0; i < g->nx; i++) {
        double ux = synth_u(g, 0, i), f = 0;
        for (n = 0; n < c->n; n++) {
            const blob *b = &c->b[n];
            double d0 = ux - b->c[0], d1 = uy - b->c[1], d2 = uz - b->c[2], e;
            if (d0 * d0 + d1 * d1 + d2 * d2 > b->reach2) continue;
            e = b->q[0][0] * d0 * d0 + b->q[1][1] * d1 * d1 + b->q[2][2] * d2 * d2 +
                2.0 * (b->q[0][1] * d0 * d1 + b->q[0][2] * d0 * d2 + b->q[1][2] * d1 * d2);
            f += b->amp * exp(-e);
        }
        row[i] = (float)f;
    }
}

/* A random rotation from a random unit quaternion (Shoemake's method). */
static void random_rotation(wvol_rng *r, double R[3][3])
{
    double u1 = wvol_rng_uniform(r), u2 = 6.283185307179586 * wvol_rng_uniform(r),
           u3 = 6.283185307179586 * wvol_rng_uniform(r);
    double a = sqrt(1 - u1), b = sqrt(u1);
    double w = a * sin(u2), x = a * cos(u2), y = b * sin(u3), z = b * cos(u3);
    R[0][0] = 1 - 2 * (y * y + z * z);
    R[0][1] = 2 * (x * y - z * w);
    R[0][2] = 2 * (x * z + y * w);
    R[1][0] = 2 * (x * y + z * w);
    R[1][1] = 1 - 2 * (x * x + z * z);
    R[1][2] = 2 * (y * z - x * w);
    R[2][0] = 2 * (x * z - y * w);
    R[2][1] = 2 * (y * z + x * w);
    R[2][2] = 1 - 2 * (x * x + y * y);
}

wvol_status wvol__synth_plan_blobs(synth_plan *pl, const wvol_synth_params *p, wvol_error *err)
{
    blobs_ctx *c;
    wvol_rng rng;
    int n, a, b2, m, count;
    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "synth blobs: NULL parameters");
    count = p->count == 0 ? 5 : p->count;
    WVOL_RETURN_IF(count < 1 || count > MAX_BLOBS, err, WVOL_ERR_ARG,
                   "synth blobs: count %d must be from 1 to %d", p->count, MAX_BLOBS);
    WVOL_FORWARD(wvol__synth_geometry(&pl->g, p, NULL, "blobs", err));
    WVOL_RETURN_IF(!(c = wvol__synth_plan_ctx(pl, sizeof *c, blobs_row)), err, WVOL_ERR_NOMEM,
                   "synth blobs: out of memory");
    c->n = count;
    wvol_rng_seed(&rng, p->seed ^ 0xB10B5ull);
    for (n = 0; n < c->n; n++) {
        blob *b = &c->b[n];
        double R[3][3], s[3], smax = 0;
        for (a = 0; a < 3; a++) b->c[a] = -0.45 + 0.9 * wvol_rng_uniform(&rng);
        b->amp = 0.3 + 0.7 * wvol_rng_uniform(&rng);
        for (a = 0; a < 3; a++) {
            s[a] = 0.06 + 0.16 * wvol_rng_uniform(&rng);
            if (s[a] > smax) smax = s[a];
        }
        random_rotation(&rng, R);
        /* Q = R diag(1 / (2 s^2)) R^T */
        for (a = 0; a < 3; a++)
            for (b2 = 0; b2 < 3; b2++) {
                double q = 0;
                for (m = 0; m < 3; m++) q += R[a][m] * R[b2][m] / (2.0 * s[m] * s[m]);
                b->q[a][b2] = q;
            }
        /* exp(-r^2 / (2 smax^2)) < 1e-9 beyond r^2 = 2 smax^2 * 20.7 */
        b->reach2 = 2.0 * smax * smax * 20.8;
    }
    return WVOL_OK;
}

wvol_status wvol_synth_blobs(wvol_volume **out, const wvol_synth_params *p, wvol_error *err)
{
    return wvol__synth_whole(out, NULL, wvol__synth_plan_blobs, p, "blobs", err);
}
