/* SPDX-License-Identifier: MIT
 * NRRD reader: attached and detached headers; raw, gzip and ascii data (the header
 * is parsed in nrrd_header.c).
 * Based on: the NRRD file format, teem.sourceforge.net/nrrd/format.html (NRRD0005).
 *
 * The data length is compared with what the sizes need before anything large is
 * allocated, and samples are converted chunk by chunk from bounded buffers. */
#define _POSIX_C_SOURCE 200809L
#include "core/file_open.h"
#include "io/io_internal.h"
#include "io/nrrd_internal.h"

#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

/* ---- reading the data --------------------------------------------------------- */

/* The integer sample at p (4 or 8 bytes, the header's byte order) as a magnitude and a sign. */
static void integer_at(const unsigned char *p, const nrrd_header *h, unsigned long long *mag, int *neg)
{
    const int size = h->type == T_I64 || h->type == T_U64 ? 8 : 4;
    const int is_signed = h->type == T_I64 || h->type == WVOL_SAMPLE_TYPE_I32;
    uint64_t u = 0;
    for (int b = 0; b < size; b++) u |= (uint64_t)p[h->big_endian ? size - 1 - b : b] << (8 * b);
    *neg = is_signed && (u >> (8 * size - 1)) & 1;
    if (*neg) u = size == 8 ? ~u + 1 : (uint64_t)(uint32_t)(~(uint32_t)u + 1u); /* two's complement magnitude */
    *mag = u;
}

wvol_status wvol__nrrd_convert(float *dst, const unsigned char *src, size_t n, const nrrd_header *h, const char *name,
                               unsigned long long first, wvol_error *err)
{
    const int wide = h->type == T_I64 || h->type == T_U64;
    if (!wide) wvol_samples_to_float(dst, src, n, (wvol_sample_type)h->type, h->big_endian);
    if (!wide && h->type != WVOL_SAMPLE_TYPE_I32 && h->type != WVOL_SAMPLE_TYPE_U32) return WVOL_OK;
    for (size_t i = 0; i < n; i++) {
        unsigned long long mag;
        int neg;
        integer_at(src + i * h->elem, h, &mag, &neg);
        if (wide) dst[i] = neg ? -(float)mag : (float)mag;
        /* long double holds every 64-bit integer, and 2^64 (where the largest round to) */
        if (mag > (1ull << 24) && (long double)fabsf(dst[i]) != (long double)mag) {
            char digits[24];
            snprintf(digits, sizeof digits, "%s%llu", neg ? "-" : "", mag);
            return wvol__inexact_integer(name, first + i, digits, err);
        }
    }
    return WVOL_OK;
}

static wvol_status skip_lines(const nrrd_header *h, FILE *fp, wvol_error *err)
{
    long long l;
    for (l = 0; l < h->line_skip; l++) {
        int c;
        while ((c = fgetc(fp)) != EOF && c != '\n') {
        }
        if (c == EOF) return HFAIL(h, WVOL_ERR_FORMAT, "data end within the %lld lines 'line skip' says to skip",
                                   h->line_skip);
    }
    return WVOL_OK;
}

static wvol_status file_size(const nrrd_header *h, FILE *fp, const char *name, long long *size, wvol_error *err)
{
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode))
        return HFAIL(h, WVOL_ERR_IO, "data file %s is not a regular file", name);
    *size = (long long)st.st_size;
    return WVOL_OK;
}

/* Creates the volume once the data length has been checked against the sizes. */
static wvol_status new_volume(const nrrd_header *h, wvol_volume **v, wvol_error *err)
{
    return wvol_volume_create(v, h->sizes[0], h->dim > 1 ? h->sizes[1] : 1, h->dim > 2 ? h->sizes[2] : 1, err);
}

wvol_status wvol__nrrd_raw_start(const nrrd_header *h, FILE *fp, const char *name, long long *start,
                                 wvol_error *err)
{
    long long size = 0, pos, left;
    WVOL_FORWARD(file_size(h, fp, name, &size, err));
    pos = ftell(fp);
    if (h->byte_skip == -1) {
        if ((long long)h->bytes > size - pos)
            return HFAIL(h, WVOL_ERR_FORMAT, "data file %s has %lld bytes after the header, the sizes need %zu",
                         name, size - pos, h->bytes);
        pos = size - (long long)h->bytes;
    } else {
        if (h->byte_skip > size - pos)
            return HFAIL(h, WVOL_ERR_FORMAT, "byte skip %lld goes past the end of %s", h->byte_skip, name);
        pos += h->byte_skip;
    }
    left = size - pos;
    if (left != (long long)h->bytes)
        return HFAIL(h, WVOL_ERR_FORMAT, "data file %s holds %lld data bytes but %zux%zux%zu %zu-byte samples need %zu (%s)",
                     name, left, h->sizes[0], h->dim > 1 ? h->sizes[1] : 1, h->dim > 2 ? h->sizes[2] : 1,
                     h->elem, h->bytes, left < (long long)h->bytes ? "truncated" : "too long");
    *start = pos;
    return WVOL_OK;
}

static wvol_status read_raw(const nrrd_header *h, FILE *fp, const char *name, wvol_volume **v, wvol_error *err)
{
    float *out;
    long long pos;
    size_t done = 0;
    unsigned char *buf;
    wvol_status s;
    WVOL_FORWARD(wvol__nrrd_raw_start(h, fp, name, &pos, err));
    if (fseek(fp, (long)pos, SEEK_SET) != 0) return HFAIL(h, WVOL_ERR_IO, "cannot seek in %s", name);
    WVOL_FORWARD(new_volume(h, v, err));
    out = (*v)->data;
    buf = malloc((size_t)CHUNK_SAMPLES * h->elem);
    if (!buf) return HFAIL(h, WVOL_ERR_NOMEM, "out of memory");
    while (done < h->count) {
        size_t want = h->count - done < CHUNK_SAMPLES ? h->count - done : CHUNK_SAMPLES;
        if (fread(buf, h->elem, want, fp) != want) {
            free(buf);
            return HFAIL(h, WVOL_ERR_IO, "read error in %s at sample %zu", name, done);
        }
        if ((s = wvol__nrrd_convert(out + done, buf, want, h, name, done, err)) != WVOL_OK) {
            free(buf);
            return s;
        }
        done += want;
    }
    free(buf);
    return WVOL_OK;
}

static wvol_status read_gzip(const nrrd_header *h, FILE *fp, const char *name, wvol_volume **v, wvol_error *err)
{
    float *out;
    long long size = 0, pos;
    unsigned char *in = NULL, *chunk = NULL, scratch[512];
    size_t chunk_bytes = (size_t)CHUNK_SAMPLES * h->elem, filled = 0, done = 0;
    unsigned long long skip = (unsigned long long)h->byte_skip, total = 0;
    unsigned long long need = (unsigned long long)h->bytes, want_total = skip + need;
    z_stream z;
    int zr, eof = 0;
    wvol_status s = WVOL_OK;

    WVOL_FORWARD(file_size(h, fp, name, &size, err));
    pos = ftell(fp);
    /* deflate cannot compress better than 1032:1, so a file too small for the
     * sizes is refused before anything large is read */
    if (need / 1032ull > (unsigned long long)(size - pos) + 64ull)
        return HFAIL(h, WVOL_ERR_FORMAT, "gzip data of %lld bytes in %s cannot hold the %zu bytes the sizes need",
                     size - pos, name, h->bytes);
    WVOL_FORWARD(new_volume(h, v, err));
    out = (*v)->data;
    memset(&z, 0, sizeof z);
    if (inflateInit2(&z, 15 + 32) != Z_OK) return HFAIL(h, WVOL_ERR_NOMEM, "cannot start zlib");
    in = malloc(GZ_IN_BYTES);
    chunk = malloc(chunk_bytes);
    if (!in || !chunk) {
        s = HFAIL(h, WVOL_ERR_NOMEM, "out of memory");
        goto done;
    }
    for (;;) {
        /* Output goes to scratch while skipping "byte skip" bytes, then into the
         * chunk (never past the data the sizes need), then to scratch again,
         * where any byte at all means the data are too long. */
        int phase;
        uInt before;
        unsigned long long got = total > skip ? total - skip : 0;
        if (z.avail_in == 0 && !eof) {
            z.avail_in = (uInt)fread(in, 1, GZ_IN_BYTES, fp);
            z.next_in = in;
            if (z.avail_in == 0) {
                if (ferror(fp)) {
                    s = HFAIL(h, WVOL_ERR_IO, "read error in %s", name);
                    goto done;
                }
                eof = 1;
            }
        }
        if (total < skip) {
            phase = 0;
            z.next_out = scratch;
            z.avail_out = (uInt)(skip - total < sizeof scratch ? skip - total : sizeof scratch);
        } else if (got < need) {
            unsigned long long room = chunk_bytes - filled, left = need - got;
            phase = 1;
            z.next_out = chunk + filled;
            z.avail_out = (uInt)(room < left ? room : left);
        } else {
            phase = 2;
            z.next_out = scratch;
            z.avail_out = sizeof scratch;
        }
        before = z.avail_out;
        zr = inflate(&z, Z_NO_FLUSH);
        total += before - z.avail_out;
        if (phase == 1) filled += before - z.avail_out;
        if (phase == 2 && z.avail_out != before) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "gzip data in %s hold more than the %llu bytes the sizes need (too long)",
                      name, want_total);
            goto done;
        }
        if (filled == chunk_bytes || (filled > 0 && total == want_total)) {
            if ((s = wvol__nrrd_convert(out + done, chunk, filled / h->elem, h, name, done, err)) != WVOL_OK) goto done;
            done += filled / h->elem;
            filled = 0;
        }
        if (zr == Z_STREAM_END) {
            /* another gzip member may follow; anything else is an error */
            if (z.avail_in == 0 && !eof) {
                z.avail_in = (uInt)fread(in, 1, GZ_IN_BYTES, fp);
                z.next_in = in;
            }
            if (z.avail_in == 0) break;
            if (z.avail_in >= 2 && z.next_in[0] == 0x1f && z.next_in[1] == 0x8b) {
                inflateReset(&z);
                continue;
            }
            s = HFAIL(h, WVOL_ERR_FORMAT, "%s has bytes after the end of its gzip data", name);
            goto done;
        }
        if (zr == Z_BUF_ERROR && z.avail_in == 0) {
            if (!eof) continue; /* needs more input */
            s = HFAIL(h, WVOL_ERR_FORMAT, "gzip data in %s end early after %llu of %llu bytes (truncated)", name,
                      total, want_total);
            goto done;
        }
        if (zr != Z_OK) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "corrupt gzip data in %s: %s", name, z.msg ? z.msg : "inflate failed");
            goto done;
        }
    }
    if (total != want_total)
        s = HFAIL(h, WVOL_ERR_FORMAT, "gzip data in %s hold %llu bytes but the sizes need %llu (truncated)", name,
                  total, want_total);
done:
    inflateEnd(&z);
    free(in);
    free(chunk);
    return s;
}

/* The values a sample of the header's type can hold, [*lo, *hi]; *integral for the integer
 * types. The binary encodings cannot hold anything else; a text value outside them is as
 * malformed as one that is not a number. */
static void type_range(int type, double *lo, double *hi, int *integral)
{
    *integral = 1;
    switch (type) {
    case WVOL_SAMPLE_TYPE_I8: *lo = INT8_MIN, *hi = INT8_MAX; break;
    case WVOL_SAMPLE_TYPE_U8: *lo = 0, *hi = UINT8_MAX; break;
    case WVOL_SAMPLE_TYPE_I16: *lo = INT16_MIN, *hi = INT16_MAX; break;
    case WVOL_SAMPLE_TYPE_U16: *lo = 0, *hi = UINT16_MAX; break;
    case WVOL_SAMPLE_TYPE_I32: *lo = INT32_MIN, *hi = INT32_MAX; break;
    case WVOL_SAMPLE_TYPE_U32: *lo = 0, *hi = UINT32_MAX; break;
    case T_I64: *lo = -9223372036854775808.0, *hi = 9223372036854775807.0; break;
    case T_U64: *lo = 0, *hi = 18446744073709551615.0; break;
    case WVOL_SAMPLE_TYPE_F32: *integral = 0, *lo = -FLT_MAX, *hi = FLT_MAX; break;
    default: *integral = 0, *lo = -DBL_MAX, *hi = DBL_MAX; break;
    }
}

static wvol_status read_ascii(const nrrd_header *h, FILE *fp, const char *name, wvol_volume **v, wvol_error *err)
{
    float *out;
    long long size = 0, pos;
    char *text, *p;
    size_t n = 0, got;
    char why[128];
    double lo, hi;
    int integral;
    type_range(h->type, &lo, &hi, &integral);
    WVOL_FORWARD(file_size(h, fp, name, &size, err));
    pos = ftell(fp);
    /* each value takes at least a digit and a separator */
    if ((unsigned long long)h->count > (unsigned long long)(size - pos) / 2 + 1)
        return HFAIL(h, WVOL_ERR_FORMAT, "ascii data in %s are too short for %zu values (truncated)", name, h->count);
    if ((unsigned long long)(size - pos) >= (unsigned long long)SIZE_MAX)
        return HFAIL(h, WVOL_ERR_NOMEM, "ascii data in %s too large", name);
    WVOL_FORWARD(new_volume(h, v, err));
    out = (*v)->data;
    text = malloc((size_t)(size - pos) + 1);
    if (!text) return HFAIL(h, WVOL_ERR_NOMEM, "out of memory");
    got = fread(text, 1, (size_t)(size - pos), fp);
    text[got] = '\0';
    p = text;
    for (;;) {
        char *end;
        double v;
        while (*p && (isspace((unsigned char)*p) || *p == ',')) p++;
        if (!*p) break;
        errno = 0;
        v = strtod(p, &end);
        /* a number ends at a separator: "5x" is one bad value, not 5 and then x. NaN and Inf in
         * a floating-point type are left to the samples' finite check, which names the voxel */
        why[0] = '\0';
        if (end == p || errno == ERANGE || (*end && !isspace((unsigned char)*end) && *end != ','))
            snprintf(why, sizeof why, "is not a number");
        else if (isfinite(v) ? !(v >= lo && v <= hi) : integral)
            snprintf(why, sizeof why, "is outside the range of type '%.20s' (%.9g to %.9g)", h->value[F_TYPE], lo, hi);
        else if (integral && v != floor(v))
            snprintf(why, sizeof why, "is not an integer (type '%.20s')", h->value[F_TYPE]);
        if (why[0]) {
            size_t len = strcspn(p, " \t\r\n\v\f,");
            wvol_status s = HFAIL(h, WVOL_ERR_FORMAT, "ascii data in %s: value %zu '%.*s' %s", name, n + 1,
                                  (int)(len < 20 ? len : 20), p, why);
            free(text); /* after the message: it quotes the text */
            return s;
        }
        if (integral && fabs(v) > 16777216.0 && (double)(float)v != v) {
            char digits[24];
            wvol_status s;
            size_t len = strcspn(p, " \t\r\n\v\f,");
            snprintf(digits, sizeof digits, "%.*s", (int)(len < 23 ? len : 23), p);
            s = wvol__inexact_integer(name, n, digits, err);
            free(text); /* after the message: it quotes the text */
            return s;
        }
        if (n == h->count) {
            free(text);
            return HFAIL(h, WVOL_ERR_FORMAT, "ascii data in %s hold more than the %zu values the sizes need (too long)",
                         name, h->count);
        }
        out[n++] = (float)v;
        p = end;
    }
    free(text);
    if (n != h->count)
        return HFAIL(h, WVOL_ERR_FORMAT, "ascii data in %s hold %zu values but the sizes need %zu (truncated)", name, n,
                     h->count);
    return WVOL_OK;
}

wvol_status wvol__nrrd_open_data(const nrrd_header *h, FILE *fp, FILE **dfp, char **dpath, const char **dname,
                                 wvol_error *err)
{
    *dfp = NULL, *dpath = NULL, *dname = h->path;
    if (h->value[F_DATA_FILE]) {
        *dpath = wvol__io_data_path_of(h->path, h->value[F_DATA_FILE]);
        if (!*dpath) return HFAIL(h, WVOL_ERR_NOMEM, "out of memory");
        wvol_error e;
        if (wvol__fopen_regular(dfp, *dpath, &e) != WVOL_OK) return HFAIL(h, WVOL_ERR_IO, "data file %s", e.message);
        *dname = *dpath;
        return WVOL_OK;
    }
    *dfp = fp;
    if (fseek(fp, h->data_offset, SEEK_SET) != 0) return HFAIL(h, WVOL_ERR_IO, "cannot seek to the data");
    return WVOL_OK;
}

wvol_status wvol_nrrd_read(wvol_volume **out, const char *path, wvol_error *err)
{
    nrrd_header h;
    FILE *fp, *dfp = NULL;
    char *dpath = NULL;
    const char *dname;
    wvol_volume *v = NULL;
    wvol_status s;

    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "nrrd read: NULL argument");
    *out = NULL;
    s = wvol__nrrd_open_header(&h, path, &fp, err);
    if (!fp) return s;
    if (s) goto done;

    s = wvol__nrrd_open_data(&h, fp, &dfp, &dpath, &dname, err);
    if (s) goto done;
    s = skip_lines(&h, dfp, err);
    if (s) goto done;
    if (h.encoding == ENC_RAW) s = read_raw(&h, dfp, dname, &v, err);
    else if (h.encoding == ENC_GZIP) s = read_gzip(&h, dfp, dname, &v, err);
    else s = read_ascii(&h, dfp, dname, &v, err);
    if (!s) s = wvol__io_apply_geometry(v, h.origin, h.spacing, h.dir, err); /* flips applied */
    if (!s) s = wvol_check_finite(v->data, v->nx, v->ny, v->nz, path, err);
done:
    if (dfp && dfp != fp) fclose(dfp);
    fclose(fp);
    free(dpath);
    wvol__nrrd_header_free(&h);
    if (s) {
        wvol_volume_destroy(v);
        return s;
    }
    *out = v;
    return WVOL_OK;
}
