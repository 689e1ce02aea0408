/* SPDX-License-Identifier: MIT
 * What the fuzz targets that read files share: the input written to a named file in a scratch
 * folder of the process's own, made on first use and removed with its files at exit. Include
 * it before any system header (it asks for mkdtemp). */
#ifndef WVOL_FUZZ_FILE_H
#define WVOL_FUZZ_FILE_H

#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define FUZZ_FILES 4

static char fuzz_dir[64], fuzz_path[FUZZ_FILES][96];
static int fuzz_nfiles;

static void fuzz_cleanup(void)
{
    for (int i = 0; i < fuzz_nfiles; i++) unlink(fuzz_path[i]);
    rmdir(fuzz_dir);
}

/* Writes data to the scratch folder's file `name` (the same file for the same name: each
 * input replaces the last) and returns its path; aborts when it cannot, so that a failed
 * write is never taken for a reader's verdict. */
static const char *fuzz_write(const char *name, const uint8_t *data, size_t size)
{
    char path[96];
    FILE *f;
    int i, ok;
    if (!fuzz_dir[0]) {
        snprintf(fuzz_dir, sizeof fuzz_dir, "/tmp/wvol_fuzz_XXXXXX");
        if (!mkdtemp(fuzz_dir)) abort();
        atexit(fuzz_cleanup);
    }
    snprintf(path, sizeof path, "%s/%s", fuzz_dir, name);
    for (i = 0; i < fuzz_nfiles && strcmp(fuzz_path[i], path) != 0; i++) {}
    if (i == fuzz_nfiles) {
        if (fuzz_nfiles == FUZZ_FILES) abort();
        memcpy(fuzz_path[fuzz_nfiles++], path, sizeof path);
    }
    if (!(f = fopen(fuzz_path[i], "wb"))) abort();
    ok = fwrite(data, 1, size, f) == size;
    if (fclose(f) != 0 || !ok) abort();
    return fuzz_path[i];
}

#endif
