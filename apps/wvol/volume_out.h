/* SPDX-License-Identifier: MIT */
/* Writing a volume from a sub-command: remembers every file written (a detached
 * .nhdr header has a data file beside it) so a later failure can remove them all. */
#ifndef WVOL_APP_VOLUME_OUT_H
#define WVOL_APP_VOLUME_OUT_H

#include <stdint.h>

#include "wvol/volume.h"

typedef struct volume_out {
    char path[4096];
    char data_path[4096];      /* detached NRRD data file, "" if none */
    unsigned long long bytes;  /* of all the files together */
} volume_out;

/* Saves v to path (format by extension; gzip: NRRD gzip encoding). */
wvol_status volume_out_save(volume_out *f, const wvol_volume *v, const char *path, int gzip, wvol_error *err);
/* Removes what volume_out_save wrote. */
void volume_out_remove(const volume_out *f);
/* JSON fields "file", "files", "bytes", "dims", "spacing", "origin". */
void volume_out_json(const volume_out *f, const wvol_volume *v);
/* JSON fields "dims", "spacing", "origin" of v. */
void volume_json_grid(const wvol_volume *v);

/* "--seed S": an integer from 0 to 2^64 - 1; prints a usage error and returns 0 if not. */
int parse_seed(const char *cmd, const char *s, uint64_t *out);

#endif
