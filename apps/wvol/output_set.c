/* SPDX-License-Identifier: MIT */
/* The outputs of one command, kept or undone together (output_set.h). */
#define _XOPEN_SOURCE 700 /* realpath, lstat */
#include "output_set.h"

#include <errno.h>
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

static output_entry *entries;
static int count, cap;
static char **dirs; /* in the order made: parents first */
static int ndirs, capdirs;

/* A hard link to path under a new name beside it; NULL when none can be made. */
static char *keep_link(const char *path)
{
    static const char set[] = "abcdefghijklmnopqrstuvwxyz0123456789";
    const size_t n = strlen(path);
    char *name = malloc(n + 12);
    unsigned long r = (unsigned long)getpid() * 2654435761u ^ (unsigned long)time(NULL);
    if (!name) return NULL;
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
    if (!path || !*path) return WVOL_OK;
    memset(&e, 0, sizeof e);
    if (lstat(path, &st) == 0 && S_ISLNK(st.st_mode)) {
        if (!(e.path = realpath(path, NULL))) return WVOL_OK; /* a link to nothing: the writers refuse it */
    } else if (!(e.path = strdup(path))) {
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    for (int i = 0; i < count; i++)
        if (!strcmp(entries[i].path, e.path)) {
            free(e.path);
            return WVOL_OK;
        }
    if (count == cap) {
        int nc = cap ? 2 * cap : 8;
        output_entry *q = realloc(entries, (size_t)nc * sizeof *q);
        if (!q) {
            free(e.path);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
        }
        entries = q, cap = nc;
    }
    if (stat(e.path, &st) == 0) {
        if (!S_ISREG(st.st_mode)) { /* a folder or device: the writers refuse it, nothing to undo */
            free(e.path);
            return WVOL_OK;
        }
        e.existed = 1, e.dev = st.st_dev, e.ino = st.st_ino;
        e.kept = keep_link(e.path);
    }
    entries[count++] = e;
    return WVOL_OK;
}

wvol_status output_set_add_dir(const char *path, wvol_error *err)
{
    char *p = strdup(path);
    if (p && ndirs == capdirs) {
        int nc = capdirs ? 2 * capdirs : 4;
        char **q = realloc(dirs, (size_t)nc * sizeof *q);
        if (!q) {
            free(p);
            p = NULL;
        } else {
            dirs = q, capdirs = nc;
        }
    }
    if (!p) return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    dirs[ndirs++] = p;
    return WVOL_OK;
}

static void drop_dirs(int remove_them)
{
    while (ndirs > 0) {
        char *d = dirs[--ndirs];
        if (remove_them) (void)rmdir(d); /* only if empty: what someone else put there stays */
        free(d);
    }
    free(dirs);
    dirs = NULL, capdirs = 0;
}

void output_set_undo(void)
{
    while (count > 0) {
        output_entry *e = &entries[--count];
        struct stat st;
        const int now = stat(e->path, &st) == 0;
        const int same = now && e->existed && st.st_dev == e->dev && st.st_ino == e->ino;
        if (same) {
            if (e->kept) remove(e->kept); /* never replaced */
        } else if (e->kept) {
            (void)rename(e->kept, e->path); /* if that fails, the earlier file stays under the kept name */
        } else if (now) {
            remove(e->path);
        }
        free(e->kept);
        free(e->path);
    }
    free(entries);
    entries = NULL, cap = 0;
    drop_dirs(1);
}

void output_set_done(void)
{
    while (count > 0) {
        output_entry *e = &entries[--count];
        if (e->kept) remove(e->kept);
        free(e->kept);
        free(e->path);
    }
    free(entries);
    entries = NULL, cap = 0;
    drop_dirs(0);
}
