/* SPDX-License-Identifier: MIT */
/* Headerless raw volumes: dimensions and sample type come from the caller. */
#define _POSIX_C_SOURCE 200809L
#include "core/status_internal.h"
#include "io/io_internal.h"
#include "wvol/io.h"
#include "wvol/source.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

void wvol_load_options_default(wvol_load_options *opt)
{
    if (!opt) return;
    memset(opt, 0, sizeof *opt);
    opt->raw_type = WVOL_SAMPLE_TYPE_F32;
    opt->spacing[0] = opt->spacing[1] = opt->spacing[2] = 1.0;
}

/* The whole volume through the raw file source (io/source_file.c): one reader of raw data
 * (its checks of the dimensions and the file's length, float32 in the host's byte order read
 * straight into the volume, the finiteness check), for slabs and for whole volumes alike. */
wvol_status wvol_raw_read(wvol_volume **out, const char *path, const wvol_load_options *opt,
                          wvol_error *err)
{
    wvol_source *src = NULL;
    wvol_status s;
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "raw read: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol__source_open_raw(&src, path, opt, err));
    s = wvol_source_read_volume(src, out, err);
    wvol_source_destroy(src);
    return s;
}

wvol_status wvol_raw_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    wvol_atomic_file f;
    size_t n;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "raw write: volume is NULL");
    WVOL_FORWARD(wvol_atomic_open(&f, path, err));
    n = wvol_volume_count(v);
    /* Samples are written in host order; every supported host is little-endian. */
    if (fwrite(v->data, sizeof(float), n, f.fp) != n) return wvol_atomic_fail(&f, err);
    return wvol_atomic_commit(&f, err);
}
