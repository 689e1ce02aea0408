/* SPDX-License-Identifier: MIT
 * The PCA of a build without LAPACKE (CMake leaves out pca.c then): answers
 * WVOL_ERR_UNSUPPORTED with a message naming the missing library. */
#include "wvol/analysis.h"

#ifndef WVOL_HAVE_LAPACKE
wvol_status wvol_features_pca(wvol_features *f, double variance, double *eigenvalues, wvol_error *err)
{
    (void)f, (void)variance, (void)eigenvalues;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                          "pca: this build has no LAPACKE (LAPACK's C interface), which the PCA needs");
}
#endif

/* ISO C wants at least one declaration in a translation unit. */
typedef int wvol__pca_missing_unused;
