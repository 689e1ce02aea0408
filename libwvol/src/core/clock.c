/* SPDX-License-Identifier: MIT
 * Clocks and the thread count (core/clock.h). */
#define _POSIX_C_SOURCE 200809L
#include "core/clock.h"

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
