/* SPDX-License-Identifier: MIT
 * The library's two error-handling shortcuts (not installed; modelled on zstd's
 * RETURN_ERROR_IF and FORWARD_IF_ERROR). Each module's internal header includes
 * this; a source without one includes it directly. */
#ifndef WVOL_CORE_STATUS_INTERNAL_H
#define WVOL_CORE_STATUS_INTERNAL_H

#include "wvol/status.h"

/* Return with an error when cond holds. */
#define WVOL_RETURN_IF(cond, err, status, ...)                     \
    do {                                                           \
        if (cond) return wvol_error_set((err), (status), __VA_ARGS__); \
    } while (0)

/* Propagate a non-OK status. */
#define WVOL_FORWARD(expr)               \
    do {                                 \
        wvol_status wvol__s_ = (expr);   \
        if (wvol__s_ != WVOL_OK) return wvol__s_; \
    } while (0)

#endif
