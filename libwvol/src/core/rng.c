/* SPDX-License-Identifier: MIT
 * The pseudo-random generator (wvol/rng.h).
 * Based on: Blackman & Vigna 2018 (xoshiro256**), Steele et al. 2014 (splitmix64). */
#include "wvol/rng.h"

#include <math.h>

uint64_t wvol_hash64(uint64_t x)
{
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

void wvol_rng_seed(wvol_rng *r, uint64_t seed)
{
    int i;
    uint64_t x = seed;
    if (!r) return;
    for (i = 0; i < 4; i++) {
        r->s[i] = wvol_hash64(x);
        x += 0x9E3779B97F4A7C15ull;
    }
}

static inline uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

uint64_t wvol_rng_next(wvol_rng *r)
{
    uint64_t *s, result, t;
    if (!r) return 0;
    s = r->s;
    result = rotl(s[1] * 5, 7) * 9;
    t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double wvol_rng_uniform(wvol_rng *r)
{
    return (double)(wvol_rng_next(r) >> 11) * (1.0 / 9007199254740992.0);
}

double wvol_rng_normal(wvol_rng *r)
{
    /* Box-Muller, one value per call: u1 in (0, 1] keeps the log finite. */
    if (!r) return 0.0;
    double u1 = 1.0 - wvol_rng_uniform(r), u2 = wvol_rng_uniform(r);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}
