/* SPDX-License-Identifier: MIT */
/* Analysis in wavelet space: features, PCA, Kohonen map, scoring. */
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/analysis.h"
#include "wvol_synth.h"

/* measured: see the printed value; the bound leaves room for the SOM's randomness */
#define WVOL_TEST_MOSAIC_BOUND 0.05

/* A 2D image with two gratings of different frequency: period 4 in the middle half,
 * period 16 in the outer quarters (so the periodic wrap of the transform joins a
 * texture with itself). The features must separate them: away from the two
 * boundaries (radius 8 = 2^levels) the majority-mapped error is zero. */
static void test_two_gratings(void)
{
    const size_t n = 64;
    wvol_volume *v = NULL;
    wvol_features *f = NULL;
    wvol_som *som = NULL;
    wvol_feature_params fp;
    wvol_som_params sp;
    wvol_seg_score score;
    wvol_error err;
    int32_t *truth = malloc(n * n * sizeof *truth), *lab = malloc(n * n * sizeof *lab);
    wvol_volume_create(&v, n, n, 1, &err);
    for (size_t j = 0; j < n; j++)
        for (size_t i = 0; i < n; i++) {
            int middle = i >= n / 4 && i < 3 * n / 4;
            v->data[i + n * j] = (float)sin(2 * M_PI * (double)i / (middle ? 4.0 : 16.0));
            truth[i + n * j] = middle;
        }
    wvol_feature_params_default(&fp);
    fp.levels = 3;
    CHECK(wvol_features_compute(&f, v, fixture_filter("db2"), &fp, &err) == WVOL_OK, "features: %s", err.message);
    CHECK(f && f->count == 3 * (3 + 1), "2D: 3 bands + low-pass per level, got %d", f ? f->count : -1);
    CHECK(wvol_features_pca(f, 1.0, NULL, &err) == WVOL_OK, "pca: %s", err.message);
    for (int c = 0; f && c < f->count; c++) {
        float lo = 1, hi = 0;
        for (size_t i = 0; i < n * n; i++) {
            lo = f->data[c * n * n + i] < lo ? f->data[c * n * n + i] : lo;
            hi = f->data[c * n * n + i] > hi ? f->data[c * n * n + i] : hi;
        }
        CHECK(lo >= 0 && hi <= 1, "component %d normalised to [0,1]: %g..%g", c, lo, hi);
    }
    wvol_som_params_default(&sp);
    sp.dims[0] = 2;
    sp.dims[1] = 1;
    sp.dims[2] = 1;
    sp.iterations = 4000;
    CHECK(wvol_som_train(&som, f, &sp, &err) == WVOL_OK, "som: %s", err.message);
    CHECK(wvol_som_classify(lab, NULL, som, f, &err) == WVOL_OK, "classify: %s", err.message);
    CHECK(wvol_segmentation_score(&score, lab, truth, n, n, 1, 8, &err) == WVOL_OK, "score");
    CHECK(score.interior > 0, "interior pixels to score");
    CHECK(score.error_interior == 0.0, "two gratings split cleanly away from the boundary: %g",
          score.error_interior);
    wvol_som_destroy(som);
    wvol_features_destroy(f);
    wvol_volume_destroy(v);
    free(truth);
    free(lab);
}

/* Determinism: the same seed gives the same map and labels. */
static void test_determinism(void)
{
    wvol_synth_params p;
    wvol_volume *v = NULL, *labels = NULL;
    wvol_features *f = NULL;
    wvol_som *a = NULL, *b = NULL;
    wvol_som_params sp;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[0] = p.dims[1] = 64;
    p.dims[2] = 1;
    CHECK(wvol_synth_textures(&v, &labels, &p, &err) == WVOL_OK, "textures: %s", err.message);
    CHECK(wvol_features_compute(&f, v, fixture_filter("haar"), NULL, &err) == WVOL_OK, "features: %s", err.message);
    CHECK(f && wvol_features_pca(f, 1.0, NULL, &err) == WVOL_OK, "pca: %s", err.message);
    wvol_som_params_default(&sp);
    sp.iterations = 2000;
    CHECK(f && wvol_som_train(&a, f, &sp, &err) == WVOL_OK, "som a: %s", err.message);
    CHECK(f && wvol_som_train(&b, f, &sp, &err) == WVOL_OK, "som b: %s", err.message);
    CHECK(a && b && memcmp(a->weights, b->weights, (size_t)a->neurons * a->features * sizeof(float)) == 0,
          "same seed, same weights");
    wvol_som_destroy(b);
    b = NULL;
    sp.seed = 2;
    wvol_som_train(&b, f, &sp, &err);
    CHECK(a && b && memcmp(a->weights, b->weights, (size_t)a->neurons * a->features * sizeof(float)) != 0,
          "another seed, other weights");
    wvol_som_destroy(a);
    wvol_som_destroy(b);
    wvol_features_destroy(f);
    wvol_volume_destroy(v);
    wvol_volume_destroy(labels);
}

/* The texture mosaic of datasets-synth, 4 gratings: misclassification away from the
 * boundaries after majority mapping. Bound measured (see docs/analysis.md). */
static void test_gratings_mosaic(void)
{
    const size_t n = 128;
    wvol_synth_params p;
    wvol_volume *v = NULL, *labels = NULL;
    wvol_features *f = NULL;
    wvol_som *som = NULL;
    wvol_som_params sp;
    wvol_feature_params fp;
    wvol_seg_score score;
    wvol_error err;
    int32_t *truth = malloc(n * n * sizeof *truth), *lab = malloc(n * n * sizeof *lab);
    wvol_synth_params_default(&p);
    p.dims[0] = p.dims[1] = n;
    p.dims[2] = 1;
    p.variant = "gratings";
    CHECK(wvol_synth_textures(&v, &labels, &p, &err) == WVOL_OK, "textures: %s", err.message);
    for (size_t i = 0; labels && i < n * n; i++) truth[i] = (int32_t)labels->data[i];
    wvol_feature_params_default(&fp);
    fp.levels = 3;
    CHECK(wvol_features_compute(&f, v, fixture_filter("db2"), &fp, &err) == WVOL_OK, "features: %s", err.message);
    CHECK(f && wvol_features_pca(f, 1.0, NULL, &err) == WVOL_OK, "pca: %s", err.message);
    wvol_som_params_default(&sp);
    CHECK(f && wvol_som_train(&som, f, &sp, &err) == WVOL_OK, "som: %s", err.message);
    CHECK(som && wvol_som_classify(lab, NULL, som, f, &err) == WVOL_OK, "classify");
    memset(&score, 0, sizeof score);
    CHECK(wvol_segmentation_score(&score, lab, truth, n, n, 1, 8, &err) == WVOL_OK, "score: %s", err.message);
    CHECK(score.interior > 0, "interior pixels to score");
    printf("gratings mosaic 128^2 db2 M=3: error %.3f overall, %.3f interior (%zu px)\n", score.error_all,
           score.error_interior, score.interior);
    CHECK(score.error_interior < WVOL_TEST_MOSAIC_BOUND, "interior error %.4f", score.error_interior);
    wvol_som_destroy(som);
    wvol_features_destroy(f);
    wvol_volume_destroy(v);
    wvol_volume_destroy(labels);
    free(truth);
    free(lab);
}

static void test_bad_input(void)
{
    wvol_volume *v = NULL;
    wvol_features *f = NULL;
    wvol_feature_params fp;
    wvol_som_params sp;
    wvol_som *som = NULL;
    wvol_error err;
    wvol_volume_create(&v, 8, 8, 8, &err);
    wvol_feature_params_default(&fp);
    fp.levels = 10;
    CHECK(wvol_features_compute(&f, v, fixture_filter("haar"), &fp, &err) == WVOL_ERR_ARG && !f, "too many levels");
    fp.levels = 1;
    v->data[3] = NAN;
    CHECK(wvol_features_compute(&f, v, fixture_filter("haar"), &fp, &err) == WVOL_ERR_NONFINITE, "NaN refused");
    v->data[3] = 0;
    CHECK(wvol_features_compute(&f, v, fixture_filter("haar"), &fp, &err) == WVOL_OK, "constant volume ok");
    CHECK(wvol_features_pca(f, 1.5, NULL, &err) == WVOL_ERR_ARG, "variance > 1 refused");
    CHECK(wvol_features_pca(f, 1.0, NULL, &err) == WVOL_OK, "pca of constant features: %s", err.message);
    wvol_som_params_default(&sp);
    sp.dims[0] = 0;
    CHECK(wvol_som_train(&som, f, &sp, &err) == WVOL_ERR_ARG && !som, "zero lattice refused");
    wvol_som_params_default(&sp);
    if (f) {
        f->data[5] = NAN;
        CHECK(wvol_som_train(&som, f, &sp, &err) == WVOL_ERR_NONFINITE && !som && strstr(err.message, "NaN"),
              "NaN features refused: %s", err.message);
    }
    wvol_features_destroy(f);
    wvol_volume_destroy(v);
}

/* Scores: every voxel within the radius of a class boundary leaves no interior, whose error is
 * then undefined (NaN), not 0; the overall error is still counted. */
static void test_score_without_interior(void)
{
    enum { n = 6 };
    int32_t truth[n * n], pred[n * n];
    wvol_seg_score score;
    wvol_error err;
    for (int i = 0; i < n * n; i++) {
        truth[i] = (i % n) < n / 2; /* two halves along x */
        pred[i] = i == 0 ? 1 - truth[i] : truth[i];
    }
    CHECK(wvol_segmentation_score(&score, pred, truth, n, n, 1, n, &err) == WVOL_OK, "score: %s", err.message);
    CHECK(score.interior == 0 && isnan(score.error_interior), "no interior: NaN, not %g (%zu voxels)",
          score.error_interior, score.interior);
    CHECK(fabs(score.error_all - 1.0 / (n * n)) < 1e-12, "one voxel of %d misclassified: %g", n * n, score.error_all);
    CHECK(wvol_segmentation_score(&score, pred, truth, n, n, 1, 1, &err) == WVOL_OK && score.interior > 0 &&
              isfinite(score.error_interior),
          "radius 1 leaves an interior: %zu voxels, error %g", score.interior, score.error_interior);
}

int main(void)
{
    test_score_without_interior();
    test_two_gratings();
    test_determinism();
    test_gratings_mosaic();
    test_bad_input();
    return check_summary("test_analysis");
}
