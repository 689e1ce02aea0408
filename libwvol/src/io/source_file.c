/* SPDX-License-Identifier: MIT */
/* File volume sources (wvol/source.h): raw files and NRRD raw data are read slab by slab
 * with a seek; NRRD gzip data through zlib's gzread/gzseek (a forward seek inflates and
 * discards, a backward one restarts the stream); every other format is loaded whole on
 * open. The checks are those of the whole-file readers (nrrd_read.c; raw.c reads through the
 * raw source itself): the data length against the sizes before anything is read, and for
 * gzip the end of the stream at the last slab (too long or truncated data are refused there). */
#define _FILE_OFFSET_BITS 64
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/file_open.h"
#include "core/source_volume.h"
#include "io/io_internal.h"
#include "io/nrrd_internal.h"
#include "wvol/source.h"

enum { CHUNK_BYTES = 1 << 20, SPLIT_BYTES = 4 << 20 };

typedef struct file_src {
    char *path;               /* the data file, for messages */
    FILE *fp;                 /* raw data */
    gzFile gz;                /* gzip data */
    unsigned long long start; /* raw: file offset of the first sample; gzip: bytes to skip after inflating */
    unsigned long long pos;   /* gzip: inflated bytes consumed so far */
    unsigned long long total; /* data bytes the sizes need */
    size_t slice_bytes, row_bytes;
    nrrd_header conv;         /* type, elem and byte order of the samples (only those fields) */
    int direct;               /* float32 in the host's byte order: read into the caller's slab */
    unsigned char *buf;
} file_src;

static void file_close(void *ctx)
{
    file_src *f = ctx;
    if (!f) return;
    if (f->fp) fclose(f->fp);
    if (f->gz) gzclose(f->gz);
    free(f->buf);
    free(f->path);
    free(f);
}

/* n bytes at file offset off into dst with pread (the stream's position untouched); 1 when
 * they come short (an error or the file's end). */
static int pread_full(int fd, unsigned char *dst, size_t n, unsigned long long off)
{
    size_t a = 0;
    while (a < n) {
        ssize_t r = pread(fd, dst + a, n - a, (off_t)(off + a));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return 1;
        a += (size_t)r;
    }
    return 0;
}

/* n bytes at file offset off into dst, split among the threads in contiguous parts, each
 * read with pread: reading a cached file is the kernel's copy out of the page cache, which
 * runs on the reading thread. 1 when a part comes short (an error or the file's end). */
static int read_split(int fd, unsigned char *dst, unsigned long long off, size_t n, int threads)
{
    const size_t part = ((n + (size_t)threads - 1) / (size_t)threads + 4095) & ~(size_t)4095;
    int failed = 0;
#pragma omp parallel for schedule(static, 1) num_threads(threads) reduction(| : failed)
    for (int t = 0; t < threads; t++) {
        size_t a = (size_t)t * part, b = a + part < n ? a + part : n;
        if (a < b) failed |= pread_full(fd, dst + a, b - a, off + a);
    }
    return failed;
}

static int read_threads(size_t n)
{
#ifdef _OPENMP
    if (n >= SPLIT_BYTES && !omp_in_parallel()) return omp_get_max_threads();
#endif
    (void)n;
    return 1;
}

/* n bytes of raw data from file offset at into dst: float32 in the host's byte order
 * straight in (split among the threads when large), other samples through f->buf and
 * converted, a chunk at a time. pread: no stream position to keep. */
static wvol_status raw_at(file_src *f, float *dst, unsigned long long at, size_t n, wvol_error *err)
{
    const size_t elem = f->conv.elem;
    const int threads = f->direct ? read_threads(n) : 1;
    if (threads > 1) {
        WVOL_RETURN_IF(read_split(fileno(f->fp), (unsigned char *)dst, at, n, threads), err, WVOL_ERR_IO,
                       "%s: short read in bytes %llu .. %llu (the file shrank or cannot be read)", f->path, at,
                       at + n);
        return WVOL_OK;
    }
    for (size_t done = 0; done < n;) {
        size_t want = f->direct || n - done < CHUNK_BYTES ? n - done : CHUNK_BYTES;
        unsigned char *to = f->direct ? (unsigned char *)dst + done : f->buf;
        WVOL_RETURN_IF(pread_full(fileno(f->fp), to, want, at + done), err, WVOL_ERR_IO,
                       "%s: short read in bytes %llu .. %llu (the file shrank or cannot be read)", f->path,
                       at + done, at + done + want);
        if (!f->direct)
            WVOL_FORWARD(wvol__nrrd_convert(dst + done / elem, f->buf, want / elem, &f->conv, f->path,
                                            (at + done - f->start) / elem, err));
        done += want;
    }
    return WVOL_OK;
}

static wvol_status file_read(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err)
{
    file_src *f = ctx;
    size_t elem = f->conv.elem, n = f->slice_bytes * nz, done = 0;
    unsigned long long at = (unsigned long long)z0 * f->slice_bytes;
    if (f->fp) return raw_at(f, dst, f->start + at, n, err);
    if (f->start + at != f->pos) {
        WVOL_RETURN_IF(gzseek(f->gz, (z_off_t)(f->start + at), SEEK_SET) < 0, err, WVOL_ERR_FORMAT,
                       "%s: cannot reach slice %zu of the gzip data (truncated or corrupt)", f->path, z0);
        f->pos = f->start + at;
    }
    while (done < n) {
        /* float32 in the host's byte order goes straight into dst: no staging copy */
        size_t want = n - done < CHUNK_BYTES || f->direct ? n - done : CHUNK_BYTES;
        unsigned char *to = f->direct ? (unsigned char *)dst + done : f->buf;
        int r, code = Z_OK;
        if (want > (size_t)1 << 30) want = (size_t)1 << 30; /* gzread takes an unsigned int */
        r = gzread(f->gz, to, (unsigned)want);
        if (r < 0) {
            const char *msg = gzerror(f->gz, &code);
            return wvol_error_set(err, WVOL_ERR_FORMAT, "corrupt gzip data in %s: %s", f->path,
                                  msg ? msg : "inflate failed");
        }
        f->pos += (unsigned)r;
        WVOL_RETURN_IF((size_t)r != want, err, WVOL_ERR_FORMAT,
                       "gzip data in %s end early after %llu of %llu bytes (truncated)", f->path,
                       f->pos - f->start, f->total);
        if (!f->direct)
            WVOL_FORWARD(wvol__nrrd_convert(dst + done / elem, f->buf, want / elem, &f->conv, f->path,
                                            (at + done) / elem, err));
        done += want;
    }
    if (at + n == f->total) {
        /* the last slab: the stream must end here */
        unsigned char extra;
        int r = gzread(f->gz, &extra, 1);
        WVOL_RETURN_IF(r != 0, err, WVOL_ERR_FORMAT, "gzip data in %s hold more than the %llu bytes the sizes need%s",
                       f->path, f->total, r < 0 ? " or are corrupt" : " (too long)");
    }
    return WVOL_OK;
}

/* Row bands of raw data (core/source_volume.h): per slice the band's bytes at their offset. */
static wvol_status file_rows(void *ctx, float *dst, size_t z0, size_t nz, size_t y0, size_t ny, wvol_error *err)
{
    file_src *f = ctx;
    const size_t n = f->row_bytes * ny;
    for (size_t k = 0; k < nz; k++)
        WVOL_FORWARD(raw_at(f, dst + k * (n / f->conv.elem),
                            f->start + (unsigned long long)(z0 + k) * f->slice_bytes + y0 * f->row_bytes, n, err));
    return WVOL_OK;
}

static const wvol_source_ops file_ops = {file_read, file_close};

/* A source over raw data (f->fp): slabs, and row bands where the data can be sought. */
static wvol_status raw_source(wvol_source **out, const size_t dims[3], const double spacing[3], const double origin[3],
                              const char *path, file_src *f, wvol_error *err)
{
    WVOL_FORWARD(wvol_source_create(out, dims, spacing, origin, path, 1, &file_ops, f, err));
    wvol__source_set_rows(*out, file_rows);
    return WVOL_OK;
}

static wvol_status new_file_src(file_src **out, const char *path, int type, size_t elem, int big_endian,
                                const size_t dims[3], wvol_error *err)
{
    const uint16_t one = 1;
    file_src *f = calloc(1, sizeof *f);
    WVOL_RETURN_IF(!f, err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    f->direct = type == WVOL_SAMPLE_TYPE_F32 && !big_endian == (*(const unsigned char *)&one == 1);
    f->path = strdup(path);
    f->buf = f->direct ? NULL : malloc(CHUNK_BYTES + 8);
    if (!f->path || (!f->direct && !f->buf)) {
        file_close(f);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    f->conv.type = type;
    f->conv.elem = elem;
    f->conv.big_endian = big_endian;
    f->row_bytes = dims[0] * elem;
    f->slice_bytes = dims[0] * dims[1] * elem;
    f->total = (unsigned long long)f->slice_bytes * dims[2];
    *out = f;
    return WVOL_OK;
}

wvol_status wvol__source_open_raw(wvol_source **out, const char *path, const wvol_load_options *opt,
                                  wvol_error *err)
{
    size_t elem, bytes;
    struct stat st;
    file_src *f;
    WVOL_RETURN_IF(!opt || !opt->dims[0] || !opt->dims[1] || !opt->dims[2], err, WVOL_ERR_ARG,
                   "%s: a raw file needs its dimensions (--dims NXxNYxNZ)", path);
    elem = wvol_sample_type_size(opt->raw_type);
    WVOL_RETURN_IF(!elem, err, WVOL_ERR_ARG, "%s: unknown raw sample type", path);
    WVOL_RETURN_IF(!wvol_size_mul3(opt->dims[0], opt->dims[1], opt->dims[2], elem, &bytes), err, WVOL_ERR_DIMS,
                   "%s: dimensions %zux%zux%zu overflow", path, opt->dims[0], opt->dims[1], opt->dims[2]);
    WVOL_RETURN_IF(stat(path, &st) != 0, err, WVOL_ERR_IO, "%s: %s", path, strerror(errno));
    WVOL_RETURN_IF(!S_ISREG(st.st_mode), err, WVOL_ERR_IO, "%s: not a regular file", path);
    WVOL_RETURN_IF((unsigned long long)st.st_size != (unsigned long long)bytes, err, WVOL_ERR_FORMAT,
                   "%s: file has %lld bytes but %zux%zux%zu %s samples need %zu", path, (long long)st.st_size,
                   opt->dims[0], opt->dims[1], opt->dims[2], wvol_sample_type_name(opt->raw_type), bytes);
    WVOL_FORWARD(new_file_src(&f, path, (int)opt->raw_type, elem, opt->big_endian, opt->dims, err));
    if (wvol__fopen_regular(&f->fp, path, err) != WVOL_OK) {
        wvol_status s = err ? err->status : WVOL_ERR_IO;
        file_close(f);
        return s;
    }
    return raw_source(out, opt->dims, opt->spacing, opt->origin, path, f, err);
}

/* NRRD with raw or gzip data and no "line skip": slab by slab. *whole = 1 (nothing
 * opened) for what only the whole-volume reader handles (ascii data, line skips, an axis
 * that runs backwards: the reader reverses it in memory). */
static wvol_status open_nrrd(wvol_source **out, const char *path, int *whole, wvol_error *err)
{
    nrrd_header h;
    FILE *fp, *dfp = NULL;
    char *dpath = NULL;
    const char *dname = path;
    file_src *f = NULL;
    size_t dims[3];
    long long size = 0, pos;
    struct stat st;
    wvol_status s;

    *whole = 0;
    s = wvol__nrrd_open_header(&h, path, &fp, err);
    if (!fp) return s;
    if (s) goto done;
    if (h.encoding == ENC_ASCII || h.line_skip > 0 || wvol__io_reversed_axes(h.spacing, h.dir)) {
        *whole = 1;
        goto done;
    }
    dims[0] = h.sizes[0], dims[1] = h.dim > 1 ? h.sizes[1] : 1, dims[2] = h.dim > 2 ? h.sizes[2] : 1;
    s = wvol__nrrd_open_data(&h, fp, &dfp, &dpath, &dname, err);
    if (s) goto done;
    pos = ftell(dfp);
    if (fstat(fileno(dfp), &st) != 0 || !S_ISREG(st.st_mode)) {
        s = HFAIL(&h, WVOL_ERR_IO, "data file %s is not a regular file", dname);
        goto done;
    }
    size = (long long)st.st_size;
    s = new_file_src(&f, dname, h.type, h.elem, h.big_endian, dims, err);
    if (s) goto done;
    if (h.encoding == ENC_RAW) {
        s = wvol__nrrd_raw_start(&h, dfp, dname, &pos, err);
        if (s) goto done;
        f->start = (unsigned long long)pos;
        f->fp = dfp;
        if (dfp == fp) fp = NULL;
        dfp = NULL;
    } else {
        int fd;
        if (h.byte_skip < 0 || (unsigned long long)h.bytes / 1032ull > (unsigned long long)(size - pos) + 64ull) {
            s = HFAIL(&h, WVOL_ERR_FORMAT, h.byte_skip < 0 ? "byte skip -1 is not allowed with gzip data in %s"
                                                           : "gzip data in %s cannot hold the bytes the sizes need",
                      dname);
            goto done;
        }
        fd = dup(fileno(dfp));
        if (fd < 0 || lseek(fd, (off_t)pos, SEEK_SET) < 0 || !(f->gz = gzdopen(fd, "rb"))) {
            if (fd >= 0) close(fd);
            s = HFAIL(&h, WVOL_ERR_NOMEM, "cannot start zlib on %s", dname);
            goto done;
        }
        gzbuffer(f->gz, 1 << 18);
        f->start = (unsigned long long)h.byte_skip;
        f->pos = 0;
    }
    s = f->fp ? raw_source(out, dims, h.spacing, h.origin, path, f, err)
              : wvol_source_create(out, dims, h.spacing, h.origin, path, 1, &file_ops, f, err);
    f = NULL; /* the source owns it now, or has closed it */
done:
    file_close(f);
    if (dfp && dfp != fp) fclose(dfp);
    if (fp) fclose(fp);
    free(dpath);
    wvol__nrrd_header_free(&h);
    return s;
}

/* ---- whole volumes ------------------------------------------------------------- */

static void whole_close(void *ctx) { wvol_volume_destroy(ctx); }

static wvol_status open_whole(wvol_source **out, const char *path, const wvol_load_options *opt, wvol_error *err)
{
    static const wvol_source_ops ops = {wvol__source_volume_read, whole_close};
    wvol_volume *v;
    size_t dims[3];
    WVOL_FORWARD(wvol_volume_load(&v, path, opt, err));
    dims[0] = v->nx, dims[1] = v->ny, dims[2] = v->nz;
    WVOL_FORWARD(wvol_source_create(out, dims, v->spacing, v->origin, path, 0, &ops, v, err));
    wvol__source_set_rows(*out, wvol__source_volume_rows);
    return WVOL_OK;
}

int wvol_source_format_streams(const char *path)
{
    return path && (wvol_path_has_ext(path, ".raw") || wvol_path_has_ext(path, ".nrrd") ||
                    wvol_path_has_ext(path, ".nhdr"));
}

wvol_status wvol_source_open(wvol_source **out, const char *path, const wvol_load_options *opt, wvol_error *err)
{
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "volume source: NULL argument");
    *out = NULL;
    if (wvol_path_has_ext(path, ".raw")) return wvol__source_open_raw(out, path, opt, err);
    if (wvol_path_has_ext(path, ".nrrd") || wvol_path_has_ext(path, ".nhdr")) {
        int whole = 0;
        WVOL_FORWARD(open_nrrd(out, path, &whole, err));
        if (!whole) return WVOL_OK;
    }
    return open_whole(out, path, opt, err);
}
