/* SPDX-License-Identifier: MIT
 * The library's one pseudo-random generator: xoshiro256** seeded through splitmix64, the
 * same bit stream on every platform for a seed (the Kohonen map's training order, the
 * synthetic generators' parameters and tests draw from it). Not for cryptography.
 * Threading: a wvol_rng is one stream; use one per thread. */
#ifndef WVOL_RNG_H
#define WVOL_RNG_H

#include "wvol/export.h"
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct wvol_rng {
    uint64_t s[4];
} wvol_rng;

/* A NULL generator: seed does nothing, next, uniform and normal return 0. */
WVOL_API void wvol_rng_seed(wvol_rng *r, uint64_t seed);
WVOL_API uint64_t wvol_rng_next(wvol_rng *r);
WVOL_API double wvol_rng_uniform(wvol_rng *r);  /* [0, 1) with 53 random bits */
WVOL_API double wvol_rng_normal(wvol_rng *r);   /* standard normal (Box-Muller) */

/* splitmix64 finaliser: a good 64-bit mixing hash (the seeding's, and counter-based noise). */
WVOL_API uint64_t wvol_hash64(uint64_t x);

#ifdef __cplusplus
}
#endif
#endif
