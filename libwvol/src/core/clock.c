/* SPDX-License-Identifier: MIT
 * Clocks and the thread count (core/clock.h). */
#define _POSIX_C_SOURCE 200809L
#include "core/clock.h"
#include "core/status_internal.h"

#include <omp.h>
#include <time.h>

double wvol__now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double wvol__cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int wvol__threads(int requested)
{
    return requested > 0 ? requested : omp_get_max_threads();
}

wvol_status wvol__threads_check(int requested, const char *who, wvol_error *err)
{
    WVOL_RETURN_IF(requested < 0 || requested > WVOL__MAX_THREADS, err, WVOL_ERR_ARG,
                   "%s: threads %d outside 0..%d (0: OpenMP's default)", who, requested, WVOL__MAX_THREADS);
    return WVOL_OK;
}
