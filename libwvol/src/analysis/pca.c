/* SPDX-License-Identifier: MIT */
/* PCA decorrelation of the feature planes, then min-max normalisation to [0, 1]
 * (paper section 4.2: the amplitude distribution is unknown, so each component
 * is scaled straightforwardly by its minimum and maximum). */
#include "core/status_internal.h"
#include "wvol/analysis.h"

#include <dlfcn.h>
#include <lapacke.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* LAPACKE is loaded on the first PCA, not linked (CMakeLists.txt says why): dsyev from its
 * runtime library, by the names Debian and other distributions give it. */
typedef lapack_int (*dsyev_fn)(int layout, char jobz, char uplo, lapack_int n, double *a, lapack_int lda, double *w);
static pthread_once_t lapacke_once = PTHREAD_ONCE_INIT;
static dsyev_fn lapacke_dsyev;
static char lapacke_why[512];

static void lapacke_load(void)
{
    static const char *const names[] = {"liblapacke.so.3", "liblapacke.so"};
    lapacke_why[0] = '\0';
    for (size_t i = 0; i < sizeof names / sizeof *names && !lapacke_dsyev; i++) {
        void *h = dlopen(names[i], RTLD_NOW | RTLD_LOCAL);
        const char *e;
        if (!h) {
            e = dlerror();
            if (!lapacke_why[0]) snprintf(lapacke_why, sizeof lapacke_why, "%s", e ? e : names[i]);
            continue;
        }
        *(void **)&lapacke_dsyev = dlsym(h, "LAPACKE_dsyev");
        if (!lapacke_dsyev) {
            e = dlerror();
            snprintf(lapacke_why, sizeof lapacke_why, "%s has no LAPACKE_dsyev: %s", names[i], e ? e : "?");
            dlclose(h);
        }
    }
}

wvol_status wvol_features_pca(wvol_features *f, double variance, double *eigenvalues, wvol_error *err)
{
    size_t n;
    int F, keep;
    double *mean = NULL, *cov = NULL, *eval = NULL, total = 0, acc = 0;
    float *out = NULL;
    wvol_status s = WVOL_OK;

    WVOL_RETURN_IF(!f || !f->data || f->count < 1, err, WVOL_ERR_ARG, "pca: no features");
    WVOL_RETURN_IF(!(variance > 0 && variance <= 1), err, WVOL_ERR_ARG,
                   "pca: variance share %g must be in (0, 1]", variance);
    n = f->nx * f->ny * f->nz;
    F = f->count;
    mean = calloc((size_t)F, sizeof *mean);
    cov = calloc((size_t)F * (size_t)F, sizeof *cov);
    eval = calloc((size_t)F, sizeof *eval);
    if (!mean || !cov || !eval) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "pca: out of memory");
        goto done;
    }
    for (int a = 0; a < F; a++) {
        const float *pa = f->data + (size_t)a * n;
        double sum = 0;
        for (size_t i = 0; i < n; i++) sum += pa[i];
        mean[a] = sum / (double)n;
    }
    /* covariance in float64; upper triangle, one pair of planes at a time */
    #pragma omp parallel for schedule(dynamic)
    for (int a = 0; a < F; a++) {
        const float *pa = f->data + (size_t)a * n;
        for (int b = a; b < F; b++) {
            const float *pb = f->data + (size_t)b * n;
            double sum = 0;
            for (size_t i = 0; i < n; i++) sum += ((double)pa[i] - mean[a]) * ((double)pb[i] - mean[b]);
            cov[(size_t)a * F + b] = cov[(size_t)b * F + a] = sum / (double)n;
        }
    }
    /* eigenvectors in the columns of cov (row-major: cov[i*F + j] = component j's weight i) */
    pthread_once(&lapacke_once, lapacke_load);
    if (!lapacke_dsyev) {
        s = wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "pca: LAPACKE (LAPACK's C interface) could not be loaded: %s",
                           lapacke_why);
        goto done;
    }
    if (lapacke_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', F, cov, F, eval) != 0) {
        s = wvol_error_set(err, WVOL_ERR_INTERNAL, "pca: LAPACK dsyev did not converge");
        goto done;
    }
    /* dsyev sorts ascending; we take components from the last (largest) down */
    for (int j = 0; j < F; j++) total += eval[j] > 0 ? eval[j] : 0;
    keep = 0;
    for (int j = F - 1; j >= 0; j--) {
        acc += eval[j] > 0 ? eval[j] : 0;
        keep++;
        if (total <= 0 || acc >= variance * total - 1e-15 * total) break;
    }
    if (eigenvalues)
        for (int c = 0; c < keep; c++) eigenvalues[c] = eval[F - 1 - c];
    out = malloc((size_t)keep * n * sizeof(float));
    if (!out) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "pca: out of memory");
        goto done;
    }
    #pragma omp parallel for schedule(static)
    for (long ii = 0; ii < (long)n; ii++) {
        size_t i = (size_t)ii;
        for (int c = 0; c < keep; c++) {
            int col = F - 1 - c;
            double v = 0;
            for (int a = 0; a < F; a++) v += cov[(size_t)a * F + col] * ((double)f->data[(size_t)a * n + i] - mean[a]);
            out[(size_t)c * n + i] = (float)v;
        }
    }
    for (int c = 0; c < keep; c++) {
        float *pc = out + (size_t)c * n, lo = pc[0], hi = pc[0];
        for (size_t i = 0; i < n; i++) {
            lo = pc[i] < lo ? pc[i] : lo;
            hi = pc[i] > hi ? pc[i] : hi;
        }
        float inv = hi > lo ? 1.0f / (hi - lo) : 0.0f;
        if (isfinite(inv) && isfinite(hi - lo)) {
            for (size_t i = 0; i < n; i++) pc[i] = (pc[i] - lo) * inv;
        } else {
            /* a range below 1/FLT_MAX (a volume ~1e-35: 1/range overflows, 0 * Inf is NaN) or
             * beyond FLT_MAX: the same map in double */
            double dinv = 1.0 / ((double)hi - (double)lo);
            for (size_t i = 0; i < n; i++) pc[i] = (float)(((double)pc[i] - (double)lo) * dinv);
        }
    }
    free(f->data);
    f->data = out;
    f->count = keep;
    out = NULL;
done:
    free(mean);
    free(cov);
    free(eval);
    free(out);
    return s;
}
