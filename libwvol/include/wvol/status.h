/* SPDX-License-Identifier: MIT */
/* Status codes and error messages. Every fallible call returns a wvol_status
 * (0 = OK; published values never change) and, when the caller passes a
 * wvol_error, fills it with a message that names the problem and its context.
 * The library never prints, exits or aborts, and keeps no global error state. */
#ifndef WVOL_STATUS_H
#define WVOL_STATUS_H

#include "wvol/export.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum wvol_status {
    WVOL_OK = 0,
    WVOL_ERR_ARG = 1,          /* bad argument or option value */
    WVOL_ERR_NOMEM = 2,        /* allocation failed or size overflows */
    WVOL_ERR_IO = 3,           /* file cannot be opened, read or written */
    WVOL_ERR_FORMAT = 4,       /* file content is malformed, truncated or corrupt */
    WVOL_ERR_UNSUPPORTED = 5,  /* feature not built in, or format variant not handled */
    WVOL_ERR_NONFINITE = 6,    /* NaN or Inf in the input */
    WVOL_ERR_DIMS = 7,         /* dimensions invalid, inconsistent or overflowing */
    WVOL_ERR_INTERNAL = 8,     /* a bug: an invariant did not hold */
    WVOL_ERR_NUMERIC = 9       /* an iterative computation did not converge: no result */
} wvol_status;

#define WVOL_ERROR_MSG_MAX 512

/* Caller-owned error record; any function taking `wvol_error *err` accepts NULL. */
typedef struct wvol_error {
    wvol_status status;
    char message[WVOL_ERROR_MSG_MAX];
} wvol_error;

/* Short fixed description of a status code ("bad argument", ...). */
WVOL_API const char *wvol_status_string(wvol_status s);

/* Fills err (if not NULL) with status and a printf-style message; returns status. */
WVOL_API wvol_status wvol_error_set(wvol_error *err, wvol_status status, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Resets err to OK with an empty message. */
WVOL_API void wvol_error_clear(wvol_error *err);

/* Prefixes the existing message with context ("reading x.nrrd: ..."). */
WVOL_API void wvol_error_prefix(wvol_error *err, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

#ifdef __cplusplus
}
#endif
#endif
