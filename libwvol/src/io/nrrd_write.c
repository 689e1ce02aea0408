/* SPDX-License-Identifier: MIT
 * NRRD writer: float32 samples, raw or gzip, attached (.nrrd) or detached (.nhdr and
 * its data file), every file written atomically.
 * Based on: the NRRD file format, teem.sourceforge.net/nrrd/format.html (NRRD0004). */
#define _POSIX_C_SOURCE 200809L
#include "core/finite.h"
#include "core/status_internal.h"
#include "io/io_internal.h"
#include "wvol/io.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "wvol/version.h"

/* ---- writing ---------------------------------------------------------------- */

int wvol_nrrd_data_path(char *buf, size_t cap, const char *nhdr_path, int gzip)
{
    size_t n;
    const char *ext = gzip ? ".raw.gz" : ".raw";
    if (!buf || !nhdr_path) return 0;
    n = strlen(nhdr_path);
    if (wvol_path_has_ext(nhdr_path, ".nhdr")) n -= 5;
    if (n + strlen(ext) + 1 > cap) return 0;
    memcpy(buf, nhdr_path, n);
    strcpy(buf + n, ext);
    return 1;
}

static int host_big_endian(void)
{
    const uint16_t one = 1;
    return *(const unsigned char *)&one == 0;
}

static int write_header(FILE *fp, const size_t dims[3], const double spacing[3], const double origin[3], int gzip,
                        const char *data_file)
{
    int r = 0;
    r |= fprintf(fp, "NRRD0004\n# Complete NRRD file format specification at:\n"
                     "# http://teem.sourceforge.net/nrrd/format.html\n"
                     "# written by libwvol %s\n", WVOL_VERSION_STRING) < 0;
    r |= fprintf(fp, "type: float\ndimension: 3\nspace: left-posterior-superior\n") < 0;
    r |= fprintf(fp, "sizes: %zu %zu %zu\n", dims[0], dims[1], dims[2]) < 0;
    r |= fprintf(fp, "space directions: (%.17g,0,0) (0,%.17g,0) (0,0,%.17g)\n", spacing[0], spacing[1],
                 spacing[2]) < 0;
    r |= fprintf(fp, "kinds: domain domain domain\nendian: %s\nencoding: %s\n",
                 host_big_endian() ? "big" : "little", gzip ? "gzip" : "raw") < 0;
    r |= fprintf(fp, "space origin: (%.17g,%.17g,%.17g)\n", origin[0], origin[1], origin[2]) < 0;
    if (data_file) r |= fprintf(fp, "data file: %s\n", data_file) < 0;
    else r |= fputc('\n', fp) == EOF;
    return r ? -1 : 0;
}

/* ---- slab writer: raw, and NRRD attached or detached, raw or gzip ------------------- */

struct wvol_slab_writer {
    wvol_atomic_file data, header; /* header.fp is NULL unless a detached .nhdr */
    char path[4096];
    size_t dims[3], written;       /* slices written */
    int gzip;
    z_stream z;
    unsigned char *obuf;
};
enum { OBUF_BYTES = 1 << 18 };

void wvol_slab_writer_abort(wvol_slab_writer *w)
{
    if (!w) return;
    if (w->data.fp) wvol_atomic_abort(&w->data);
    if (w->header.fp) wvol_atomic_abort(&w->header);
    if (w->gzip) deflateEnd(&w->z);
    free(w->obuf);
    free(w);
}

/* nrrd: 0 raw samples only, 1 NRRD (a detached header when the path ends in .nhdr). */
static wvol_status open_writer(wvol_slab_writer **out, const char *path, int nrrd, const size_t dims[3],
                               const double spacing[3], const double origin[3], int gzip_level, wvol_error *err)
{
    static const double one[3] = {1, 1, 1}, zero[3] = {0, 0, 0};
    wvol_slab_writer *w;
    wvol_status s;
    size_t bytes;
    int nhdr = nrrd && wvol_path_has_ext(path, ".nhdr");
    WVOL_RETURN_IF(gzip_level < 0 || gzip_level > 9 || (gzip_level && !nrrd), err, WVOL_ERR_ARG,
                   "%s: gzip level %d (0 = raw .. 9; gzip only for NRRD)", path, gzip_level);
    WVOL_RETURN_IF(!dims[0] || !dims[1] || !dims[2] || !wvol_size_mul3(dims[0], dims[1], dims[2], 4, &bytes), err,
                   WVOL_ERR_DIMS, "%s: bad size %zu x %zu x %zu", path, dims[0], dims[1], dims[2]);
    if (!spacing) spacing = one;
    if (!origin) origin = zero;
    w = calloc(1, sizeof *w);
    WVOL_RETURN_IF(!w, err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    snprintf(w->path, sizeof w->path, "%s", path);
    memcpy(w->dims, dims, sizeof w->dims);
    if (gzip_level > 0) {
        w->obuf = malloc(OBUF_BYTES);
        if (!w->obuf || deflateInit2(&w->z, gzip_level, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
            free(w->obuf);
            free(w);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: cannot start zlib", path);
        }
        w->gzip = 1;
    }
    if (nhdr) {
        char dpath[4096];
        const char *base;
        if (!wvol_nrrd_data_path(dpath, sizeof dpath, path, gzip_level > 0)) {
            wvol_slab_writer_abort(w);
            return wvol_error_set(err, WVOL_ERR_ARG, "%s: path too long", path);
        }
        base = strrchr(dpath, '/');
        base = base ? base + 1 : dpath;
        /* the header first: an unwritable place is named by the file the caller gave */
        s = wvol_atomic_open(&w->header, path, err);
        if (!s) s = wvol_atomic_open(&w->data, dpath, err);
        if (!s && write_header(w->header.fp, dims, spacing, origin, gzip_level > 0, base) != 0)
            s = wvol__write_failed(path, err);
    } else {
        s = wvol_atomic_open(&w->data, path, err);
        if (!s && nrrd && write_header(w->data.fp, dims, spacing, origin, gzip_level > 0, NULL) != 0)
            s = wvol__write_failed(path, err);
    }
    if (s) {
        wvol_slab_writer_abort(w);
        return s;
    }
    *out = w;
    return WVOL_OK;
}

wvol_status wvol_slab_writer_open(wvol_slab_writer **out, const char *path, const size_t dims[3],
                                  const double spacing[3], const double origin[3], int gzip_level, wvol_error *err)
{
    int nrrd;
    WVOL_RETURN_IF(!out || !path || !dims, err, WVOL_ERR_ARG, "volume write: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol__geometry_check(spacing, origin, err));
    nrrd = wvol_path_has_ext(path, ".nhdr") || wvol_path_has_ext(path, ".nrrd");
    WVOL_RETURN_IF(!nrrd && !wvol_path_has_ext(path, ".raw"), err, WVOL_ERR_UNSUPPORTED,
                   "%s: slab by slab writes only .raw, .nrrd and .nhdr", path);
    return open_writer(out, path, nrrd, dims, spacing, origin, gzip_level, err);
}

/* Deflates n bytes (flush: Z_FINISH at the end) into the data file. */
static int deflate_out(wvol_slab_writer *w, const void *src, size_t n, int flush)
{
    const unsigned char *p = src;
    size_t done = 0;
    int zr;
    do {
        size_t k = n - done < ((size_t)1 << 30) ? n - done : ((size_t)1 << 30);
        int f = done + k == n ? flush : Z_NO_FLUSH;
        w->z.next_in = (Bytef *)(p + done);
        w->z.avail_in = (uInt)k;
        done += k;
        do {
            w->z.next_out = w->obuf;
            w->z.avail_out = OBUF_BYTES;
            zr = deflate(&w->z, f);
            if (zr == Z_STREAM_ERROR) return -1;
            if (fwrite(w->obuf, 1, OBUF_BYTES - w->z.avail_out, w->data.fp) != OBUF_BYTES - w->z.avail_out) return -1;
        } while (w->z.avail_out == 0 || (f == Z_FINISH && zr != Z_STREAM_END));
    } while (done < n);
    return 0;
}

wvol_status wvol_slab_writer_put(wvol_slab_writer *w, const float *slab, size_t nz, wvol_error *err)
{
    size_t n;
    WVOL_RETURN_IF(!w || !slab, err, WVOL_ERR_ARG, "volume write: NULL argument");
    WVOL_RETURN_IF(nz > w->dims[2] - w->written, err, WVOL_ERR_ARG, "%s: %zu slices past the %zu of the volume",
                   w->path, nz, w->dims[2]);
    n = w->dims[0] * w->dims[1] * nz;
    /* Samples are written in host order (the NRRD header says which); every supported host
     * is little-endian, which is what a raw file holds. */
    if (w->gzip ? deflate_out(w, slab, n * sizeof(float), Z_NO_FLUSH) != 0
                : fwrite(slab, sizeof(float), n, w->data.fp) != n)
        return wvol__write_failed(w->path, err);
    w->written += nz;
    return WVOL_OK;
}

wvol_status wvol_slab_writer_commit(wvol_slab_writer *w, unsigned long long *bytes, wvol_error *err)
{
    wvol_status s;
    long long data_bytes = 0, header_bytes = 0;
    WVOL_RETURN_IF(!w, err, WVOL_ERR_ARG, "volume write: NULL argument");
    if (w->written != w->dims[2]) {
        s = wvol_error_set(err, WVOL_ERR_ARG, "%s: %zu of %zu slices written", w->path, w->written, w->dims[2]);
        wvol_slab_writer_abort(w);
        return s;
    }
    if (w->gzip && deflate_out(w, "", 0, Z_FINISH) != 0) {
        s = wvol__write_failed(w->path, err);
        wvol_slab_writer_abort(w);
        return s;
    }
    /* both files' bytes out before either replaces an older one: a full disk shows here, and
     * a detached header's old data file is not replaced by data whose header then fails */
    if (fflush(w->data.fp) != 0 || ferror(w->data.fp)) {
        s = wvol__write_failed(w->data.final_path, err);
        wvol_slab_writer_abort(w);
        return s;
    }
    if (w->header.fp && (fflush(w->header.fp) != 0 || ferror(w->header.fp))) {
        s = wvol__write_failed(w->path, err);
        wvol_slab_writer_abort(w);
        return s;
    }
    data_bytes = ftell(w->data.fp);
    if (w->header.fp) header_bytes = ftell(w->header.fp);
    s = wvol_atomic_commit(&w->data, err);
    w->data.fp = NULL;
    if (!s && w->header.fp) {
        char dpath[4096];
        s = wvol_atomic_commit(&w->header, err);
        w->header.fp = NULL;
        /* no data file without its header */
        if (s && wvol_nrrd_data_path(dpath, sizeof dpath, w->path, w->gzip)) remove(dpath);
    }
    if (bytes) *bytes = (unsigned long long)(data_bytes + header_bytes);
    wvol_slab_writer_abort(w); /* frees what is left (nothing open) */
    return s;
}

wvol_status wvol_nrrd_write_gzip(const wvol_volume *v, const char *path, int gzip_level, wvol_error *err)
{
    wvol_slab_writer *w;
    size_t dims[3];
    wvol_status s;
    WVOL_RETURN_IF(!v || !v->data || !path, err, WVOL_ERR_ARG, "nrrd write: NULL argument");
    WVOL_RETURN_IF(gzip_level < 0 || gzip_level > 9, err, WVOL_ERR_ARG,
                   "%s: gzip level %d must be from 0 (raw) to 9", path, gzip_level);
    dims[0] = v->nx, dims[1] = v->ny, dims[2] = v->nz;
    WVOL_FORWARD(open_writer(&w, path, 1, dims, v->spacing, v->origin, gzip_level, err));
    s = wvol_slab_writer_put(w, v->data, v->nz, err);
    if (s) {
        wvol_slab_writer_abort(w);
        return s;
    }
    return wvol_slab_writer_commit(w, NULL, err);
}

wvol_status wvol_nrrd_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    return wvol_nrrd_write_gzip(v, path, 0, err);
}
