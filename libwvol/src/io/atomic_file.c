/* SPDX-License-Identifier: MIT */
#define _XOPEN_SOURCE 700 /* realpath, lstat, clock_gettime */
#include "core/file_open.h"
#include "core/status_internal.h"
#include "io/io_internal.h"
#include "wvol/io.h"

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

int wvol_path_has_ext(const char *path, const char *ext)
{
    size_t n, e;
    if (!path || !ext) return 0;
    n = strlen(path);
    e = strlen(ext);
    return n >= e && strcasecmp(path + n - e, ext) == 0;
}

wvol_status wvol__output_path(char **final, const char *path, wvol_error *err)
{
    struct stat st;
    *final = NULL;
    WVOL_RETURN_IF(!path || !*path, err, WVOL_ERR_ARG, "output path is empty");
    if (lstat(path, &st) == 0 && S_ISLNK(st.st_mode)) {
        char *r = realpath(path, NULL);
        WVOL_RETURN_IF(!r, err, WVOL_ERR_IO, "%s: a symbolic link to no file (%s): not written", path, strerror(errno));
        if (stat(r, &st) != 0 || !S_ISREG(st.st_mode)) {
            free(r);
            return wvol_error_set(err, WVOL_ERR_IO, "%s: links to something that is not a regular file: not written",
                                  path);
        }
        *final = r;
        return WVOL_OK;
    }
    /* a missing path is what an output usually is; another error shows when it is created */
    WVOL_RETURN_IF(stat(path, &st) == 0 && !S_ISREG(st.st_mode), err, WVOL_ERR_IO,
                   "%s: exists and is not a regular file (a folder, device or FIFO): not written", path);
    *final = strdup(path);
    WVOL_RETURN_IF(!*final, err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    return WVOL_OK;
}

/* The temporaries open now, for wvol_atomic_remove_pending, which may run in a signal handler:
 * fixed slots (no allocation), each claimed by an atomic exchange, its name copied in, then
 * marked live. A temporary that finds no free slot, or whose name does not fit, is not removed
 * by it (its writer still removes it on an error). */
enum { TEMP_FREE, TEMP_FILLING, TEMP_LIVE, TEMP_SLOTS = 64 };
static struct {
    int state;
    char path[4096];
} temps[TEMP_SLOTS];

static void temp_track(const char *path)
{
    const size_t n = strlen(path);
    if (n >= sizeof temps[0].path) return;
    for (int i = 0; i < TEMP_SLOTS; i++) {
        int expected = TEMP_FREE;
        if (__atomic_compare_exchange_n(&temps[i].state, &expected, TEMP_FILLING, 0, __ATOMIC_ACQUIRE,
                                        __ATOMIC_RELAXED)) {
            memcpy(temps[i].path, path, n + 1);
            __atomic_store_n(&temps[i].state, TEMP_LIVE, __ATOMIC_RELEASE);
            return;
        }
    }
}

void wvol__temp_done(const char *path)
{
    if (!path) return;
    /* only the owner marks its slot free: temporaries' names are unique, so no other live slot
     * can hold this name */
    for (int i = 0; i < TEMP_SLOTS; i++)
        if (__atomic_load_n(&temps[i].state, __ATOMIC_ACQUIRE) == TEMP_LIVE && !strcmp(temps[i].path, path)) {
            __atomic_store_n(&temps[i].state, TEMP_FREE, __ATOMIC_RELEASE);
            return;
        }
}

void wvol_atomic_remove_pending(void)
{
    for (int i = 0; i < TEMP_SLOTS; i++)
        if (__atomic_load_n(&temps[i].state, __ATOMIC_ACQUIRE) == TEMP_LIVE) (void)unlink(temps[i].path);
}

/* splitmix64's finaliser: spreads a counter and a clock over a name's characters */
static uint64_t mix64(uint64_t x)
{
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

int wvol__create_temp(char *tmpl, size_t suffix_len)
{
    static const char set[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
    static uint64_t counter;
    const size_t n = tmpl ? strlen(tmpl) : 0;
    char *x;
    if (n < 6 + suffix_len || memcmp(tmpl + n - suffix_len - 6, "XXXXXX", 6) != 0) {
        errno = EINVAL;
        return -1;
    }
    x = tmpl + n - suffix_len - 6;
    for (int attempt = 0; attempt < 1000; attempt++) {
        struct timespec ts;
        uint64_t r;
        int fd;
        clock_gettime(CLOCK_REALTIME, &ts);
        /* the name need only be unlikely to exist: O_EXCL makes taking it safe */
        r = mix64(__atomic_add_fetch(&counter, 1, __ATOMIC_RELAXED) ^ ((uint64_t)getpid() << 40) ^
                  ((uint64_t)ts.tv_sec << 20) ^ (uint64_t)ts.tv_nsec);
        for (int i = 0; i < 6; i++, r /= sizeof set - 1) x[i] = set[r % (sizeof set - 1)];
        fd = open(tmpl, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) temp_track(tmpl);
        if (fd >= 0 || errno != EEXIST) return fd;
    }
    errno = EEXIST;
    return -1;
}

wvol_status wvol_atomic_open(wvol_atomic_file *f, const char *path, wvol_error *err)
{
    int fd;
    WVOL_RETURN_IF(!f, err, WVOL_ERR_ARG, "atomic file: handle is NULL");
    memset(f, 0, sizeof *f);
    WVOL_FORWARD(wvol__output_path(&f->final_path, path, err));
    path = f->final_path;
    f->tmp_path = wvol__temp_template(path, ".tmp-", "");
    if (!f->tmp_path) {
        wvol_status st = wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
        wvol_atomic_abort(f); /* frees path's string: the message is made first */
        return st;
    }
    fd = wvol__create_temp(f->tmp_path, 0);
    if (fd < 0) {
        int e = errno;
        wvol_status st = wvol_error_set(err, WVOL_ERR_IO, "%s: cannot create output file: %s", path, strerror(e));
        free(f->tmp_path);
        f->tmp_path = NULL;
        wvol_atomic_abort(f);
        return st;
    }
    f->fp = fdopen(fd, "wb");
    if (!f->fp) {
        wvol_status st = wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open output stream", path);
        close(fd);
        wvol_atomic_abort(f);
        return st;
    }
    return WVOL_OK;
}

wvol_status wvol_atomic_commit(wvol_atomic_file *f, wvol_error *err)
{
    int bad = 0, e = 0;
    WVOL_RETURN_IF(!f, err, WVOL_ERR_ARG, "atomic file: handle is NULL");
    if (!f->fp) return wvol_error_set(err, WVOL_ERR_ARG, "atomic file is not open");
    if (fflush(f->fp) != 0 || ferror(f->fp)) { bad = 1; e = errno; }
    if (fclose(f->fp) != 0 && !bad) { bad = 1; e = errno; }
    f->fp = NULL;
    if (!bad && rename(f->tmp_path, f->final_path) != 0) { bad = 1; e = errno; }
    if (!bad) wvol__temp_done(f->tmp_path);
    if (bad) {
        errno = e; /* the first failure's cause */
        return wvol_atomic_fail(f, err);
    }
    free(f->tmp_path);
    free(f->final_path);
    f->tmp_path = f->final_path = NULL;
    return WVOL_OK;
}

wvol_status wvol__write_failed(const char *path, wvol_error *err)
{
    const int e = errno;
    return wvol_error_set(err, WVOL_ERR_IO, "%s: write failed: %s", path ? path : "", e ? strerror(e) : "stream error");
}

wvol_status wvol_atomic_fail(wvol_atomic_file *f, wvol_error *err)
{
    wvol_status s = wvol__write_failed(f ? f->final_path : NULL, err); /* before the abort's own calls */
    wvol_atomic_abort(f);
    return s;
}

void wvol_atomic_abort(wvol_atomic_file *f)
{
    if (!f) return;
    if (f->fp) fclose(f->fp);
    f->fp = NULL;
    if (f->tmp_path) {
        remove(f->tmp_path);
        wvol__temp_done(f->tmp_path);
    }
    free(f->tmp_path);
    free(f->final_path);
    f->tmp_path = f->final_path = NULL;
}
