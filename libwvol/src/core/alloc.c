/* SPDX-License-Identifier: MIT */
/* Large buffers backed by transparent huge pages (core/alloc.h says why). */
#define _DEFAULT_SOURCE
#include "core/alloc.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

enum { HUGE_PAGE = 2u << 20, LARGE = 8u << 20, PAGED = 1u << 20 };

/* Asks for huge pages over the whole 2 MiB pages inside [p, p + bytes). glibc serves
 * buffers this large from a fresh mapping that it neither reads nor clears, so the
 * advice comes before the first touch. */
static void advise_huge(void *p, size_t bytes)
{
#ifdef MADV_HUGEPAGE
    uintptr_t a = ((uintptr_t)p + HUGE_PAGE - 1) & ~(uintptr_t)(HUGE_PAGE - 1);
    uintptr_t b = ((uintptr_t)p + bytes) & ~(uintptr_t)(HUGE_PAGE - 1);
    if (p && bytes >= LARGE && b > a) (void)madvise((void *)a, b - a, MADV_HUGEPAGE);
#else
    (void)p, (void)bytes;
#endif
}

void *wvol__calloc_large(size_t n, size_t size)
{
    void *p = calloc(n, size);
    if (p) advise_huge(p, n * size); /* calloc refused an overflowing n * size */
    return p;
}

void *wvol__malloc_large(size_t bytes)
{
    /* whole huge pages from the start: malloc's block starts a little past a page, and the
     * 4 KiB pages before its first and after its last 2 MiB boundary (up to 4 MiB) were
     * faulted one by one. The caller fills the buffer whole, so the rounding costs no
     * untouched page. */
    if (bytes >= PAGED) return wvol__malloc_pages(&bytes);
    return malloc(bytes);
}

void *wvol__realloc_large(void *p, size_t bytes)
{
    void *q = realloc(p, bytes);
    advise_huge(q, bytes);
    return q;
}

size_t wvol__pages_bytes(size_t bytes)
{
    if (bytes < PAGED || bytes > SIZE_MAX - HUGE_PAGE) return bytes;
    return (bytes + HUGE_PAGE - 1) & ~(size_t)(HUGE_PAGE - 1);
}

void *wvol__malloc_pages(size_t *bytes)
{
    void *p = NULL;
    size_t n = *bytes;
    if (n < PAGED) return malloc(n ? n : 1);
    if (n > SIZE_MAX - HUGE_PAGE) return NULL;
    n = wvol__pages_bytes(n);
    if (posix_memalign(&p, HUGE_PAGE, n) != 0) return NULL;
#ifdef MADV_HUGEPAGE
    (void)madvise(p, n, MADV_HUGEPAGE); /* p and n whole huge pages; glibc has not touched them */
#endif
    *bytes = n;
    return p;
}
