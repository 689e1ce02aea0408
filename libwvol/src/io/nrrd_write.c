/* SPDX-License-Identifier: MIT
 * NRRD writer: float32 samples, raw or gzip, attached (.nrrd) or detached (.nhdr and
 * its data file), every file written atomically.
 * Based on: the NRRD file format, teem.sourceforge.net/nrrd/format.html (NRRD0004). */
#define _POSIX_C_SOURCE 200809L
#include "core/status_internal.h"
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

static int write_header(FILE *fp, const wvol_volume *v, int gzip, const char *data_file)
{
    int r = 0;
    r |= fprintf(fp, "NRRD0004\n# Complete NRRD file format specification at:\n"
                     "# http://teem.sourceforge.net/nrrd/format.html\n"
                     "# written by libwvol %s\n", WVOL_VERSION_STRING) < 0;
    r |= fprintf(fp, "type: float\ndimension: 3\nspace: left-posterior-superior\n") < 0;
    r |= fprintf(fp, "sizes: %zu %zu %zu\n", v->nx, v->ny, v->nz) < 0;
    r |= fprintf(fp, "space directions: (%.17g,0,0) (0,%.17g,0) (0,0,%.17g)\n", v->spacing[0], v->spacing[1],
                 v->spacing[2]) < 0;
    r |= fprintf(fp, "kinds: domain domain domain\nendian: %s\nencoding: %s\n",
                 host_big_endian() ? "big" : "little", gzip ? "gzip" : "raw") < 0;
    r |= fprintf(fp, "space origin: (%.17g,%.17g,%.17g)\n", v->origin[0], v->origin[1], v->origin[2]) < 0;
    if (data_file) r |= fprintf(fp, "data file: %s\n", data_file) < 0;
    else r |= fputc('\n', fp) == EOF;
    return r ? -1 : 0;
}

static int write_samples(FILE *fp, const wvol_volume *v, int gzip_level)
{
    size_t n = wvol_volume_count(v);
    z_stream z;
    unsigned char *obuf;
    const size_t obytes = 1 << 18, step = 1 << 18; /* floats per deflate call */
    size_t done = 0;
    int zr, bad = 0;
    if (gzip_level <= 0) return fwrite(v->data, sizeof(float), n, fp) == n ? 0 : -1;
    memset(&z, 0, sizeof z);
    if (deflateInit2(&z, gzip_level, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return -1;
    obuf = malloc(obytes);
    if (!obuf) {
        deflateEnd(&z);
        return -1;
    }
    do {
        size_t k = n - done < step ? n - done : step;
        int flush = done + k == n ? Z_FINISH : Z_NO_FLUSH;
        z.next_in = (Bytef *)(v->data + done);
        z.avail_in = (uInt)(k * sizeof(float));
        done += k;
        do {
            z.next_out = obuf;
            z.avail_out = (uInt)obytes;
            zr = deflate(&z, flush);
            if (zr == Z_STREAM_ERROR) bad = 1;
            if (fwrite(obuf, 1, obytes - z.avail_out, fp) != obytes - z.avail_out) bad = 1;
        } while (!bad && (z.avail_out == 0 || (flush == Z_FINISH && zr != Z_STREAM_END)));
    } while (!bad && done < n);
    deflateEnd(&z);
    free(obuf);
    return bad ? -1 : 0;
}

wvol_status wvol_nrrd_write_gzip(const wvol_volume *v, const char *path, int gzip_level, wvol_error *err)
{
    wvol_atomic_file f, df;
    wvol_status s;
    WVOL_RETURN_IF(!v || !v->data || !path, err, WVOL_ERR_ARG, "nrrd write: NULL argument");
    WVOL_RETURN_IF(gzip_level < 0 || gzip_level > 9, err, WVOL_ERR_ARG,
                   "%s: gzip level %d must be from 0 (raw) to 9", path, gzip_level);
    if (wvol_path_has_ext(path, ".nhdr")) {
        char dpath[4096];
        const char *base;
        WVOL_RETURN_IF(!wvol_nrrd_data_path(dpath, sizeof dpath, path, gzip_level > 0), err, WVOL_ERR_ARG,
                       "%s: path too long", path);
        base = strrchr(dpath, '/');
        base = base ? base + 1 : dpath;
        s = wvol_atomic_open(&df, dpath, err);
        if (!s && write_samples(df.fp, v, gzip_level) != 0) {
            wvol_atomic_abort(&df);
            s = wvol_error_set(err, WVOL_ERR_IO, "%s: write failed", dpath);
        } else if (!s) {
            s = wvol_atomic_commit(&df, err);
        }
        if (s) {
            wvol_error_prefix(err, "%s: data file", path);
            return s;
        }
        s = wvol_atomic_open(&f, path, err);
        if (!s && write_header(f.fp, v, gzip_level > 0, base) != 0) {
            wvol_atomic_abort(&f);
            s = wvol_error_set(err, WVOL_ERR_IO, "%s: write failed", path);
        } else if (!s) {
            s = wvol_atomic_commit(&f, err);
        }
        if (s) remove(dpath); /* no data file without its header */
        return s;
    }
    WVOL_FORWARD(wvol_atomic_open(&f, path, err));
    if (write_header(f.fp, v, gzip_level > 0, NULL) != 0 || write_samples(f.fp, v, gzip_level) != 0) {
        wvol_atomic_abort(&f);
        return wvol_error_set(err, WVOL_ERR_IO, "%s: write failed", path);
    }
    return wvol_atomic_commit(&f, err);
}

wvol_status wvol_nrrd_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    return wvol_nrrd_write_gzip(v, path, 0, err);
}
