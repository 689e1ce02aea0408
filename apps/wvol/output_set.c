/* SPDX-License-Identifier: MIT */
/* The outputs of one command, kept or undone together (output_set.h). A signal handler undoes
 * the set too (output_set_undo_on_signal), so entries are never moved or freed while the command
 * runs: they live in blocks allocated once, published by the count after they are complete. */
#define _XOPEN_SOURCE 700 /* realpath, lstat */
#include "output_set.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

typedef struct output_entry {
    char *path;   /* the file a writer replaces: a symbolic link's target, as the writers resolve it */
    char *kept;   /* hard link to the earlier file, NULL if none was there or none could be made */
    int existed;  /* a regular file was at path */
    dev_t dev;    /* and which: a file still the same was not written */
    ino_t ino;
} output_entry;

enum { BLOCK = 64, MAX_BLOCKS = 256, MAX_DIRS = 64 };
static output_entry *blocks[MAX_BLOCKS];
static volatile sig_atomic_t count; /* entries complete */
static char *dirs[MAX_DIRS];        /* in the order made: parents first */
static volatile sig_atomic_t ndirs;

static output_entry *entry(int i)
{
    return &blocks[i / BLOCK][i % BLOCK];
}

/* A hard link to path under a new name beside it, "PATH.old-XXXXXX" (the file's own name
 * shortened, at a character's start, where the whole would pass 255 bytes, as the library's
 * temporaries are); NULL when none can be made. */
static char *keep_link(const char *path)
{
    static const char set[] = "abcdefghijklmnopqrstuvwxyz0123456789";
    const char *slash = strrchr(path, '/'), *base = slash ? slash + 1 : path;
    size_t keep = strlen(base), n;
    char *name;
    unsigned long r = (unsigned long)getpid() * 2654435761u ^ (unsigned long)time(NULL);
    if (keep > 255 - 11) {
        keep = 255 - 11;
        while (keep > 0 && ((unsigned char)base[keep] & 0xC0) == 0x80) keep--;
    }
    n = (size_t)(base - path) + keep;
    if (!(name = malloc(n + 12))) return NULL;
    memcpy(name, path, n);
    memcpy(name + n, ".old-", 5);
    for (int attempt = 0; attempt < 100; attempt++) {
        r = r * 6364136223846793005ul + 1442695040888963407ul;
        for (int i = 0; i < 6; i++) name[n + 5 + i] = set[(r >> (8 * i + 16)) % (sizeof set - 1)];
        name[n + 11] = '\0';
        if (link(path, name) == 0) return name;
        if (errno != EEXIST) break;
    }
    free(name);
    return NULL;
}

wvol_status output_set_add(const char *path, wvol_error *err)
{
    struct stat st;
    output_entry e;
    const int n = count;
    if (!path || !*path) return WVOL_OK;
    memset(&e, 0, sizeof e);
    if (lstat(path, &st) == 0 && S_ISLNK(st.st_mode)) {
        if (!(e.path = realpath(path, NULL))) return WVOL_OK; /* a link to nothing: the writers refuse it */
    } else if (!(e.path = strdup(path))) {
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    for (int i = 0; i < n; i++)
        if (!strcmp(entry(i)->path, e.path)) {
            free(e.path);
            return WVOL_OK;
        }
    if (n == BLOCK * MAX_BLOCKS || (!blocks[n / BLOCK] && !(blocks[n / BLOCK] = calloc(BLOCK, sizeof e)))) {
        free(e.path);
        return wvol_error_set(err, n == BLOCK * MAX_BLOCKS ? WVOL_ERR_ARG : WVOL_ERR_NOMEM,
                              "%s: %s", path, n == BLOCK * MAX_BLOCKS ? "too many output files" : "out of memory");
    }
    if (stat(e.path, &st) == 0) {
        if (!S_ISREG(st.st_mode)) { /* a folder or device: the writers refuse it, nothing to undo */
            free(e.path);
            return WVOL_OK;
        }
        e.existed = 1, e.dev = st.st_dev, e.ino = st.st_ino;
        e.kept = keep_link(e.path);
    }
    *entry(n) = e;
    __atomic_signal_fence(__ATOMIC_SEQ_CST); /* the entry complete before a handler can see it */
    count = n + 1;
    return WVOL_OK;
}

wvol_status output_set_add_dir(const char *path, wvol_error *err)
{
    char *p;
    if (ndirs == MAX_DIRS) return WVOL_OK; /* deeper still: those stay after a failure */
    if (!(p = strdup(path))) return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    dirs[ndirs] = p;
    __atomic_signal_fence(__ATOMIC_SEQ_CST);
    ndirs = ndirs + 1;
    return WVOL_OK;
}

/* Every path as it was, the folders made removed; async-signal-safe (stat, rename, unlink,
 * rmdir), touching no allocation. */
static void undo_all(void)
{
    for (int i = count - 1; i >= 0; i--) {
        const output_entry *e = entry(i);
        struct stat st;
        const int now = stat(e->path, &st) == 0;
        const int same = now && e->existed && st.st_dev == e->dev && st.st_ino == e->ino;
        if (same) {
            if (e->kept) (void)unlink(e->kept); /* never replaced */
        } else if (e->kept) {
            (void)rename(e->kept, e->path); /* if that fails, the earlier file stays under the kept name */
        } else if (now) {
            (void)unlink(e->path);
        }
    }
    for (int i = ndirs - 1; i >= 0; i--) (void)rmdir(dirs[i]); /* only if empty: what others put there stays */
}

static void release(void)
{
    const int n = count, nd = ndirs;
    count = 0, ndirs = 0;
    for (int i = 0; i < n; i++) {
        free(entry(i)->kept);
        free(entry(i)->path);
    }
    for (int b = 0; b < MAX_BLOCKS && blocks[b]; b++) {
        free(blocks[b]);
        blocks[b] = NULL;
    }
    for (int i = 0; i < nd; i++) free(dirs[i]);
}

void output_set_undo(void)
{
    undo_all();
    release();
}

void output_set_undo_on_signal(void)
{
    undo_all();
}

void output_set_done(void)
{
    for (int i = count - 1; i >= 0; i--)
        if (entry(i)->kept) (void)unlink(entry(i)->kept);
    release();
}
