/* SPDX-License-Identifier: MIT */
/* Per-voxel wavelet features (paper section 4.1, DESIGN.md section 10).
 * One global transform, level by level: at level m the previous low-pass cube is
 * split once; each detail band present gives a magnitude plane |d| and the new
 * low-pass cube gives a value plane, both on the level's coarse grid. Each plane is
 * then interpolated (trilinear; bilinear in 2D) back to every voxel. */
#include "core/finite.h"
#include "core/status_internal.h"
#include "wvol/analysis.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void wvol_feature_params_default(wvol_feature_params *p)
{
    if (!p) return;
    p->levels = 3;
    p->smooth = 1;
    p->include_lowpass = 1;
}

void wvol_features_destroy(wvol_features *f)
{
    if (!f) return;
    free(f->data);
    free(f);
}

/* Edge-replicating pad of v into a px*py*pz array. */
static void pad_edge(float *dst, const wvol_volume *v, size_t px, size_t py, size_t pz)
{
    for (size_t k = 0; k < pz; k++) {
        size_t sk = k < v->nz ? k : v->nz - 1;
        for (size_t j = 0; j < py; j++) {
            size_t sj = j < v->ny ? j : v->ny - 1;
            const float *src = v->data + v->nx * (sj + v->ny * sk);
            float *row = dst + px * (j + py * k);
            memcpy(row, src, v->nx * sizeof(float));
            for (size_t i = v->nx; i < px; i++) row[i] = src[v->nx - 1];
        }
    }
}

static size_t pad_to(size_t n, int levels)
{
    size_t b = (size_t)1 << levels;
    return n == 1 ? 1 : (n + b - 1) / b * b;
}

/* Periodic box average of radius r along each transformed axis, in place. */
static void box_smooth(float *a, const size_t n[3], int r, float *tmp)
{
    size_t total = n[0] * n[1] * n[2];
    for (int axis = 0; axis < 3; axis++) {
        size_t len = n[axis], stride = axis == 0 ? 1 : axis == 1 ? n[0] : n[0] * n[1];
        if (len == 1 || r <= 0) continue;
        for (size_t base = 0; base < total; base++) {
            /* visit each line once: base is a line start when its axis coordinate is 0 */
            if ((base / stride) % len != 0) continue;
            for (size_t i = 0; i < len; i++) {
                double s = 0;
                for (long d = -r; d <= r; d++) {
                    size_t ii = (size_t)(((long)i + d + (long)len * (r + 1)) % (long)len);
                    s += a[base + ii * stride];
                }
                tmp[i] = (float)(s / (2 * r + 1));
            }
            for (size_t i = 0; i < len; i++) a[base + i * stride] = tmp[i];
        }
    }
}

/* Interpolates the coarse plane c (size cn) of level m to every voxel of the
 * original grid: coefficient p sits at voxel coordinate 2^m (p + s) - s. */
static void interpolate(float *out, const float *c, const size_t cn[3], int m, double s,
                        size_t nx, size_t ny, size_t nz)
{
    const double scale = 1.0 / (double)((size_t)1 << m);
    const size_t n[3] = {nx, ny, nz};
    #pragma omp parallel for schedule(static)
    for (long kk = 0; kk < (long)nz; kk++) {
        size_t idx[3][2];
        double w[3][2];
        size_t k = (size_t)kk;
        for (size_t j = 0; j < ny; j++) {
            for (size_t i = 0; i < nx; i++) {
                const size_t pos[3] = {i, j, k};
                double v = 0;
                for (int a = 0; a < 3; a++) {
                    if (cn[a] == 1 || n[a] == 1) {
                        idx[a][0] = idx[a][1] = 0;
                        w[a][0] = 1;
                        w[a][1] = 0;
                        continue;
                    }
                    double u = ((double)pos[a] + s) * scale - s;
                    double fl = floor(u);
                    long len = (long)cn[a];
                    long i0 = (((long)fl % len) + len) % len;
                    idx[a][0] = (size_t)i0;
                    idx[a][1] = (size_t)((i0 + 1) % len);
                    w[a][1] = u - fl;
                    w[a][0] = 1 - w[a][1];
                }
                for (int dz = 0; dz < 2; dz++)
                    for (int dy = 0; dy < 2; dy++)
                        for (int dx = 0; dx < 2; dx++) {
                            double ww = w[0][dx] * w[1][dy] * w[2][dz];
                            if (ww == 0) continue;
                            v += ww * c[idx[0][dx] + cn[0] * (idx[1][dy] + cn[1] * idx[2][dz])];
                        }
                out[i + nx * (j + ny * k)] = (float)v;
            }
        }
    }
}

wvol_status wvol_features_compute(wvol_features **out, const wvol_volume *v, const wvol_filter *f,
                                  const wvol_feature_params *p, wvol_error *err)
{
    wvol_feature_params defaults;
    size_t n, pn[3], planes_per_level, bytes;
    float *low = NULL, *work = NULL, *plane = NULL, *tmp = NULL;
    wvol_features *res = NULL;
    int bands[7], nbands = 0, plane_index = 0, maxl;
    wvol_status s = WVOL_OK;

    WVOL_RETURN_IF(!out || !v || !v->data || !f, err, WVOL_ERR_ARG, "features: NULL argument");
    *out = NULL;
    if (!p) {
        wvol_feature_params_default(&defaults);
        p = &defaults;
    }
    maxl = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    WVOL_RETURN_IF(p->levels < 1 || p->levels > maxl, err, WVOL_ERR_ARG,
                   "features: levels = %d, must be 1..%d for a %zux%zux%zu volume", p->levels, maxl,
                   v->nx, v->ny, v->nz);
    WVOL_RETURN_IF(p->smooth < 0 || p->smooth > 16, err, WVOL_ERR_ARG,
                   "features: smoothing radius %d out of range 0..16", p->smooth);
    WVOL_FORWARD(wvol_check_finite(v->data, v->nx, v->ny, v->nz, "features input", err));

    for (int l = 1; l < 8; l++) {
        if ((l & 1) && v->nx == 1) continue;
        if ((l & 2) && v->ny == 1) continue;
        if ((l & 4) && v->nz == 1) continue;
        bands[nbands++] = l;
    }
    planes_per_level = (size_t)nbands + (p->include_lowpass ? 1 : 0);
    n = wvol_volume_count(v);
    pn[0] = pad_to(v->nx, p->levels);
    pn[1] = pad_to(v->ny, p->levels);
    pn[2] = pad_to(v->nz, p->levels);
    if (!wvol_size_mul3(n, planes_per_level * (size_t)p->levels, 1, sizeof(float), &bytes))
        return wvol_error_set(err, WVOL_ERR_NOMEM, "features: %zu voxels x %zu features overflow", n,
                              planes_per_level * (size_t)p->levels);

    res = calloc(1, sizeof *res);
    low = malloc(pn[0] * pn[1] * pn[2] * sizeof(float));
    work = malloc(pn[0] * pn[1] * pn[2] * sizeof(float));
    plane = malloc(pn[0] * pn[1] * pn[2] * sizeof(float));
    tmp = malloc((pn[0] + pn[1] + pn[2]) * sizeof(float));
    if (res) res->data = malloc(bytes);
    if (!res || !low || !work || !plane || !tmp || !res->data) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "features: out of memory (%zu bytes of features)", bytes);
        goto done;
    }
    res->nx = v->nx;
    res->ny = v->ny;
    res->nz = v->nz;
    res->levels = p->levels;
    res->count = (int)(planes_per_level * (size_t)p->levels);
    pad_edge(low, v, pn[0], pn[1], pn[2]);

    for (int m = 1; m <= p->levels; m++) {
        size_t cur[3], half[3];
        int dims = 0;
        for (int a = 0; a < 3; a++) {
            cur[a] = pn[a] == 1 ? 1 : pn[a] >> (m - 1);
            half[a] = pn[a] == 1 ? 1 : cur[a] / 2;
            dims += pn[a] > 1;
        }
        memcpy(work, low, cur[0] * cur[1] * cur[2] * sizeof(float));
        /* the input was checked finite: Inf in a coarser level's input is the low-pass outgrowing
         * float32 (the transform would call it NaN or Inf input); said as the features' check says it */
        if (m > 1 && !wvol__all_finite(work, cur[0] * cur[1] * cur[2])) {
            s = wvol_error_set(err, WVOL_ERR_NONFINITE,
                               "features: the volume's magnitudes overflow float32 in level %d's low-pass (scale "
                               "the volume down: the segmentation does not depend on the scale)", m - 1);
            goto done;
        }
        s = wvol_dwt3_inplace_f32(work, cur[0], cur[1], cur[2], f, 1, err);
        if (s) goto done;
        for (int b = 0; b < nbands; b++) {
            size_t off[3] = {(bands[b] & 1) ? half[0] : 0, (bands[b] & 2) ? half[1] : 0,
                             (bands[b] & 4) ? half[2] : 0};
            for (size_t k = 0; k < half[2]; k++)
                for (size_t j = 0; j < half[1]; j++)
                    for (size_t i = 0; i < half[0]; i++)
                        plane[i + half[0] * (j + half[1] * k)] = fabsf(
                            work[(i + off[0]) + cur[0] * ((j + off[1]) + cur[1] * (k + off[2]))]);
            box_smooth(plane, half, p->smooth, tmp);
            interpolate(res->data + (size_t)plane_index++ * n, plane, half, m, f->center, v->nx,
                        v->ny, v->nz);
        }
        /* the new low-pass cube, scaled by 2^{-dims/2} per level to stay comparable with the samples */
        {
            double scale = pow(2.0, -0.5 * dims);
            for (size_t k = 0; k < half[2]; k++)
                for (size_t j = 0; j < half[1]; j++)
                    for (size_t i = 0; i < half[0]; i++)
                        low[i + half[0] * (j + half[1] * k)] =
                            (float)(scale * work[i + cur[0] * (j + cur[1] * k)]);
        }
        if (p->include_lowpass)
            interpolate(res->data + (size_t)plane_index++ * n, low, half, m, f->center, v->nx, v->ny,
                        v->nz);
    }
    /* magnitudes near float32's limit overflow in the transform and the smoothing sums: such a
     * volume is refused (scaled down it gives the same segmentation) rather than handed on
     * with Inf or NaN features, which the PCA cannot take */
    for (size_t i = 0; i < n * (size_t)res->count; i++)
        if (!isfinite(res->data[i])) {
            s = wvol_error_set(err, WVOL_ERR_NONFINITE,
                               "features: the volume's magnitudes overflow float32 in feature %zu (scale the volume "
                               "down: the segmentation does not change)",
                               i / n);
            goto done;
        }
    *out = res;
    res = NULL;
done:
    wvol_features_destroy(res);
    free(low);
    free(work);
    free(plane);
    free(tmp);
    return s;
}
