/* SPDX-License-Identifier: MIT
 * Per-pixel error bounds from the coefficients a store dropped (docs/render.md, "Error
 * bounds").
 *
 * f - f^ = sum over the dropped functions of c_j B_j, so along a ray
 *   |X - X^| = |sum_j c_j int B_j dt| <= sum_j |c_j| int |B_j| dt <= int sum_j |c_j| B+_j dt,
 * B+_j the product of the majorants of |phi|, |psi| (wvol_basis_create_majorant: equal to
 * |B_j| on every spline piece where it keeps one sign). The right side is the X-ray of the
 * residual store, which holds |c_j| on those majorants (wvol_store_params.majorant), so the
 * exact X-ray paths compute it: `axis` where it applies (orthographic along an axis),
 * otherwise the spline integrator, ray by ray. A coefficient error e on every coefficient (a
 * .wvc's quantiser) adds e times the integral of sum_j |B_j(x(t))|, at most e * chord * sum
 * over levels and bands of norm_m prod_a S_a, S = sup_u sum_k theta+(u - k) (the periodised
 * majorant), bounded from the majorants' Bernstein coefficients.
 *
 * The coarse bound (wvol_render_bound_coarse) uses the same sum with, per level and band, the
 * largest |c| the residual holds in place of e: chord x sum_{m,band} max|c| norm_m prod_a S_a.
 * One pass over the residual and O(1) per pixel, for any camera; looser, since every dropped
 * function of a band is taken at its band's largest magnitude.
 *
 * Absorption (the emission-absorption integral I = int E(f) T dt, E = c(f) kappa(f),
 * T = exp(-int kappa)): along the path f_s = f^ + s (f - f^), s in [0, 1],
 *   |dI/ds| <= int |E'| |f - f^| dt + int E T (int_0^t |kappa'| |f - f^|) dt
 *          <= (L_E + c_max L_kappa) int |f - f^| dt,
 * using int kappa T dt = 1 - T_end <= 1 and E <= c_max kappa; L_E and L_kappa are the largest
 * slopes of E and kappa over the TF (kappa' is constant on a segment, E' linear in the value,
 * so its extreme is at a knot). Alpha changes by at most L_kappa int |f - f^|. Both images lie
 * in [0, c_max], so the bound is clipped there. Sampling (trilinear, step) error is not part
 * of it: the bound compares the models, as the spline integrator computes them. */
#include "render_internal.h"

#include <math.h>
#include <string.h>

/* Relative slack for the rounding of the X-ray image (float output of double sums) and of
 * the scaling below: far above either, far below any use of the bound. */
#define BOUND_ROUNDING 1e-6

/* sup_u sum_k theta+(u - k), padded for the rounding of its sums. */
static double periodised_sup(const wvol_basis *b, int which)
{
    return wvol_basis_periodised_sup(b, which) * (1.0 + BOUND_ROUNDING);
}

/* Sum over levels and bands of w[m][band] norm_m prod_a S_a (w NULL: 1): with w the largest
 * |c| of each band, it bounds sum_j |c_j| |B_j(x)| at every x. */
static double band_density(const wvol_store *s, double w[][8])
{
    const wvol_basis *b = wvol_store_basis(s);
    wvol_store_info info;
    double S[2] = {periodised_sup(b, 0), periodised_sup(b, 1)}, total = 0;
    int m, band, a, ntr;
    wvol_store_get_info(s, &info);
    ntr = info.transformed[0] + info.transformed[1] + info.transformed[2];
    for (m = 1; m <= info.levels; m++)
        for (band = (m == info.levels ? 0 : 1); band < 8; band++) {
            double prod = pow(2.0, -0.5 * m * ntr) * (w ? w[m][band] : 1.0);
            int ok = 1;
            for (a = 0; a < 3; a++) {
                int bit = (band >> a) & 1;
                if (!info.transformed[a]) ok &= !bit; /* no wavelet along an untransformed axis */
                else prod *= S[bit];
            }
            if (ok) total += prod;
        }
    return total;
}

/* The largest |c| the residual holds per level and band. */
static void band_max(const wvol_store *s, double w[][8])
{
    wvol_store_iter it = {0, 0};
    wvol_store_coeff c;
    memset(w, 0, (WVOL_SELECT_MAX_LEVELS + 1) * sizeof *w);
    while (wvol_store_next(s, &it, &c)) w[c.level][c.band] = fmax(w[c.level][c.band], fabs((double)c.value));
}

/* Largest |kappa'| and, per channel, |(c kappa)'| and c over the TF (kappa per world unit). */
static void tf_lipschitz(const wvol_tf *tf, double *lk, double le[3], double cmax[3])
{
    int i, ch;
    *lk = 0;
    for (ch = 0; ch < 3; ch++) le[ch] = 0, cmax[ch] = 0;
    for (i = 0; i < tf->count; i++)
        for (ch = 0; ch < 3; ch++) cmax[ch] = fmax(cmax[ch], tf->points[i].rgb[ch]);
    for (i = 0; i + 1 < tf->count; i++) {
        const wvol_tf_point *p = &tf->points[i], *q = &tf->points[i + 1];
        double dv = q->value - p->value, k1 = (q->opacity - p->opacity) / dv;
        *lk = fmax(*lk, fabs(k1));
        for (ch = 0; ch < 3; ch++) {
            double c1 = (q->rgb[ch] - p->rgb[ch]) / dv;
            double at_p = c1 * p->opacity + p->rgb[ch] * k1, at_q = c1 * q->opacity + q->rgb[ch] * k1;
            le[ch] = fmax(le[ch], fmax(fabs(at_p), fabs(at_q)));
        }
    }
}

/* The residual's X-ray by an exact path: axis where it applies, else the spline integrator. */
static wvol_status residual_xray(wvol_image *img, const wvol_store *res, const wvol_camera *cam,
                                 const wvol_render_params *p, wvol_render_stats *st, wvol_error *err)
{
    wvol_render_params xp = *p;
    wvol_status s;
    xp.mode = WVOL_RENDER_MODE_XRAY;
    xp.shading = 0;
    s = wvol_render_xray_axis(img, res, cam, &xp, st, NULL);
    if (s == WVOL_ERR_UNSUPPORTED) s = wvol_render_spline(img, res, cam, NULL, &xp, st, err);
    else if (s != WVOL_OK) s = wvol_render_xray_axis(img, res, cam, &xp, st, err); /* for its message */
    return s;
}

static wvol_status bound_image(wvol_image *bound, const wvol_store *residual, double coeff_error, int coarse,
                               const wvol_camera *cam, const wvol_tf *tf_in, const wvol_render_params *params,
                               wvol_render_bound_stats *stats, wvol_error *err)
{
    wvol_render_params p;
    wvol_render_stats xs;
    wvol_store_info info;
    wvol_geometry g;
    wvol__cam k;
    wvol_tf tf;
    double lo[3], hi[3], t_start = wvol__now(), sum = 0, mx = 0, scale[4], clip[4], density = 0;
    const wvol_basis *b;
    int x, y, a, ch;

    WVOL_RETURN_IF(!residual, err, WVOL_ERR_ARG, "render bound: no residual store (the dropped coefficients)");
    b = wvol_store_basis(residual);
    WVOL_RETURN_IF(!b || !b->majorant, err, WVOL_ERR_ARG,
                   "render bound: the residual store must be a majorant store (wvol_store_params.majorant, as "
                   "wvol_compress's build_residual makes it)");
    WVOL_RETURN_IF(!(coeff_error >= 0) || !isfinite(coeff_error), err, WVOL_ERR_ARG,
                   "render bound: the coefficient error must be finite and >= 0 (got %g)", coeff_error);
    wvol__params(&p, params);
    WVOL_FORWARD(wvol__render_check(bound, cam, tf_in, &p, err));
    WVOL_RETURN_IF(p.mode == WVOL_RENDER_MODE_ABSORPTION_LINEAR, err, WVOL_ERR_UNSUPPORTED,
                   "render bound: mode absorption-linear has no bound (its clamp max(0, 1 - dtau) is not the "
                   "exponential the derivation needs); use xray or absorption");
    WVOL_RETURN_IF(p.mode != WVOL_RENDER_MODE_XRAY && p.shading, err, WVOL_ERR_UNSUPPORTED,
                   "render bound: shading multiplies emission by a function of the gradient, which the bound "
                   "does not cover; render the bound without shading");
    WVOL_FORWARD(wvol__check_colors(&p, NULL, 0, err));
    memset(&xs, 0, sizeof xs);
    if (coarse) {
        double w[WVOL_SELECT_MAX_LEVELS + 1][8];
        band_max(residual, w);
        density = band_density(residual, w);
        memset(bound->rgba, 0, 4 * sizeof(float) * (size_t)bound->width * (size_t)bound->height);
        xs.method = WVOL_RENDER_METHOD_AUTO;
    } else {
        WVOL_FORWARD(residual_xray(bound, residual, cam, &p, &xs, err));
    }
    if (coeff_error > 0) density += coeff_error * band_density(residual, NULL);
    wvol_store_get_info(residual, &info);
    for (a = 0; a < 3; a++) {
        g.dims[a] = a == 0 ? info.nx : a == 1 ? info.ny : info.nz;
        g.spacing[a] = info.spacing[a];
        g.origin[a] = info.origin[a];
    }
    if (p.mode == WVOL_RENDER_MODE_XRAY) {
        for (a = 0; a < 3; a++) scale[a] = 1, clip[a] = INFINITY;
        scale[3] = 0, clip[3] = 0; /* X-ray alpha is coverage, the same for both images */
    } else {
        double lk, le[3], cmax[3];
        wvol__tf_world(&tf, tf_in, &g);
        tf_lipschitz(&tf, &lk, le, cmax);
        for (a = 0; a < 3; a++) scale[a] = le[a] + cmax[a] * lk, clip[a] = cmax[a];
        scale[3] = lk, clip[3] = 1;
    }
    wvol_geometry_bounds(&g, lo, hi);
    wvol__cam_init(&k, cam);
    for (y = 0; y < bound->height; y++)
        for (x = 0; x < bound->width; x++) {
            float *px = bound->rgba + 4 * ((size_t)x + (size_t)bound->width * (size_t)y);
            double o[3], d[3], t0 = 0, t1 = 0, xb, pm = 0;
            wvol__cam_ray(&k, x + 0.5, y + 0.5, o, d);
            if (density > 0 && wvol__ray_box(o, d, lo, hi, &t0, &t1)) {
                if (cam->projection == WVOL_PROJECTION_PERSPECTIVE && t0 < 0) t0 = 0;
                if (t1 < t0) t1 = t0;
            }
            xb = ((double)px[0] + density * (t1 - t0)) * (1.0 + BOUND_ROUNDING);
            for (ch = 0; ch < 4; ch++) {
                /* rounded up to float, so that the stored bound stays a bound */
                double v = fmin(xb * scale[ch] * (1.0 + BOUND_ROUNDING), clip[ch]);
                float f = (float)v;
                if ((double)f < v) f = nextafterf(f, INFINITY);
                px[ch] = f;
                if (ch < 3) pm = fmax(pm, f);
            }
            sum += pm;
            mx = fmax(mx, pm);
        }
    if (stats) {
        memset(stats, 0, sizeof *stats);
        stats->max = mx;
        stats->mean = sum / ((double)bound->width * (double)bound->height);
        stats->functions = xs.functions;
        stats->rays_hit = xs.rays_hit;
        stats->method = xs.method;
        stats->coeff_error_density = density;
        stats->seconds = wvol__now() - t_start;
    }
    return wvol__image_check_range(bound, err);
}

wvol_status wvol_render_bound(wvol_image *bound, const wvol_store *residual, double coeff_error,
                              const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *params,
                              wvol_render_bound_stats *stats, wvol_error *err)
{
    return bound_image(bound, residual, coeff_error, 0, cam, tf, params, stats, err);
}

wvol_status wvol_render_bound_coarse(wvol_image *bound, const wvol_store *residual, double coeff_error,
                                     const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *params,
                                     wvol_render_bound_stats *stats, wvol_error *err)
{
    return bound_image(bound, residual, coeff_error, 1, cam, tf, params, stats, err);
}
