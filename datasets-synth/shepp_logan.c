/* SPDX-License-Identifier: MIT
 * 3D Shepp-Logan head phantom.
 * Based on: Kak & Slaney, Principles of Computerized Tomographic Imaging (IEEE Press
 * 1988), Table 3.2, with the corrections of the book's errata page (ellipsoid e
 * was printed as a copy of f; g's x centre printed -0.8 for -0.08; h's y centre
 * -0.065 for -0.65). Densities "yu-ye-wang": Yu, Ye & Wang, "Katsevich-type
 * algorithms for variable radius spiral cone-beam CT", Proc. SPIE 5535 (2004).
 *
 * Each ellipsoid: centre (x0, y0, z0), semi-axes (A, B, C) along its own x', y', z'
 * axes, rotated by phi about z (x' points at angle phi from x), density added inside:
 *   x' =  cos(phi) dx + sin(phi) dy,  y' = -sin(phi) dx + cos(phi) dy,  z' = dz,
 *   inside when (x'/A)^2 + (y'/B)^2 + (z'/C)^2 <= 1. */
#include <math.h>
#include <string.h>
#include <strings.h>

#include "synth_internal.h"

enum { SL_N = 10 };

static const double sl_table[SL_N][7] = {
    /*  x0     y0      z0      A       B      C     phi (deg) */
    {0.00, 0.000, 0.000, 0.6900, 0.920, 0.900, 0},
    {0.00, 0.000, 0.000, 0.6624, 0.874, 0.880, 0},
    {-0.22, 0.000, -0.250, 0.4100, 0.160, 0.210, 108},
    {0.22, 0.000, -0.250, 0.3100, 0.110, 0.220, 72},
    {0.00, 0.350, -0.250, 0.2100, 0.250, 0.500, 0},
    {0.00, 0.100, -0.250, 0.0460, 0.046, 0.046, 0},
    {-0.08, -0.650, -0.250, 0.0460, 0.023, 0.020, 0},
    {0.06, -0.650, -0.250, 0.0460, 0.023, 0.020, 90},
    {0.06, -0.105, 0.625, 0.0560, 0.040, 0.100, 90},
    {0.00, 0.100, 0.625, 0.0560, 0.056, 0.100, 0},
};

static const double sl_density_ks[SL_N] = {2.0, -0.98, -0.02, -0.02, 0.02, 0.02, 0.01, 0.01, 0.02, -0.02};
static const double sl_density_yyw[SL_N] = {1.0, -0.8, -0.2, -0.2, 0.2, 0.2, 0.1, 0.1, 0.2, -0.2};

typedef struct sl_ctx {
    double c[SL_N][3], inv_a2[SL_N][3], cs[SL_N][2], rho[SL_N];
} sl_ctx;

static void sl_row(const void *vctx, const synth_grid *g, size_t j, size_t k, float *row, float *lab)
{
    const sl_ctx *c = vctx;
    double uy = synth_u(g, 1, j), uz = synth_u(g, 2, k);
    size_t i;
    int e;
    (void)lab;
    for (i = 0; i < g->nx; i++) {
        double ux = synth_u(g, 0, i), f = 0;
        for (e = 0; e < SL_N; e++) {
            double dx = ux - c->c[e][0], dy = uy - c->c[e][1], dz = uz - c->c[e][2];
            double xp = c->cs[e][0] * dx + c->cs[e][1] * dy, yp = -c->cs[e][1] * dx + c->cs[e][0] * dy;
            if (xp * xp * c->inv_a2[e][0] + yp * yp * c->inv_a2[e][1] + dz * dz * c->inv_a2[e][2] <= 1.0)
                f += c->rho[e];
        }
        row[i] = (float)f;
    }
}

wvol_status wvol__synth_plan_shepp_logan(synth_plan *pl, const wvol_synth_params *p, wvol_error *err)
{
    sl_ctx *c;
    const double *rho = sl_density_ks;
    int e, a;
    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "synth shepp-logan: NULL parameters");
    if (p->variant && *p->variant && strcasecmp(p->variant, "kak-slaney") != 0) {
        WVOL_RETURN_IF(strcasecmp(p->variant, "yu-ye-wang") != 0, err, WVOL_ERR_ARG,
                       "synth shepp-logan: unknown variant '%s' (known: kak-slaney, yu-ye-wang)",
                       p->variant);
        rho = sl_density_yyw;
    }
    WVOL_FORWARD(wvol__synth_geometry(&pl->g, p, NULL, "shepp-logan", err));
    WVOL_RETURN_IF(!(c = wvol__synth_plan_ctx(pl, sizeof *c, sl_row)), err, WVOL_ERR_NOMEM,
                   "synth shepp-logan: out of memory");
    for (e = 0; e < SL_N; e++) {
        double phi = sl_table[e][6] * 3.14159265358979323846 / 180.0;
        for (a = 0; a < 3; a++) {
            c->c[e][a] = sl_table[e][a];
            c->inv_a2[e][a] = 1.0 / (sl_table[e][3 + a] * sl_table[e][3 + a]);
        }
        c->cs[e][0] = cos(phi);
        c->cs[e][1] = sin(phi);
        c->rho[e] = rho[e];
    }
    return WVOL_OK;
}

wvol_status wvol_synth_shepp_logan(wvol_volume **out, const wvol_synth_params *p, wvol_error *err)
{
    return wvol__synth_whole(out, NULL, wvol__synth_plan_shepp_logan, p, "shepp-logan", err);
}
