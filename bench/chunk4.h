/* SPDX-License-Identifier: MIT
 * A prototype of a chunk coder with less work per coefficient (bench/chunk4.c), measured
 * against chunk modes 2 and 3 by bench_chunkcoder.c. Same conventions as the codec's
 * mode-3 coder (codec/wvc_internal.h): n detail bands of one extent; the decoder writes
 * only non-zeros into Q, which must be zero over the bands, and counts them. */
#ifndef WVOL_BENCH_CHUNK4_H
#define WVOL_BENCH_CHUNK4_H

#include "codec/wvc_internal.h"

/* Options of the prototype, so that one build measures the variants. */
typedef struct c4_opts {
    int raw_signs; /* 1: signs as raw bits; 0: a binary rANS model per band x sign(N) x sign(U) */
    int group;     /* coefficients per zero flag (a power of two, 4..64) */
    int comp;      /* compensation for W: 1 sign(N[x-1]) in the sign context; 2 the rows two above
                    * (y - 2, z - 2) in the magnitude sum; 4 the parent's x neighbours in its class */
    int with_w;    /* encoder only, to measure bits: W (the left neighbour) in the magnitude and
                    * sign contexts, as mode 3 has it (no decoder: that is the serial chain) */
    int simd;      /* decoder only, the same stream: 0 scalar; where the CPU has AVX2: 1 the magnitudes in
                    * AVX2, 2 the modelled signs too */
    int states;    /* magnitude states: 8 (0 means 8) or 16 (coefficient x on state x mod 16: the two
                    * halves of a group of 16 independent, for the AVX2 engine's two registers) */
    int sign_states; /* modelled signs' states: 4 (0 means 4) or 8 (with states = 16 only): the k-th
                      * non-zero of a group on sign state k mod 8, a group's signs in two vector steps */
} c4_opts;

int c4_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
              const wvc_band *const b[], const c4_opts *o);
int c4_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[], const uint8_t *buf,
              size_t size, const c4_opts *o, uint64_t *nonzero, const char **why);

#endif
