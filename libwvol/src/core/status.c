/* SPDX-License-Identifier: MIT */
#include "wvol/status.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

const char *wvol_status_string(wvol_status s)
{
    switch (s) {
    case WVOL_OK: return "ok";
    case WVOL_ERR_ARG: return "bad argument";
    case WVOL_ERR_NOMEM: return "out of memory";
    case WVOL_ERR_IO: return "i/o error";
    case WVOL_ERR_FORMAT: return "malformed input";
    case WVOL_ERR_UNSUPPORTED: return "unsupported";
    case WVOL_ERR_NONFINITE: return "non-finite value";
    case WVOL_ERR_DIMS: return "bad dimensions";
    case WVOL_ERR_INTERNAL: return "internal error";
    case WVOL_ERR_NUMERIC: return "did not converge";
    }
    return "unknown status";
}

wvol_status wvol_error_set(wvol_error *err, wvol_status status, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        err->status = status;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return status;
}

void wvol_error_clear(wvol_error *err)
{
    if (err) {
        err->status = WVOL_OK;
        err->message[0] = '\0';
    }
}

void wvol_error_prefix(wvol_error *err, const char *fmt, ...)
{
    char prefix[WVOL_ERROR_MSG_MAX], old[WVOL_ERROR_MSG_MAX];
    va_list ap;
    if (!err) return;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, err->message, sizeof old);
    /* prefix + ": " + old, truncated to the buffer (strings copied by hand so the
     * compiler's format-truncation check has nothing to flag) */
    {
        size_t cap = sizeof err->message - 1, n = 0, k;
        for (k = 0; prefix[k] && n < cap; k++) err->message[n++] = prefix[k];
        for (k = 0; ": "[k] && n < cap; k++) err->message[n++] = ": "[k];
        for (k = 0; old[k] && n < cap; k++) err->message[n++] = old[k];
        err->message[n] = '\0';
    }
}
