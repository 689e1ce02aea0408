/* SPDX-License-Identifier: MIT
 * Clocks and the thread count the modules report and run with (not installed). */
#ifndef WVOL_CORE_CLOCK_H
#define WVOL_CORE_CLOCK_H

#include "wvol/status.h"

/* Monotonic wall-clock seconds, and the process's CPU seconds (all threads). */
double wvol__now(void);
double wvol__cpu_now(void);
/* OpenMP thread count for a requested count (0 = OpenMP's default). */
int wvol__threads(int requested);

/* The most threads an entry point accepts: each thread is started with its stack and scratch,
 * so a count beyond any machine's cores would exhaust the memory, not run faster. */
#define WVOL__MAX_THREADS 4096

/* WVOL_OK for a requested count in 0..WVOL__MAX_THREADS, else WVOL_ERR_ARG with
 * "WHO: threads N outside 0..4096 (0: OpenMP's default)". */
wvol_status wvol__threads_check(int requested, const char *who, wvol_error *err);

#endif
