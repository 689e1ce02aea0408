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

/* calloc(n, size), with huge pages asked for when the buffer is large. */
void *wvol__calloc_large(size_t n, size_t size);
/* malloc(bytes), likewise (for buffers the caller fills whole). */
void *wvol__malloc_large(size_t bytes);

#endif
