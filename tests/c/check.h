/* SPDX-License-Identifier: MIT */
/* Minimal test harness: CHECK records a failure and goes on; the test's main
 * returns check_summary(), which prints "N passed, N failed" and the exit code. */
#ifndef WVOL_TEST_CHECK_H
#define WVOL_TEST_CHECK_H

#include <math.h>
#include <stdio.h>

/* WVOL_TEST_ASAN: built with AddressSanitizer (GCC says so by __SANITIZE_ADDRESS__, clang by
 * __has_feature), where tests trim their slowest loops and skip resident-memory checks. */
#if defined(__SANITIZE_ADDRESS__)
#define WVOL_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define WVOL_TEST_ASAN 1
#endif
#endif

static int check_passed, check_failed;

#define CHECK(cond, ...)                                                   \
    do {                                                                   \
        if (cond) {                                                        \
            check_passed++;                                                \
        } else {                                                           \
            check_failed++;                                                \
            fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                  \
            fputc('\n', stderr);                                           \
        }                                                                  \
    } while (0)

/* |a - b| <= tol, with the values in the message. */
#define CHECK_NEAR(a, b, tol, what)                                                       \
    CHECK(fabs((double)(a) - (double)(b)) <= (tol), "%s: %.17g vs %.17g (tol %.3g)", what, \
          (double)(a), (double)(b), (double)(tol))

static inline int check_summary(const char *name)
{
    printf("%s: %d passed, %d failed\n", name, check_passed, check_failed);
    return check_failed ? 1 : 0;
}

#endif
