/* SPDX-License-Identifier: MIT */
/* Volume output of the sub-commands (volume_out.h): every file written joins the command's
 * output set, which undoes them after a failure. */
#define _POSIX_C_SOURCE 200809L
#include "volume_out.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "output_set.h"
#include "wvol/io.h"

static unsigned long long size_of(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (unsigned long long)st.st_size : 0;
}

wvol_status volume_out_save(volume_out *f, const wvol_volume *v, const char *path, int gzip, wvol_error *err)
{
    wvol_status s;
    int nrrd = wvol_path_has_ext(path, ".nrrd") || wvol_path_has_ext(path, ".nhdr");
    memset(f, 0, sizeof *f);
    if (strlen(path) >= sizeof f->path - 8)
        return wvol_error_set(err, WVOL_ERR_ARG, "%s: path too long", path);
    strcpy(f->path, path);
    if (wvol_path_has_ext(path, ".nhdr")) wvol_nrrd_data_path(f->data_path, sizeof f->data_path, path, gzip);
    if ((s = volume_out_claim(path, gzip, err)) != WVOL_OK) return s;
    s = nrrd ? wvol_nrrd_write_gzip(v, path, gzip ? 6 : 0, err) : wvol_volume_save(v, path, err);
    if (s) return s;
    f->bytes = size_of(f->path) + (f->data_path[0] ? size_of(f->data_path) : 0);
    return WVOL_OK;
}

wvol_status volume_out_claim(const char *path, int gzip, wvol_error *err)
{
    char data[4096];
    wvol_status s = output_set_add(path, err);
    if (s || !wvol_path_has_ext(path, ".nhdr")) return s;
    if (!wvol_nrrd_data_path(data, sizeof data, path, gzip))
        return wvol_error_set(err, WVOL_ERR_ARG, "%s: path too long", path);
    return output_set_add(data, err);
}

void volume_out_json(const volume_out *f, const wvol_volume *v)
{
    cli_json_str("file", f->path);
    cli_json_open("files", '[');
    cli_json_str(NULL, f->path);
    if (f->data_path[0]) cli_json_str(NULL, f->data_path);
    cli_json_close(']');
    cli_json_int("bytes", (long long)f->bytes);
    volume_json_grid(v);
}

void volume_json_grid(const wvol_volume *v)
{
    cli_json_size3("dims", v->nx, v->ny, v->nz);
    cli_json_num3("spacing", v->spacing);
    cli_json_num3("origin", v->origin);
}

int parse_seed(const char *cmd, const char *s, uint64_t *out)
{
    char *end;
    unsigned long long v;
    if (!*s || *s == '-' || *s == '+' || *s == ' ') goto bad;
    errno = 0;
    v = strtoull(s, &end, 10);
    if (errno || *end) goto bad;
    *out = (uint64_t)v;
    return 1;
bad:
    cli_usage(cmd, "--seed '%s': expected an integer from 0 to 18446744073709551615", s);
    return 0;
}
