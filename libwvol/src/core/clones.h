/* SPDX-License-Identifier: MIT
 * Function multi-versioning for hot loops (not installed): on x86-64 with GCC a function
 * marked WVOL__CLONES is compiled twice, for the baseline and for x86-64-v3 (AVX2, FMA,
 * POPCNT), and the copy for the running CPU is picked at load time; the build itself stays
 * portable (no -march). Elsewhere, and under AddressSanitizer (whose interceptors and
 * ifunc resolvers do not mix), it is compiled once. */
#ifndef WVOL_CORE_CLONES_H
#define WVOL_CORE_CLONES_H

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__SANITIZE_ADDRESS__) && \
    !defined(WVOL_NO_CLONES)
#define WVOL__CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
/* A third copy for x86-64-v4 (AVX-512), for kernels whose live vectors outnumber AVX2's 16
 * registers: the same 256-bit arithmetic, with AVX-512VL's 32 registers instead of spills
 * to the stack (the quantiser's eight double accumulators). */
#define WVOL__CLONES_V4 __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
/* A kernel written for x86-64-v4 with its intrinsics (immintrin.h), called only where
 * WVOL__CPU_V4() says the CPU has that level; WVOL__HAVE_V4 says whether such kernels are
 * compiled at all. */
#define WVOL__HAVE_V4 1
#define WVOL__TARGET_V4 __attribute__((target("arch=x86-64-v4")))
#define WVOL__CPU_V4() __builtin_cpu_supports("x86-64-v4")
#else
#define WVOL__CLONES
#define WVOL__CLONES_V4
#define WVOL__HAVE_V4 0
#define WVOL__CPU_V4() 0
#endif

/* Contraction off for one function, so that no clone fuses a product and a sum into one FMA
 * (docs/wvc-format.md, "The same bytes on every CPU"): GCC's optimize attribute. Clang has no
 * such attribute; CMakeLists.txt compiles the files that use these with -ffp-contract=off
 * there. _NO_TRAP adds GCC's no-trapping-math (clang's default), for loops whose branches GCC
 * otherwise keeps so as not to compute an unused lane's value. */
#if defined(__GNUC__) && !defined(__clang__)
#define WVOL__NO_CONTRACT __attribute__((optimize("fp-contract=off")))
#define WVOL__NO_CONTRACT_NO_TRAP __attribute__((optimize("fp-contract=off", "no-trapping-math")))
#else
#define WVOL__NO_CONTRACT
#define WVOL__NO_CONTRACT_NO_TRAP
#endif

#endif
