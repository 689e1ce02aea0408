/* SPDX-License-Identifier: MIT */
/* 3D Kohonen self-organising map (paper section 4.2, eq 31): neurons on an
 * a x b x c lattice, each with an RGB colour from its lattice position; for each
 * presented feature vector g the winner is the neuron nearest in feature space and
 * every neuron j within the shrinking neighbourhood moves by
 *   dw_j = eta(t) h(j, winner, t) (g - w_j),
 * with eta decaying exponentially eta0 -> eta1 and h a Gaussian of lattice distance
 * whose radius decays sigma0 -> sigma1 (cut at 3 sigma). Deterministic per seed (wvol_rng). */
#include "core/finite.h"
#include "core/status_internal.h"
#include "wvol/analysis.h"
#include "wvol/rng.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void wvol_som_params_default(wvol_som_params *p)
{
    if (!p) return;
    p->dims[0] = p->dims[1] = p->dims[2] = 4;
    p->iterations = 20000;
    p->eta0 = 0.5;
    p->eta1 = 0.01;
    p->sigma0 = 2.0;
    p->sigma1 = 0.3;
    p->seed = 1;
}

void wvol_som_destroy(wvol_som *s)
{
    if (!s) return;
    free(s->weights);
    free(s->colors);
    free(s->neuron_class);
    free(s);
}

/* Nearest neuron to voxel i's feature vector. */
static int winner(const wvol_som *s, const float *planes, size_t n, size_t i)
{
    int best = 0;
    float bestd = FLT_MAX;
    for (int j = 0; j < s->neurons; j++) {
        const float *w = s->weights + (size_t)j * s->features;
        float d = 0;
        for (int a = 0; a < s->features; a++) {
            float t = planes[(size_t)a * n + i] - w[a];
            d += t * t;
        }
        if (d < bestd) {
            bestd = d;
            best = j;
        }
    }
    return best;
}

static void lattice_pos(const wvol_som *s, int j, int pos[3])
{
    pos[0] = j % s->dims[0];
    pos[1] = (j / s->dims[0]) % s->dims[1];
    pos[2] = j / (s->dims[0] * s->dims[1]);
}

wvol_status wvol_som_train(wvol_som **out, const wvol_features *f, const wvol_som_params *p,
                           wvol_error *err)
{
    wvol_som *s;
    size_t n;
    wvol_rng rng;
    float *g;

    WVOL_RETURN_IF(!out || !f || !f->data || !p, err, WVOL_ERR_ARG, "som: NULL argument");
    *out = NULL;
    for (int a = 0; a < 3; a++)
        WVOL_RETURN_IF(p->dims[a] < 1 || p->dims[a] > 64, err, WVOL_ERR_ARG,
                       "som: lattice dimension %d is %d, must be 1..64", a, p->dims[a]);
    /* the training cannot be interrupted: a bound keeps a call within minutes */
    WVOL_RETURN_IF(p->iterations < 1 || p->iterations > 100000000L, err, WVOL_ERR_ARG,
                   "som: iterations %ld must be in 1..100000000", p->iterations);
    WVOL_RETURN_IF(!(p->eta0 > 0 && p->eta0 <= 1 && p->eta1 > 0 && p->eta1 <= p->eta0), err,
                   WVOL_ERR_ARG, "som: learning rates must satisfy 0 < eta1 <= eta0 <= 1 (got %g, %g)",
                   p->eta0, p->eta1);
    WVOL_RETURN_IF(!(p->sigma0 > 0 && p->sigma1 > 0 && p->sigma1 <= p->sigma0), err, WVOL_ERR_ARG,
                   "som: radii must satisfy 0 < sigma1 <= sigma0 (got %g, %g)", p->sigma0, p->sigma1);
    n = f->nx * f->ny * f->nz;
    WVOL_RETURN_IF(f->count < 1, err, WVOL_ERR_ARG, "som: %d features per voxel (at least 1)", f->count);
    WVOL_RETURN_IF(!wvol__all_finite(f->data, n * (size_t)f->count), err, WVOL_ERR_NONFINITE,
                   "som: the features hold NaN or Inf");
    s = calloc(1, sizeof *s);
    if (!s) return wvol_error_set(err, WVOL_ERR_NOMEM, "som: out of memory");
    memcpy(s->dims, p->dims, sizeof s->dims);
    s->neurons = p->dims[0] * p->dims[1] * p->dims[2];
    s->features = f->count;
    s->weights = malloc((size_t)s->neurons * (size_t)s->features * sizeof(float));
    s->colors = malloc((size_t)s->neurons * 3 * sizeof(float));
    s->neuron_class = malloc((size_t)s->neurons * sizeof(int));
    g = malloc((size_t)s->features * sizeof(float));
    if (!s->weights || !s->colors || !s->neuron_class || !g) {
        free(g);
        wvol_som_destroy(s);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "som: out of memory");
    }
    wvol_rng_seed(&rng, p->seed);
    for (int j = 0; j < s->neurons; j++) {
        int pos[3];
        lattice_pos(s, j, pos);
        for (int a = 0; a < 3; a++)
            s->colors[3 * j + a] = s->dims[a] > 1 ? (float)pos[a] / (float)(s->dims[a] - 1) : 0.5f;
        s->neuron_class[j] = -1;
        /* initialise on random samples so every neuron starts inside the data */
        size_t i = (size_t)(wvol_rng_uniform(&rng) * (double)n);
        if (i >= n) i = n - 1;
        for (int a = 0; a < s->features; a++)
            s->weights[(size_t)j * s->features + a] = f->data[(size_t)a * n + i];
    }
    for (long t = 0; t < p->iterations; t++) {
        double frac = p->iterations > 1 ? (double)t / (double)(p->iterations - 1) : 1.0;
        double eta = p->eta0 * pow(p->eta1 / p->eta0, frac);
        double sigma = p->sigma0 * pow(p->sigma1 / p->sigma0, frac);
        size_t i = (size_t)(wvol_rng_uniform(&rng) * (double)n);
        int w, wp[3];
        if (i >= n) i = n - 1;
        for (int a = 0; a < s->features; a++) g[a] = f->data[(size_t)a * n + i];
        w = winner(s, f->data, n, i);
        lattice_pos(s, w, wp);
        for (int j = 0; j < s->neurons; j++) {
            int pos[3];
            double d2, h;
            lattice_pos(s, j, pos);
            d2 = (double)((pos[0] - wp[0]) * (pos[0] - wp[0]) + (pos[1] - wp[1]) * (pos[1] - wp[1]) +
                          (pos[2] - wp[2]) * (pos[2] - wp[2]));
            if (d2 > 9.0 * sigma * sigma) continue;
            h = eta * exp(-d2 / (2.0 * sigma * sigma));
            float *wj = s->weights + (size_t)j * s->features;
            for (int a = 0; a < s->features; a++) wj[a] += (float)(h * (g[a] - wj[a]));
        }
    }
    free(g);
    *out = s;
    return WVOL_OK;
}

wvol_status wvol_som_classify(int32_t *labels, float *rgb, const wvol_som *s, const wvol_features *f,
                              wvol_error *err)
{
    size_t n;
    WVOL_RETURN_IF(!labels || !s || !f || !f->data, err, WVOL_ERR_ARG, "som classify: NULL argument");
    WVOL_RETURN_IF(f->count != s->features, err, WVOL_ERR_ARG,
                   "som classify: map trained on %d features, got %d", s->features, f->count);
    n = f->nx * f->ny * f->nz;
    #pragma omp parallel for schedule(static)
    for (long ii = 0; ii < (long)n; ii++) {
        int w = winner(s, f->data, n, (size_t)ii);
        labels[ii] = w;
        if (rgb) memcpy(rgb + 3 * (size_t)ii, s->colors + 3 * w, 3 * sizeof(float));
    }
    return WVOL_OK;
}

wvol_status wvol_som_label(wvol_som *s, const wvol_features *f, const int32_t *truth,
                           const uint8_t *mask, wvol_error *err)
{
    size_t n;
    int32_t maxc = -1;
    long *votes;
    WVOL_RETURN_IF(!s || !f || !truth, err, WVOL_ERR_ARG, "som label: NULL argument");
    WVOL_RETURN_IF(f->count != s->features, err, WVOL_ERR_ARG,
                   "som label: map trained on %d features, got %d", s->features, f->count);
    n = f->nx * f->ny * f->nz;
    for (size_t i = 0; i < n; i++) {
        WVOL_RETURN_IF(truth[i] < 0 || truth[i] > 65535, err, WVOL_ERR_ARG,
                       "som label: ground-truth class %d at voxel %zu must be in 0..65535", truth[i], i);
        if ((!mask || mask[i]) && truth[i] > maxc) maxc = truth[i];
    }
    WVOL_RETURN_IF(maxc < 0, err, WVOL_ERR_ARG, "som label: the training mask selects no voxel");
    votes = calloc((size_t)s->neurons * (size_t)(maxc + 1), sizeof *votes);
    WVOL_RETURN_IF(!votes, err, WVOL_ERR_NOMEM, "som label: out of memory");
    for (size_t i = 0; i < n; i++) {
        if (mask && !mask[i]) continue;
        votes[(size_t)winner(s, f->data, n, i) * (size_t)(maxc + 1) + (size_t)truth[i]]++;
    }
    for (int j = 0; j < s->neurons; j++) {
        long best = 0;
        s->neuron_class[j] = -1;
        for (int c = 0; c <= maxc; c++)
            if (votes[(size_t)j * (size_t)(maxc + 1) + (size_t)c] > best) {
                best = votes[(size_t)j * (size_t)(maxc + 1) + (size_t)c];
                s->neuron_class[j] = c;
            }
    }
    /* neurons that won no training voxel: class of the nearest labelled neuron */
    for (int j = 0; j < s->neurons; j++) {
        if (s->neuron_class[j] >= 0) continue;
        float bestd = FLT_MAX;
        int bestc = 0;
        for (int k = 0; k < s->neurons; k++) {
            /* votes are still intact: use them to know who was labelled from data */
            long any = 0;
            for (int c = 0; c <= maxc; c++) any += votes[(size_t)k * (size_t)(maxc + 1) + (size_t)c];
            if (!any) continue;
            float d = 0;
            for (int a = 0; a < s->features; a++) {
                float t = s->weights[(size_t)j * s->features + a] - s->weights[(size_t)k * s->features + a];
                d += t * t;
            }
            if (d < bestd) {
                bestd = d;
                bestc = s->neuron_class[k];
            }
        }
        s->neuron_class[j] = bestc;
    }
    free(votes);
    return WVOL_OK;
}

void wvol_som_apply_classes(int32_t *classes, const int32_t *winners, size_t n, const wvol_som *s)
{
    const int neurons = s ? s->neurons : 0;
    if (!classes || !winners) return;
    for (size_t i = 0; i < n; i++) {
        const int32_t w = winners[i];
        /* a winner that names no neuron (not one of wvol_som_apply's labels) has no class */
        classes[i] = s && s->neuron_class && w >= 0 && w < neurons ? s->neuron_class[w] : -1;
    }
}
