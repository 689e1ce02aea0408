/* SPDX-License-Identifier: MIT
 * Fast path: X-ray along a coordinate axis from 2D coefficients alone (DESIGN.md section 8).
 * The integral of a level-m factor 2^{-m/2} B(2^{-m}(x + s) - p) over a whole period of the
 * model is 2^{m/2} times the integral of B (the spline's phi or psi: ~1 and ~0, taken as
 * computed, so the result is the spline model's exactly). What is left of each coefficient
 * is a 2D basis function of the same level and position, and the 2D multi-level sum is
 * evaluated at the pixel centres level by level (separable weights, (L-1)^2 terms per level
 * and 2D band). Cost: O(kept) + O(pixels levels 4 (L-1)^2), independent of the ray length. */
#include "render_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

wvol_status wvol_render_xray_axis(wvol_image *img, const wvol_store *s, const wvol_camera *cam,
                                  const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_store_info info;
    const wvol_basis *b;
    wvol__cam k;
    wvol_store_iter it;
    wvol_store_coeff cf;
    size_t P[3], Pu, Pv, m, i, rays_hit = 0;
    double **acc = NULL, lo[3], hi[3], t_start = wvol__now(), c_start = wvol__cpu_now(), Iphi, Ipsi, sp_ray;
    int a = -1, ua, va, M, ax, y;
    wvol_status st = WVOL_OK;

    wvol__params(&p, params);
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "render: no store");
    WVOL_FORWARD(wvol__render_check(img, cam, NULL, &p, err));
    WVOL_FORWARD(wvol__check_colors(&p, NULL, 0, err));
    WVOL_FORWARD(wvol__check_skip(&p, 0, err));
    WVOL_RETURN_IF(p.mode != WVOL_RENDER_MODE_XRAY, err, WVOL_ERR_UNSUPPORTED, "render: the axis fast path is X-ray only");
    WVOL_RETURN_IF(cam->projection != WVOL_PROJECTION_ORTHOGRAPHIC, err, WVOL_ERR_UNSUPPORTED,
                   "render: the axis fast path needs an orthographic camera");
    wvol__cam_init(&k, cam);
    for (ax = 0; ax < 3; ax++)
        if (fabs(k.fwd[ax]) > 1.0 - 1e-12) a = ax;
    WVOL_RETURN_IF(a < 0, err, WVOL_ERR_UNSUPPORTED,
                   "render: the axis fast path needs a view along x, y or z (got %g, %g, %g)", k.fwd[0], k.fwd[1],
                   k.fwd[2]);
    wvol_store_get_info(s, &info);
    b = wvol_store_basis(s);
    M = info.levels;
    P[0] = info.px, P[1] = info.py, P[2] = info.pz;
    ua = a == 0 ? 1 : 0;
    va = a == 2 ? 1 : 2;
    {
        size_t n[3] = {info.nx, info.ny, info.nz};
        WVOL_RETURN_IF(n[a] != P[a], err, WVOL_ERR_UNSUPPORTED,
                       "render: the axis fast path needs the ray axis extent (%zu) to be a whole period (%zu, a "
                       "multiple of 2^levels): a padded axis is rendered only over its original extent",
                       n[a], P[a]);
        WVOL_RETURN_IF(!info.transformed[ua] || !info.transformed[va], err, WVOL_ERR_UNSUPPORTED,
                       "render: the axis fast path needs both image axes transformed (extent > 1)");
    }
    Pu = P[ua];
    Pv = P[va];
    Iphi = b->phi_integral;
    Ipsi = b->psi_integral;
    sp_ray = info.spacing[a];

    /* acc[4*m + band2]: (Pu >> m) x (Pv >> m) arrays, band2 bit 0 = high-pass along u, bit 1 along v */
    acc = calloc((size_t)(M + 1) * 4, sizeof *acc);
    if (!acc) goto nomem;
    for (m = 0; m <= (size_t)M; m++) {
        int bd;
        for (bd = 0; bd < 4; bd++) {
            if (m == 0) continue;
            acc[4 * m + bd] = calloc((Pu >> m) * (Pv >> m), sizeof(double));
            if (!acc[4 * m + bd]) goto nomem;
        }
    }
    memset(&it, 0, sizeof it);
    while (wvol_store_next(s, &it, &cf)) {
        size_t pos[3] = {cf.p, cf.q, cf.r}, lev = cf.level;
        int rb = (cf.band >> a) & 1, bd = ((cf.band >> ua) & 1) | (((cf.band >> va) & 1) << 1);
        double w;
        if (info.transformed[a]) w = sqrt(ldexp(1.0, (int)lev)) * (rb ? Ipsi : Iphi) * sp_ray;
        else w = sp_ray;
        acc[4 * lev + bd][pos[ua] + (Pu >> lev) * pos[va]] += w * cf.value;
    }
    /* f2(u, v) = sum over levels m and 2D bands of acc * 2^{-m} B_u(2^{-m}(u + s) - p) B_v(...),
     * evaluated directly level by level. (A 2D inverse transform down to level 0 followed by the
     * level-0 scaling expansion is the same function for the true phi, but not for its cubic
     * spline, which satisfies the two-scale relation only up to the spline's error; the direct
     * sum is what the spline-projected integrator integrates.) */
    {
        wvol_geometry g;
        double sft = b->center;
        int L1 = b->length - 1;
        g.dims[0] = info.nx, g.dims[1] = info.ny, g.dims[2] = info.nz;
        for (ax = 0; ax < 3; ax++) g.spacing[ax] = info.spacing[ax], g.origin[ax] = info.origin[ax];
        wvol_geometry_bounds(&g, lo, hi);
#pragma omp parallel for schedule(dynamic, 4) num_threads(wvol__threads(p.threads)) reduction(+ : rays_hit)
        for (y = 0; y < img->height; y++) {
            double wu[2][WVOL_BASIS_MAX_LENGTH], wv[2][WVOL_BASIS_MAX_LENGTH];
            int xx, ch;
            for (xx = 0; xx < img->width; xx++) {
                double o[3], d[3], vox[3], val = 0;
                int hit, lev;
                float *px = img->rgba + 4 * ((size_t)xx + (size_t)img->width * (size_t)y);
                wvol__cam_ray(&k, xx + 0.5, y + 0.5, o, d);
                hit = o[ua] > lo[ua] && o[ua] < hi[ua] && o[va] > lo[va] && o[va] < hi[va];
                if (!hit) {
                    for (ch = 0; ch < 4; ch++) px[ch] = 0;
                    continue;
                }
                rays_hit++;
                wvol_store_world_to_voxel(s, o, vox);
                for (lev = 1; lev <= M; lev++) {
                    double sc = ldexp(1.0, -lev), zu = (vox[ua] + sft) * sc, zv = (vox[va] + sft) * sc;
                    long nu = (long)(Pu >> lev), nv = (long)(Pv >> lev), iu0 = (long)floor(zu) - L1 + 1,
                         iv0 = (long)floor(zv) - L1 + 1;
                    int ku, kv, bd;
                    for (ku = 0; ku < L1; ku++) {
                        wu[0][ku] = wvol_basis_value(b, WVOL_BASIS_PHI, zu - (double)(iu0 + ku));
                        wu[1][ku] = wvol_basis_value(b, WVOL_BASIS_PSI, zu - (double)(iu0 + ku));
                    }
                    for (kv = 0; kv < L1; kv++) {
                        wv[0][kv] = wvol_basis_value(b, WVOL_BASIS_PHI, zv - (double)(iv0 + kv));
                        wv[1][kv] = wvol_basis_value(b, WVOL_BASIS_PSI, zv - (double)(iv0 + kv));
                    }
                    for (bd = 0; bd < 4; bd++) {
                        const double *A = acc[4 * lev + bd];
                        const double *WU = wu[bd & 1], *WV = wv[bd >> 1];
                        double part = 0;
                        for (kv = 0; kv < L1; kv++) {
                            long jv = ((iv0 + kv) % nv + nv) % nv;
                            double row = 0;
                            for (ku = 0; ku < L1; ku++) {
                                long ju = ((iu0 + ku) % nu + nu) % nu;
                                row += WU[ku] * A[(size_t)ju + (size_t)nu * (size_t)jv];
                            }
                            part += WV[kv] * row;
                        }
                        val += sc * part;
                    }
                }
                px[0] = px[1] = px[2] = (float)val;
                px[3] = 1.0f;
            }
        }
    }
    {
        wvol__counts c = {.rays_hit = rays_hit, .functions = info.kept};
        wvol__stats_fill(stats, img, t_start, c_start, &c);
    }
    st = wvol__image_check_range(img, err);
    goto done;
nomem:
    st = wvol_error_set(err, WVOL_ERR_NOMEM, "render: out of memory for the projected %zux%zu pyramid", Pu, Pv);
done:
    if (acc)
        for (i = 0; i < (size_t)(M + 1) * 4; i++) free(acc[i]);
    free(acc);
    return st;
}
