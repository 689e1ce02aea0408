/* SPDX-License-Identifier: MIT */
/* Writing a volume from a sub-command: every file written (a detached .nhdr header has a data
 * file beside it) joins the command's output set (output_set.h), so a later failure undoes them. */
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
/* Adds path (and a detached .nhdr header's data file, gzip naming it .raw.gz) to the command's
 * output set (output_set.h), before the volume is written there; volume_out_save does this
 * itself, the other writers' callers call it first. */
wvol_status volume_out_claim(const char *path, int gzip, wvol_error *err);
/* JSON fields "file", "files", "bytes", "dims", "spacing", "origin". */
void volume_out_json(const volume_out *f, const wvol_volume *v);
/* JSON fields "dims", "spacing", "origin" of v. */
void volume_json_grid(const wvol_volume *v);

/* "--seed S": an integer from 0 to 2^64 - 1; prints a usage error and returns 0 if not. */
int parse_seed(const char *cmd, const char *s, uint64_t *out);

#endif
