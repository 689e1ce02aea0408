/* SPDX-License-Identifier: MIT */
/* Headerless raw volumes: dimensions and sample type come from the caller. */
#define _POSIX_C_SOURCE 200809L
#include "core/alloc.h"
#include "core/status_internal.h"
#include "wvol/io.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

void wvol_load_options_default(wvol_load_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->raw_type = WVOL_SAMPLE_TYPE_F32;
    opt->spacing[0] = opt->spacing[1] = opt->spacing[2] = 1.0;
}

wvol_status wvol_raw_read(wvol_volume **out, const char *path, const wvol_load_options *opt,
                          wvol_error *err)
{
    size_t elem, bytes, chunk = (size_t)1 << 20, done = 0, n;
    struct stat st;
    FILE *fp;
    unsigned char *buf;
    wvol_volume *v;
    wvol_status s;
    int direct;

    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "raw read: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(!opt || !opt->dims[0] || !opt->dims[1] || !opt->dims[2], err, WVOL_ERR_ARG,
                   "%s: a raw file needs its dimensions (--dims NXxNYxNZ)", path);
    elem = wvol_sample_type_size(opt->raw_type);
    WVOL_RETURN_IF(!elem, err, WVOL_ERR_ARG, "%s: unknown raw sample type", path);
    WVOL_RETURN_IF(!wvol_size_mul3(opt->dims[0], opt->dims[1], opt->dims[2], elem, &bytes), err,
                   WVOL_ERR_DIMS, "%s: dimensions %zux%zux%zu overflow", path, opt->dims[0],
                   opt->dims[1], opt->dims[2]);
    WVOL_RETURN_IF(stat(path, &st) != 0, err, WVOL_ERR_IO, "%s: %s", path, strerror(errno));
    WVOL_RETURN_IF(!S_ISREG(st.st_mode), err, WVOL_ERR_IO, "%s: not a regular file", path);
    WVOL_RETURN_IF((unsigned long long)st.st_size != (unsigned long long)bytes, err, WVOL_ERR_FORMAT,
                   "%s: file has %lld bytes but %zux%zux%zu %s samples need %zu", path,
                   (long long)st.st_size, opt->dims[0], opt->dims[1], opt->dims[2],
                   wvol_sample_type_name(opt->raw_type), bytes);
    WVOL_FORWARD(wvol_volume_create(&v, opt->dims[0], opt->dims[1], opt->dims[2], err));
    s = wvol_volume_set_geometry(v, opt->spacing, opt->origin, err);
    if (s) { wvol_volume_destroy(v); return s; }
    fp = fopen(path, "rb");
    /* float32 is read straight into the volume (converted in place when its byte order is not
     * the host's); other types through a buffer in huge pages (core/alloc.h: in 4 KiB pages its
     * first touches cost more than the read) */
    direct = opt->raw_type == WVOL_SAMPLE_TYPE_F32;
    buf = direct ? NULL : wvol__malloc_large(chunk * elem);
    if (!fp || (!direct && !buf)) {
        s = wvol_error_set(err, fp ? WVOL_ERR_NOMEM : WVOL_ERR_IO, "%s: %s", path,
                           fp ? "out of memory" : strerror(errno));
        goto fail;
    }
    n = wvol_volume_count(v);
    while (done < n) {
        size_t want = n - done < chunk ? n - done : chunk;
        void *to = direct ? (void *)(v->data + done) : (void *)buf;
        if (fread(to, elem, want, fp) != want) {
            s = wvol_error_set(err, WVOL_ERR_IO, "%s: short read at sample %zu", path, done);
            goto fail;
        }
        wvol_samples_to_float(v->data + done, to, want, opt->raw_type, opt->big_endian);
        done += want;
    }
    fclose(fp);
    free(buf);
    s = wvol_check_finite(v->data, v->nx, v->ny, v->nz, path, err);
    if (s) { wvol_volume_destroy(v); return s; }
    *out = v;
    return WVOL_OK;
fail:
    if (fp) fclose(fp);
    free(buf);
    wvol_volume_destroy(v);
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
    if (fwrite(v->data, sizeof(float), n, f.fp) != n) {
        wvol_atomic_abort(&f);
        return wvol_error_set(err, WVOL_ERR_IO, "%s: write failed", path);
    }
    return wvol_atomic_commit(&f, err);
}
