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

/* A tier of kept blocks: each serves requests of at least half its class (`cls`), the best fit
 * first; `bytes` is what it counts against the tier's bound. Kept blocks past the slots or the
 * bound go, the oldest first. Under pool_lock. */
typedef struct kept_block {
    void *p;
    size_t bytes, cls;
    unsigned long age;
} kept_block;

typedef struct tier {
    kept_block *slot;
    int n;
    size_t total, max;
} tier;

static pthread_mutex_t pool_lock = PTHREAD_MUTEX_INITIALIZER;
static unsigned long pool_clock;

/* The large buffers: 8 slots, 128 MiB of their touched bytes; a block's class is its size in
 * whole huge pages, rounded down (an aligned block's usable size runs to the end of its mapping,
 * up to a huge page more). */
enum { POOL_SLOTS = 8 };
static kept_block big_slot[POOL_SLOTS];
static tier big = {big_slot, POOL_SLOTS, 0, (size_t)128 << 20};

/* The middle tier: blocks from MID_MIN to a huge page (class: their usable size). malloc's heap
 * grows and shrinks with them at its top: a writer's few chunk payloads of some hundred KiB each,
 * made and freed in turn, were trimmed from the heap and faulted in again, 4 KiB at a time,
 * every few chunks. Requests are rounded up to MID_MIN so that the next one, a little larger,
 * finds the block given back. */
enum { MID_SLOTS = 16, MID_MIN = 64u << 10 };
static kept_block mid_slot[MID_SLOTS];
static tier mid = {mid_slot, MID_SLOTS, 0, (size_t)16 << 20};

/* The kept block that serves need (NULL: none), taken out of the tier. */
static void *tier_take(tier *t, size_t need)
{
    void *p = NULL;
    int best = -1;
    pthread_mutex_lock(&pool_lock);
    for (int i = 0; i < t->n; i++)
        if (t->slot[i].p && t->slot[i].cls >= need && t->slot[i].cls / 2 <= need &&
            (best < 0 || t->slot[i].cls < t->slot[best].cls))
            best = i;
    if (best >= 0) {
        p = t->slot[best].p;
        t->total -= t->slot[best].bytes;
        t->slot[best].p = NULL;
    }
    pthread_mutex_unlock(&pool_lock);
    return p;
}

/* Keeps p (class cls, counting bytes <= t->max) in the tier, the oldest given back until a slot
 * is free and the bytes fit. */
static void tier_keep(tier *t, void *p, size_t cls, size_t bytes)
{
    void *drop[(int)MID_SLOTS + (int)POOL_SLOTS]; /* at most a tier's slots */
    int n = 0;
    pthread_mutex_lock(&pool_lock);
    for (;;) {
        int empty = -1, oldest = -1;
        for (int i = 0; i < t->n; i++) {
            if (!t->slot[i].p) empty = empty < 0 ? i : empty;
            else if (oldest < 0 || t->slot[i].age < t->slot[oldest].age) oldest = i;
        }
        if (empty >= 0 && t->total + bytes <= t->max) {
            t->slot[empty].p = p;
            t->slot[empty].bytes = bytes;
            t->slot[empty].cls = cls;
            t->slot[empty].age = ++pool_clock;
            t->total += bytes;
            break;
        }
        drop[n++] = t->slot[oldest].p; /* nothing fits and the tier is not empty: oldest >= 0 */
        t->total -= t->slot[oldest].bytes;
        t->slot[oldest].p = NULL;
    }
    pthread_mutex_unlock(&pool_lock);
    for (int i = 0; i < n; i++) free(drop[i]); /* outside the lock: a large free unmaps */
}

void *wvol__reuse_get(size_t bytes)
{
    void *p;
    if (bytes < MID_MIN) return malloc(bytes ? bytes : 1); /* malloc's free lists reuse these */
    if (bytes < PAGED) {
        p = tier_take(&mid, bytes);
        return p ? p : malloc((bytes + MID_MIN - 1) & ~(size_t)(MID_MIN - 1));
    }
    p = tier_take(&big, wvol__pages_bytes(bytes));
    return p ? p : wvol__malloc_large(bytes);
}

void wvol__reuse_put(void *p)
{
    wvol__reuse_put_used(p, SIZE_MAX);
}

void wvol__reuse_put_used(void *p, size_t used)
{
    size_t bytes, cls;
    if (!p) return;
    bytes = malloc_usable_size(p); /* the block's true size, also after a realloc */
    cls = bytes & ~(size_t)(HUGE_PAGE - 1);
    if (cls < HUGE_PAGE) {
        if (bytes >= MID_MIN) tier_keep(&mid, p, bytes, bytes);
        else free(p);
        return;
    }
    if (used < bytes) bytes = used;
    if (bytes > big.max) {
        free(p);
        return;
    }
    tier_keep(&big, p, cls, bytes);
}

static void tier_held(tier *t, size_t *buffers, size_t *bytes)
{
    size_t n = 0;
    pthread_mutex_lock(&pool_lock);
    for (int i = 0; i < t->n; i++) n += t->slot[i].p != NULL;
    *buffers = n;
    *bytes = t->total;
    pthread_mutex_unlock(&pool_lock);
}

void wvol__reuse_held(size_t *buffers, size_t *bytes) { tier_held(&big, buffers, bytes); }

void wvol__reuse_held_mid(size_t *buffers, size_t *bytes) { tier_held(&mid, buffers, bytes); }
