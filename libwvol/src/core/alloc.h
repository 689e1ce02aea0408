/* SPDX-License-Identifier: MIT */
/* Large buffers (volumes, coefficient pyramids, transform scratch) backed by huge pages
 * where the system allows it. A fresh 64 MiB buffer costs 16384 page faults in 4 KiB
 * pages, each with its own trip into the kernel to map and clear a page; decoding and
 * reconstructing a 256^3 volume touches three such buffers, and the faults were a large
 * part of its time. Transparent huge pages (2 MiB) cut that 512-fold. The memory comes
 * from malloc/calloc and goes back with free(), as before: only the kernel's paging of
 * it changes, asked for with madvise(MADV_HUGEPAGE) before the first touch. Where THP is
 * off or madvise fails, nothing else changes. */
#ifndef WVOL_CORE_ALLOC_H
#define WVOL_CORE_ALLOC_H

#include <stddef.h>
#include <stdlib.h>

/* calloc(n, size); from 1 MiB on, whole huge pages as wvol__malloc_pages gives them. */
void *wvol__calloc_large(size_t n, size_t size);
/* malloc(bytes), likewise (for buffers the caller fills whole): from 1 MiB on, as
 * wvol__malloc_pages (whole huge pages, aligned). */
void *wvol__malloc_large(size_t bytes);
/* realloc(p, bytes), huge pages asked for over its whole 2 MiB pages from 8 MiB on (a
 * buffer that large is moved into a fresh mapping of its own, not touched beyond the old
 * contents copied in). */
void *wvol__realloc_large(void *p, size_t bytes);

/* Scratch whose old contents never matter (a slot regrown is allocated afresh, nothing
 * copied): at least *bytes bytes; from 1 MiB on, whole 2 MiB pages, aligned and asked for
 * huge pages, *bytes then rounded up to them (the caller may use all of it). Buffers of a
 * few MiB, below wvol__malloc_large's threshold, are where a fresh allocation's 4 KiB first
 * touches cost most against their use (a reconstruction's band arrays). Free with free(). */
void *wvol__malloc_pages(size_t *bytes);
/* The size wvol__malloc_pages gives for a request of `bytes` (a buffer's resident size
 * once it is filled: whole huge pages from 1 MiB on), for callers who account memory. */
size_t wvol__pages_bytes(size_t bytes);

/* Large buffers kept between one use and the next. A fresh mapping's pages are cleared by the
 * kernel on first touch, huge pages too, and on the machines measured that clearing costs more
 * than, say, a marching cubes that fills a mesh's arrays (bench/results/iso_topology.md);
 * malloc's heap reuses the memory of small blocks, but gives blocks this large back to the
 * system on free. A program that does the same work again in one process (a Python loop over
 * iso-values or time steps, a viewer re-executing a filter, a benchmark's repetitions) gets
 * pages it has touched before from this pool instead. Bounded: 8 buffers and 128 MiB of their
 * used bytes held at most, the oldest given back first.
 * wvol__reuse_get: at least `bytes` bytes of unspecified contents (the caller fills them): a
 * kept buffer of at most twice that size (counted in whole huge pages), else
 * wvol__malloc_large's. NULL when out of memory. Blocks from 64 KiB to 1 MiB, which malloc's
 * heap gives back to the system when freed at its top (a writer's chunk payloads, made and
 * freed a few at a time), are kept in a tier of their own (wvol__reuse_held_mid); smaller
 * ones are plain malloc.
 * wvol__reuse_put: gives p back (NULL is fine): kept when it is large enough to be worth it
 * and fits the bound, else freed. Any malloc'ed block may be given back, and a block from
 * wvol__reuse_get may be freed with free() instead. Both are thread-safe. */
void *wvol__reuse_get(size_t bytes);
void wvol__reuse_put(void *p);
/* wvol__reuse_put for a block whose first `used` bytes alone were touched (a large
 * reservation filled in part): those count against the bound, not the whole block. */
void wvol__reuse_put_used(void *p, size_t used);
/* The pool's buffers and bytes held now (tests): its large buffers, and (_mid) the blocks
 * from 64 KiB to 2 MiB it keeps beside them (16 blocks and 16 MiB at most), which serve
 * requests from 64 KiB to 1 MiB of at least half their size. */
void wvol__reuse_held(size_t *buffers, size_t *bytes);
void wvol__reuse_held_mid(size_t *buffers, size_t *bytes);

/* An array *p of *cap elements of elem bytes grown by doubling (from `first` elements when
 * empty) until it holds need; 1, or 0 when out of memory (*p and *cap then unchanged). */
static inline int wvol__grow(void **p, size_t *cap, size_t need, size_t elem, size_t first)
{
    size_t n = *cap ? *cap : first;
    void *q;
    if (need <= *cap) return 1;
    while (n < need) n *= 2;
    q = realloc(*p, n * elem);
    if (!q) return 0;
    *p = q;
    *cap = n;
    return 1;
}

#endif
