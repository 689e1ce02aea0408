/* Small helpers several C tests share. */
#ifndef WVOL_TEST_FIXTURES_H
#define WVOL_TEST_FIXTURES_H

#include <stddef.h>
#include <stdint.h>

#include "wvol/wavelet.h"

/* xorshift64 on the caller's state (each test seeds its own): deterministic, [0, 1)
 * from the top 53 bits. */
static inline double fixture_urand(uint64_t *state)
{
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    return (double)(*state >> 11) * (1.0 / 9007199254740992.0);
}

/* A filter by name; NULL if unknown (the tests name filters that exist). */
static inline const wvol_filter *fixture_filter(const char *name)
{
    const wvol_filter *f = NULL;
    wvol_filter_get(&f, name, NULL);
    return f;
}

#endif
