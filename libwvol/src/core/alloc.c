/* SPDX-License-Identifier: MIT */
/* Large buffers backed by transparent huge pages (core/alloc.h says why). */
#define _DEFAULT_SOURCE
#include "core/alloc.h"

#include <malloc.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
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
    size_t bytes;
    void *p;
    if (size && n > SIZE_MAX / size) return NULL;
    bytes = n * size;
    if (bytes < PAGED) return calloc(n, size);
    /* Whole huge pages, as wvol__malloc_pages: calloc's block starts a little past a page,
     * and the 4 KiB pages before its first and after its last 2 MiB boundary (up to 4 MiB)
     * were faulted one by one, at a cost per page that on some virtual machines is many times
     * the clearing of a huge page. The block may be heap memory used before: MADV_DONTNEED
     * clears it without writing it (the block is whole pages of its own in a private
     * anonymous mapping, whose dropped pages read as zero, fresh from the kernel when
     * touched); memset where the advice is refused. */
    p = wvol__malloc_pages(&bytes);
    if (!p) return NULL;
#ifdef MADV_DONTNEED
    if (madvise(p, bytes, MADV_DONTNEED) != 0)
#endif
        memset(p, 0, bytes);
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

/* ---- the reuse pool (core/alloc.h) ---- */

enum { POOL_SLOTS = 8 };
#define POOL_BYTES ((size_t)128 << 20)
static struct {
    void *p;
    size_t bytes; /* counted against POOL_BYTES: the block's touched bytes, at most its usable size */
    size_t cls;   /* what it serves: bytes in whole huge pages, rounded down (an aligned block's
                     usable size runs to the end of its mapping, up to a huge page more) */
    unsigned long age;
} pool[POOL_SLOTS];
static size_t pool_total;
static unsigned long pool_clock;
static pthread_mutex_t pool_lock = PTHREAD_MUTEX_INITIALIZER;

/* The middle tier: blocks from MID_MIN to a huge page, served to requests of at least half
 * their size. malloc's heap grows and shrinks with them at its top: a writer's few chunk
 * payloads of some hundred KiB each, made and freed in turn, were trimmed from the heap and
 * faulted in again, 4 KiB at a time, every few chunks. Requests are rounded up to MID_MIN so that
 * the next one, a little larger, finds the block given back. */
enum { MID_SLOTS = 16, MID_MIN = 64u << 10 };
#define MID_BYTES ((size_t)16 << 20)
static struct {
    void *p;
    size_t size; /* usable bytes */
    unsigned long age;
} mid[MID_SLOTS];
static size_t mid_total;

static void *mid_get(size_t bytes)
{
    void *p = NULL;
    int best = -1;
    pthread_mutex_lock(&pool_lock);
    for (int i = 0; i < MID_SLOTS; i++)
        if (mid[i].p && mid[i].size >= bytes && mid[i].size / 2 <= bytes &&
            (best < 0 || mid[i].size < mid[best].size))
            best = i;
    if (best >= 0) {
        p = mid[best].p;
        mid_total -= mid[best].size;
        mid[best].p = NULL;
    }
    pthread_mutex_unlock(&pool_lock);
    return p ? p : malloc((bytes + MID_MIN - 1) & ~(size_t)(MID_MIN - 1));
}

/* Keeps p (size usable bytes) in the middle tier, the oldest given back first when full. */
static void mid_put(void *p, size_t size)
{
    void *drop[MID_SLOTS];
    int n = 0;
    pthread_mutex_lock(&pool_lock);
    for (;;) {
        int empty = -1, oldest = -1;
        for (int i = 0; i < MID_SLOTS; i++) {
            if (!mid[i].p) empty = empty < 0 ? i : empty;
            else if (oldest < 0 || mid[i].age < mid[oldest].age) oldest = i;
        }
        if (empty >= 0 && mid_total + size <= MID_BYTES) {
            mid[empty].p = p;
            mid[empty].size = size;
            mid[empty].age = ++pool_clock;
            mid_total += size;
            break;
        }
        drop[n++] = mid[oldest].p; /* size < MID_BYTES: the tier is not empty here */
        mid_total -= mid[oldest].size;
        mid[oldest].p = NULL;
    }
    pthread_mutex_unlock(&pool_lock);
    for (int i = 0; i < n; i++) free(drop[i]);
}

void *wvol__reuse_get(size_t bytes)
{
    void *p = NULL;
    size_t need = wvol__pages_bytes(bytes);
    int i, best = -1;
    if (bytes < MID_MIN) return malloc(bytes ? bytes : 1); /* malloc's free lists reuse these */
    if (bytes < PAGED) return mid_get(bytes);
    pthread_mutex_lock(&pool_lock);
    for (i = 0; i < POOL_SLOTS; i++)
        if (pool[i].p && pool[i].cls >= need && pool[i].cls / 2 <= need &&
            (best < 0 || pool[i].cls < pool[best].cls))
            best = i;
    if (best >= 0) {
        p = pool[best].p;
        pool_total -= pool[best].bytes;
        pool[best].p = NULL;
    }
    pthread_mutex_unlock(&pool_lock);
    return p ? p : wvol__malloc_large(bytes);
}

void wvol__reuse_put(void *p)
{
    wvol__reuse_put_used(p, SIZE_MAX);
}

void wvol__reuse_put_used(void *p, size_t used)
{
    void *drop[POOL_SLOTS];
    size_t bytes, cls;
    int i, n = 0;
    if (!p) return;
    bytes = malloc_usable_size(p); /* the block's true size, also after a realloc */
    cls = bytes & ~(size_t)(HUGE_PAGE - 1);
    if (cls < HUGE_PAGE) {
        if (bytes >= MID_MIN) mid_put(p, bytes);
        else free(p);
        return;
    }
    if (used < bytes) bytes = used;
    if (bytes > POOL_BYTES) {
        free(p);
        return;
    }
    pthread_mutex_lock(&pool_lock);
    for (;;) { /* the oldest given back until a slot is free and the bytes fit */
        int empty = -1, oldest = -1;
        for (i = 0; i < POOL_SLOTS; i++) {
            if (!pool[i].p) empty = empty < 0 ? i : empty;
            else if (oldest < 0 || pool[i].age < pool[oldest].age) oldest = i;
        }
        if (empty >= 0 && pool_total + bytes <= POOL_BYTES) {
            pool[empty].p = p;
            pool[empty].bytes = bytes;
            pool[empty].cls = cls;
            pool[empty].age = ++pool_clock;
            pool_total += bytes;
            break;
        }
        drop[n++] = pool[oldest].p; /* nothing fits and the pool is not empty: oldest >= 0 */
        pool_total -= pool[oldest].bytes;
        pool[oldest].p = NULL;
    }
    pthread_mutex_unlock(&pool_lock);
    for (i = 0; i < n; i++) free(drop[i]); /* outside the lock: a large free unmaps */
}

void wvol__reuse_held(size_t *buffers, size_t *bytes)
{
    size_t n = 0;
    int i;
    pthread_mutex_lock(&pool_lock);
    for (i = 0; i < POOL_SLOTS; i++) n += pool[i].p != NULL;
    *buffers = n;
    *bytes = pool_total;
    pthread_mutex_unlock(&pool_lock);
}

void wvol__reuse_held_mid(size_t *buffers, size_t *bytes)
{
    size_t n = 0;
    pthread_mutex_lock(&pool_lock);
    for (int i = 0; i < MID_SLOTS; i++) n += mid[i].p != NULL;
    *buffers = n;
    *bytes = mid_total;
    pthread_mutex_unlock(&pool_lock);
}
