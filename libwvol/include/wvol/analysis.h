/* SPDX-License-Identifier: MIT */
/* Analysis in wavelet space (DESIGN.md section 10; paper sections 3-4):
 * per-voxel wavelet feature vectors -> PCA -> min-max normalisation -> 3D
 * Kohonen map -> labels and colours that the renderer can use. */
#ifndef WVOL_ANALYSIS_H
#define WVOL_ANALYSIS_H

#include <stdint.h>
#include "wvol/wavelet.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Feature planes: count planes of nx*ny*nz floats each (planar layout, plane f at
 * data + f*n). Per level m = 1..levels: the magnitude of each detail band present
 * (3 in 2D, 7 in 3D) and the level's low-pass value, each interpolated
 * (bilinear / trilinear) from the level's coarse grid to the voxel. */
typedef struct wvol_features {
    size_t nx, ny, nz;
    int count;
    int levels;
    float *data;
} wvol_features;

typedef struct wvol_feature_params {
    int levels;          /* pyramid depth M (>= 1) */
    int smooth;          /* radius (coarse samples) of a box average of |d| per band; 0 = none */
    int include_lowpass; /* add each level's low-pass value (the paper does; default 1) */
} wvol_feature_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_feature_params_default(wvol_feature_params *p);

WVOL_API wvol_status wvol_features_compute(wvol_features **out, const wvol_volume *v, const wvol_filter *f,
                                           const wvol_feature_params *p, wvol_error *err);
WVOL_API void wvol_features_destroy(wvol_features *f);

/* PCA over the feature planes (covariance in float64, eigenproblem by LAPACK's
 * dsyev), projection onto the components in decreasing variance, then min-max
 * normalisation of each component to [0, 1]. Keeps the fewest components that
 * explain `variance` of the total (1.0 keeps all). eigenvalues (may be NULL) gets
 * the kept variances, at most f->count values. */
WVOL_API wvol_status wvol_features_pca(wvol_features *f, double variance, double *eigenvalues, wvol_error *err);

/* 3D Kohonen map. */
typedef struct wvol_som_params {
    int dims[3];          /* lattice a x b x c, each >= 1 */
    long iterations;      /* training samples presented, 1..100000000 */
    double eta0, eta1;    /* learning rate: eta0 -> eta1, exponential decay */
    double sigma0, sigma1;/* neighbourhood radius in lattice units: sigma0 -> sigma1 */
    uint64_t seed;
} wvol_som_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_som_params_default(wvol_som_params *p);

typedef struct wvol_som {
    int dims[3];
    int neurons;
    int features;
    float *weights;   /* neurons * features */
    float *colors;    /* neurons * 3, RGB from the lattice position */
    int *neuron_class;/* after wvol_som_label: the class of each neuron, -1 if none */
} wvol_som;

/* Trains on the feature vectors (deterministic for a given seed). */
WVOL_API wvol_status wvol_som_train(wvol_som **out, const wvol_features *f, const wvol_som_params *p,
                                    wvol_error *err);
WVOL_API void wvol_som_destroy(wvol_som *s);

/* Winner neuron of every voxel (labels: n int32) and its colour (rgb: 3n floats,
 * interleaved; may be NULL). */
WVOL_API wvol_status wvol_som_classify(int32_t *labels, float *rgb, const wvol_som *s, const wvol_features *f,
                                       wvol_error *err);

/* Supervised step: gives each neuron the majority ground-truth class among the
 * voxels of the training mask (mask may be NULL = all voxels) it wins;
 * truth holds class ids >= 0. Neurons that win no training voxel take the class of
 * the nearest labelled neuron in feature space. */
WVOL_API wvol_status wvol_som_label(wvol_som *s, const wvol_features *f, const int32_t *truth,
                                    const uint8_t *mask, wvol_error *err);

/* Maps winner labels to classes through s->neuron_class (after wvol_som_label); a winner
 * outside the map's neurons (or no labels yet) maps to -1. */
WVOL_API void wvol_som_apply_classes(int32_t *classes, const int32_t *winners, size_t n, const wvol_som *s);

/* Evaluation: maps each predicted cluster to the ground-truth class it overlaps most
 * (majority), then counts misclassified voxels, overall and away from boundaries
 * (voxels whose (2r+1)^d neighbourhood holds one truth class). */
typedef struct wvol_seg_score {
    double error_all;        /* fraction misclassified */
    double error_interior;   /* same, away from boundaries; NaN when no voxel is (interior = 0) */
    size_t interior;         /* voxels counted as away from boundaries */
} wvol_seg_score;

WVOL_API wvol_status wvol_segmentation_score(wvol_seg_score *score, const int32_t *pred, const int32_t *truth,
                                             size_t nx, size_t ny, size_t nz, int boundary_radius,
                                             wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
