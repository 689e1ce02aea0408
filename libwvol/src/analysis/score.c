/* SPDX-License-Identifier: MIT */
/* Segmentation quality: majority mapping of clusters to classes, then the
 * misclassification rate overall and away from class boundaries. */
#include "core/status_internal.h"
#include "wvol/analysis.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* interior[i] = 1 when every voxel within Chebyshev radius r (clamped at the
 * volume's faces) has the same truth class: separable running min and max. */
static wvol_status interior_mask(uint8_t *interior, const int32_t *truth, size_t nx, size_t ny, size_t nz,
                                 int r, wvol_error *err)
{
    size_t n = nx * ny * nz, dims[3] = {nx, ny, nz};
    int32_t *lo = malloc(n * sizeof *lo), *hi = malloc(n * sizeof *hi), *tmp = malloc(n * sizeof *tmp);
    if (!lo || !hi || !tmp) {
        free(lo);
        free(hi);
        free(tmp);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "score: out of memory");
    }
    memcpy(lo, truth, n * sizeof *lo);
    memcpy(hi, truth, n * sizeof *hi);
    for (int axis = 0; axis < 3; axis++) {
        size_t len = dims[axis], stride = axis == 0 ? 1 : axis == 1 ? nx : nx * ny;
        if (len == 1 || r <= 0) continue;
        for (int pass = 0; pass < 2; pass++) {
            int32_t *a = pass ? hi : lo;
            memcpy(tmp, a, n * sizeof *tmp);
            for (size_t idx = 0; idx < n; idx++) {
                size_t c = (idx / stride) % len, base = idx - c * stride;
                size_t from = c >= (size_t)r ? c - (size_t)r : 0;
                size_t to = c + (size_t)r < len ? c + (size_t)r : len - 1;
                int32_t v = tmp[base + from * stride];
                for (size_t q = from + 1; q <= to; q++) {
                    int32_t w = tmp[base + q * stride];
                    if (pass ? w > v : w < v) v = w;
                }
                a[idx] = v;
            }
        }
    }
    for (size_t i = 0; i < n; i++) interior[i] = lo[i] == hi[i];
    free(lo);
    free(hi);
    free(tmp);
    return WVOL_OK;
}

wvol_status wvol_segmentation_score(wvol_seg_score *score, const int32_t *pred, const int32_t *truth,
                                    size_t nx, size_t ny, size_t nz, int boundary_radius,
                                    wvol_error *err)
{
    size_t n = nx * ny * nz, wrong = 0, wrong_in = 0, interior_n = 0;
    int32_t maxp = 0, maxt = 0;
    long *table;
    int32_t *map;
    uint8_t *interior;
    wvol_status s;

    WVOL_RETURN_IF(!score || !pred || !truth || n == 0, err, WVOL_ERR_ARG, "score: bad argument");
    WVOL_RETURN_IF(boundary_radius < 0 || boundary_radius > 64, err, WVOL_ERR_ARG,
                   "score: boundary radius %d out of range 0..64", boundary_radius);
    for (size_t i = 0; i < n; i++) {
        WVOL_RETURN_IF(pred[i] < 0 || pred[i] > 65535 || truth[i] < 0 || truth[i] > 65535, err,
                       WVOL_ERR_ARG, "score: labels must be in 0..65535 (voxel %zu: %d, %d)", i, pred[i],
                       truth[i]);
        if (pred[i] > maxp) maxp = pred[i];
        if (truth[i] > maxt) maxt = truth[i];
    }
    table = calloc((size_t)(maxp + 1) * (size_t)(maxt + 1), sizeof *table);
    map = malloc((size_t)(maxp + 1) * sizeof *map);
    interior = malloc(n);
    if (!table || !map || !interior) {
        free(table);
        free(map);
        free(interior);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "score: out of memory");
    }
    for (size_t i = 0; i < n; i++) table[(size_t)pred[i] * (size_t)(maxt + 1) + (size_t)truth[i]]++;
    for (int32_t c = 0; c <= maxp; c++) {
        long best = -1;
        map[c] = 0;
        for (int32_t t = 0; t <= maxt; t++)
            if (table[(size_t)c * (size_t)(maxt + 1) + (size_t)t] > best) {
                best = table[(size_t)c * (size_t)(maxt + 1) + (size_t)t];
                map[c] = t;
            }
    }
    s = interior_mask(interior, truth, nx, ny, nz, boundary_radius, err);
    if (s == WVOL_OK) {
        for (size_t i = 0; i < n; i++) {
            int bad = map[pred[i]] != truth[i];
            wrong += (size_t)bad;
            if (interior[i]) {
                interior_n++;
                wrong_in += (size_t)bad;
            }
        }
        score->error_all = (double)wrong / (double)n;
        /* no voxel away from a boundary: the interior error is undefined, not 0 */
        score->error_interior = interior_n ? (double)wrong_in / (double)interior_n : NAN;
        score->interior = interior_n;
    }
    free(table);
    free(map);
    free(interior);
    return s;
}
