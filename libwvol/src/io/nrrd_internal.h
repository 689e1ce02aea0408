/* SPDX-License-Identifier: MIT
 * What the NRRD reader's two halves share (not installed): the header's fields and
 * their parsed values. nrrd_header.c parses and checks the header, nrrd_read.c reads
 * the samples it describes; nrrd_write.c needs neither. */
#ifndef WVOL_IO_NRRD_INTERNAL_H
#define WVOL_IO_NRRD_INTERNAL_H

#include <stddef.h>
#include <stdio.h>

#include "core/status_internal.h"
#include "wvol/io.h"

enum {
    NRRD_MAX_DIM = 16,
    LINE_MAX_BYTES = 65536,
    HEADER_MAX_LINES = 100000,
    CHUNK_SAMPLES = 1 << 16,
    GZ_IN_BYTES = 1 << 16
};
/* Sample types beyond wvol_sample_type, converted here. */
enum { T_I64 = 100, T_U64 = 101 };
enum { ENC_RAW, ENC_GZIP, ENC_ASCII };

/* ---- the fields of the format ------------------------------------------------ */

enum {
    F_TYPE, F_DIMENSION, F_SIZES, F_ENCODING, F_ENDIAN, F_SPACINGS, F_SPACE, F_SPACE_DIMENSION,
    F_SPACE_DIRECTIONS, F_SPACE_ORIGIN, F_AXIS_MINS, F_DATA_FILE, F_BYTE_SKIP, F_LINE_SKIP, F_KINDS,
    F_IGNORED, /* recognised, not needed */
    F_COUNT
};

typedef struct nrrd_header {
    const char *path;     /* for messages */
    char *value[F_COUNT]; /* the raw value of each field, or NULL */
    int line_of[F_COUNT];
    int type;
    size_t elem;
    int dim;
    size_t sizes[NRRD_MAX_DIM];
    int encoding;
    int big_endian;
    int space_dim;
    double spacing[3], origin[3]; /* spacing < 0: the axis runs backwards ('spacings') */
    double dir[3][3];             /* columns: the axes' unit directions ('space directions') */
    long long byte_skip, line_skip;
    size_t count, bytes;  /* samples, and bytes they need in the file */
    long data_offset;     /* attached data: offset just past the blank line */
    int attached;
} nrrd_header;

/* Reads the magic line and the fields up to the blank line (or EOF for a detached
 * header), leaving fp at the first data byte, then turns the field strings into
 * numbers, checking everything. h->path must be set; free with wvol__nrrd_header_free
 * whatever the outcome. */
wvol_status wvol__nrrd_read_header(nrrd_header *h, FILE *fp, wvol_error *err);
/* Zeroes *h, opens path and reads its header (wvol__nrrd_read_header). *fp is NULL when the
 * file could not be opened (the status says why; nothing to free); otherwise the caller
 * closes *fp and frees *h whatever the status. */
wvol_status wvol__nrrd_open_header(nrrd_header *h, const char *path, FILE **fp, wvol_error *err);
void wvol__nrrd_header_free(nrrd_header *h);

/* n samples of the header's type and byte order to float32. A 32- or 64-bit integer that float32
 * cannot hold exactly is refused (wvol__inexact_integer: the data file `name`, the sample's index
 * `first` + its place in src), as every reader refuses it (docs/formats.md, "Samples"). */
wvol_status wvol__nrrd_convert(float *dst, const unsigned char *src, size_t n, const nrrd_header *h, const char *name,
                               unsigned long long first, wvol_error *err);

/* Opens the samples: the detached data file (*dpath: its malloc'ed path) or fp itself
 * positioned at the first data byte; *dname names it in messages. The caller closes *dfp
 * when it is not fp and frees *dpath, whatever the outcome. */
wvol_status wvol__nrrd_open_data(const nrrd_header *h, FILE *fp, FILE **dfp, char **dpath, const char **dname,
                                 wvol_error *err);
/* Offset of the first raw sample in fp (positioned after the header and any line skip),
 * with the data length checked against the sizes ("byte skip", -1 included). */
wvol_status wvol__nrrd_raw_start(const nrrd_header *h, FILE *fp, const char *name, long long *start,
                                 wvol_error *err);

/* Fails with "<path>: <message>". */
wvol_status wvol__nrrd_header_fail(const nrrd_header *h, wvol_error *err, wvol_status status, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
#define HFAIL(h, status, ...) wvol__nrrd_header_fail((h), err, (status), __VA_ARGS__)

#endif
