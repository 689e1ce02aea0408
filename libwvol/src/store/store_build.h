/* SPDX-License-Identifier: MIT
 * The store's internal interface for the compression pipeline (pipeline/compress.c): a build
 * from coefficients the caller has already tested for NaN and Inf. Not installed. */
#ifndef WVOL_STORE_BUILD_H
#define WVOL_STORE_BUILD_H

#include "wvol/store.h"

/* wvol_store_build without its pass over the coefficients for NaN and Inf: for coefficients
 * wvol_select has just read (it refuses non-finite ones), which are then read once, not
 * twice. */
wvol_status wvol__store_build_tested(wvol_store **out, const wvol_coeffs *c, const wvol_selection *sel,
                                     const wvol_store_params *prm, wvol_error *err);

#endif
