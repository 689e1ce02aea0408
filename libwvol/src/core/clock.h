/* SPDX-License-Identifier: MIT
 * Clocks and the thread count the modules report and run with (not installed). */
#ifndef WVOL_CORE_CLOCK_H
#define WVOL_CORE_CLOCK_H

/* Monotonic wall-clock seconds, and the process's CPU seconds (all threads). */
double wvol__now(void);
double wvol__cpu_now(void);
/* OpenMP thread count for a requested count (0 = OpenMP's default). */
int wvol__threads(int requested);

#endif
