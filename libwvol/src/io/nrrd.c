/* SPDX-License-Identifier: MIT
 * NRRD reader and writer (attached and detached headers; raw, gzip, ascii).
 * Based on: the NRRD file format, teem.sourceforge.net/nrrd/format.html (NRRD0005).
 *
 * The reader trusts nothing in the file: every number is parsed in full and range
 * checked, sizes are multiplied with overflow checks, the data length is compared
 * with what the sizes need before anything large is allocated, and samples are
 * converted chunk by chunk from bounded buffers. */
#define _POSIX_C_SOURCE 200809L
#include "core/status_internal.h"
#include "wvol/io.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <zlib.h>

#include "wvol/version.h"

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

static const struct {
    const char *name;
    int field;
} field_names[] = {
    {"type", F_TYPE}, {"dimension", F_DIMENSION}, {"sizes", F_SIZES}, {"encoding", F_ENCODING},
    {"endian", F_ENDIAN}, {"spacings", F_SPACINGS}, {"space", F_SPACE},
    {"space dimension", F_SPACE_DIMENSION}, {"space directions", F_SPACE_DIRECTIONS},
    {"space origin", F_SPACE_ORIGIN}, {"axis mins", F_AXIS_MINS}, {"axismins", F_AXIS_MINS},
    {"data file", F_DATA_FILE}, {"datafile", F_DATA_FILE}, {"byte skip", F_BYTE_SKIP},
    {"byteskip", F_BYTE_SKIP}, {"line skip", F_LINE_SKIP}, {"lineskip", F_LINE_SKIP},
    {"kinds", F_KINDS},
    {"content", F_IGNORED}, {"number", F_IGNORED}, {"block size", F_IGNORED},
    {"blocksize", F_IGNORED}, {"thicknesses", F_IGNORED}, {"axis maxs", F_IGNORED},
    {"axismaxs", F_IGNORED}, {"centerings", F_IGNORED}, {"centers", F_IGNORED},
    {"labels", F_IGNORED}, {"units", F_IGNORED}, {"min", F_IGNORED}, {"max", F_IGNORED},
    {"old min", F_IGNORED}, {"oldmin", F_IGNORED}, {"old max", F_IGNORED}, {"oldmax", F_IGNORED},
    {"sample units", F_IGNORED}, {"sampleunits", F_IGNORED}, {"space units", F_IGNORED},
    {"measurement frame", F_IGNORED},
};

static const struct {
    const char *name;
    int type;
} type_names[] = {
    {"signed char", WVOL_SAMPLE_TYPE_I8}, {"int8", WVOL_SAMPLE_TYPE_I8}, {"int8_t", WVOL_SAMPLE_TYPE_I8},
    {"uchar", WVOL_SAMPLE_TYPE_U8}, {"unsigned char", WVOL_SAMPLE_TYPE_U8}, {"uint8", WVOL_SAMPLE_TYPE_U8},
    {"uint8_t", WVOL_SAMPLE_TYPE_U8},
    {"short", WVOL_SAMPLE_TYPE_I16}, {"short int", WVOL_SAMPLE_TYPE_I16},
    {"signed short", WVOL_SAMPLE_TYPE_I16}, {"signed short int", WVOL_SAMPLE_TYPE_I16},
    {"int16", WVOL_SAMPLE_TYPE_I16}, {"int16_t", WVOL_SAMPLE_TYPE_I16},
    {"ushort", WVOL_SAMPLE_TYPE_U16}, {"unsigned short", WVOL_SAMPLE_TYPE_U16},
    {"unsigned short int", WVOL_SAMPLE_TYPE_U16}, {"uint16", WVOL_SAMPLE_TYPE_U16},
    {"uint16_t", WVOL_SAMPLE_TYPE_U16},
    {"int", WVOL_SAMPLE_TYPE_I32}, {"signed int", WVOL_SAMPLE_TYPE_I32}, {"int32", WVOL_SAMPLE_TYPE_I32},
    {"int32_t", WVOL_SAMPLE_TYPE_I32},
    {"uint", WVOL_SAMPLE_TYPE_U32}, {"unsigned int", WVOL_SAMPLE_TYPE_U32}, {"uint32", WVOL_SAMPLE_TYPE_U32},
    {"uint32_t", WVOL_SAMPLE_TYPE_U32},
    {"longlong", T_I64}, {"long long", T_I64}, {"long long int", T_I64}, {"signed long long", T_I64},
    {"signed long long int", T_I64}, {"int64", T_I64}, {"int64_t", T_I64},
    {"ulonglong", T_U64}, {"unsigned long long", T_U64}, {"unsigned long long int", T_U64}, {"uint64", T_U64},
    {"uint64_t", T_U64},
    {"float", WVOL_SAMPLE_TYPE_F32},
    {"double", WVOL_SAMPLE_TYPE_F64},
};

/* Kinds of axes that hold samples of one scalar volume. */
static const char *scalar_kinds[] = {"domain", "space", "time", "???", "none", "stub", "scalar"};

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
    double spacing[3], origin[3];
    long long byte_skip, line_skip;
    size_t count, bytes;  /* samples, and bytes they need in the file */
    long data_offset;     /* attached data: offset just past the blank line */
    int attached;
} nrrd_header;

static void header_free(nrrd_header *h)
{
    int f;
    for (f = 0; f < F_COUNT; f++) free(h->value[f]);
}

#define HFAIL(h, status, ...) header_fail((h), err, (status), __VA_ARGS__)

static wvol_status header_fail(const nrrd_header *h, wvol_error *err, wvol_status status,
                               const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static wvol_status header_fail(const nrrd_header *h, wvol_error *err, wvol_status status,
                               const char *fmt, ...)
{
    char msg[WVOL_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return wvol_error_set(err, status, "%s: %s", h->path, msg);
}

/* ---- small parsers ------------------------------------------------------------ */

static char *trim(char *s)
{
    char *e;
    while (*s == ' ' || *s == '\t') s++;
    e = s + strlen(s);
    while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) *--e = '\0';
    return s;
}

/* Next whitespace-separated token of *s (NUL-terminated in place), or NULL. */
static char *next_token(char **s)
{
    char *p = *s, *t;
    while (*p == ' ' || *p == '\t') p++;
    if (!*p) {
        *s = p;
        return NULL;
    }
    t = p;
    while (*p && *p != ' ' && *p != '\t') p++;
    if (*p) *p++ = '\0';
    *s = p;
    return t;
}

/* A whole token as an integer in [lo, hi]. */
static int parse_ll(const char *t, long long lo, long long hi, long long *out)
{
    char *end;
    long long v;
    if (!t || !*t || isspace((unsigned char)*t)) return 0;
    errno = 0;
    v = strtoll(t, &end, 10);
    if (errno || *end || v < lo || v > hi) return 0;
    *out = v;
    return 1;
}

/* A whole token as an unsigned size (digits only). */
static int parse_size(const char *t, size_t *out)
{
    char *end;
    unsigned long long v;
    if (!t || !isdigit((unsigned char)*t)) return 0;
    errno = 0;
    v = strtoull(t, &end, 10);
    if (errno || *end || v > (unsigned long long)SIZE_MAX) return 0;
    *out = (size_t)v;
    return 1;
}

/* A whole token as a double; nan allowed only if allow_nan. */
static int parse_double(const char *t, int allow_nan, double *out)
{
    char *end;
    if (!t || !*t || isspace((unsigned char)*t)) return 0;
    if (allow_nan && strcasecmp(t, "nan") == 0) {
        *out = NAN;
        return 1;
    }
    errno = 0;
    *out = strtod(t, &end);
    return !errno && !*end && isfinite(*out);
}

/* "(a,b,c)" with exactly n finite components; spaces allowed around them. */
static int parse_vector(const char *t, int n, double *out)
{
    const char *p = t;
    int i;
    while (*p == ' ') p++;
    if (*p++ != '(') return 0;
    for (i = 0; i < n; i++) {
        char *end;
        while (*p == ' ') p++;
        if (!*p || *p == ',' || *p == ')') return 0;
        errno = 0;
        out[i] = strtod(p, &end);
        if (end == p || errno || !isfinite(out[i])) return 0;
        p = end;
        while (*p == ' ') p++;
        if (*p != (i + 1 < n ? ',' : ')')) return 0;
        p++;
    }
    while (*p == ' ') p++;
    return *p == '\0';
}

/* ---- reading the header ------------------------------------------------------- */

/* One line (without '\n'; a trailing '\r' is dropped). Returns 1, 0 at EOF with
 * nothing read, -1 if the line is too long or holds a NUL byte. */
static int read_line(FILE *fp, char *buf, size_t cap, int *eof_no_newline)
{
    size_t n = 0;
    int c;
    *eof_no_newline = 0;
    while ((c = fgetc(fp)) != EOF && c != '\n') {
        if (c == '\0' || n + 1 >= cap) return -1;
        buf[n++] = (char)c;
    }
    if (c == EOF) {
        if (n == 0) return 0;
        *eof_no_newline = 1;
    }
    if (n > 0 && buf[n - 1] == '\r') n--;
    buf[n] = '\0';
    return 1;
}

static int field_of(const char *name)
{
    size_t i;
    for (i = 0; i < sizeof field_names / sizeof field_names[0]; i++)
        if (strcmp(name, field_names[i].name) == 0) return field_names[i].field;
    return -1;
}

/* Reads the magic line and the fields up to the blank line (or EOF for a detached
 * header). Leaves fp at the first data byte. */
static wvol_status read_fields(nrrd_header *h, FILE *fp, wvol_error *err)
{
    char *line = malloc(LINE_MAX_BYTES);
    int r, lineno = 0, eof_nl;
    wvol_status s = WVOL_OK;
    if (!line) return HFAIL(h, WVOL_ERR_NOMEM, "out of memory");
    r = read_line(fp, line, LINE_MAX_BYTES, &eof_nl);
    lineno = 1;
    if (r != 1 || strncmp(line, "NRRD000", 7) != 0 || line[7] < '1' || line[7] > '5' || line[8]) {
        s = HFAIL(h, WVOL_ERR_FORMAT, "not a NRRD file: the first line must be NRRD0001 to NRRD0005");
        goto done;
    }
    for (;;) {
        char *colon, *name, *val;
        int f;
        r = read_line(fp, line, LINE_MAX_BYTES, &eof_nl);
        lineno++;
        if (r < 0) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "header line %d is longer than %d bytes or holds a NUL byte",
                      lineno, LINE_MAX_BYTES);
            goto done;
        }
        if (r == 0) break; /* EOF: fine for a detached header, checked later */
        if (line[0] == '\0') {
            h->attached = 1;
            h->data_offset = ftell(fp);
            break;
        }
        if (lineno > HEADER_MAX_LINES) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "header has more than %d lines", HEADER_MAX_LINES);
            goto done;
        }
        if (line[0] == '#') continue;
        colon = strchr(line, ':');
        if (!colon) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "line %d: expected 'field: value', got '%.60s'", lineno, line);
            goto done;
        }
        if (colon[1] == '=') continue; /* key:=value pair, kept by nobody here */
        *colon = '\0';
        name = trim(line);
        val = trim(colon + 1);
        f = field_of(name);
        if (f < 0) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "line %d: unknown field '%.60s'", lineno, name);
            goto done;
        }
        if (f == F_IGNORED) continue;
        if (h->value[f]) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "line %d: field '%s' given twice (first on line %d)", lineno,
                      name, h->line_of[f]);
            goto done;
        }
        if (!*val) {
            s = HFAIL(h, WVOL_ERR_FORMAT, "line %d: field '%s' has no value", lineno, name);
            goto done;
        }
        h->value[f] = strdup(val);
        h->line_of[f] = lineno;
        if (!h->value[f]) {
            s = HFAIL(h, WVOL_ERR_NOMEM, "out of memory");
            goto done;
        }
        if (eof_nl) break;
        /* "data file: LIST" ends the header: file names follow, one a line */
        if (f == F_DATA_FILE && strncmp(val, "LIST", 4) == 0 && (val[4] == '\0' || val[4] == ' ')) break;
    }
done:
    free(line);
    return s;
}

/* Turns the field strings into numbers, checking everything. */
static wvol_status interpret(nrrd_header *h, wvol_error *err)
{
    char *p, *t;
    int a, i;
    long long ll;
    double dirs[NRRD_MAX_DIM][3], spacings[NRRD_MAX_DIM], mins[NRRD_MAX_DIM], origin[3];
    int dir_none[NRRD_MAX_DIM], have_dirs = 0, have_spacings = 0, have_mins = 0;
    size_t n3[3] = {1, 1, 1}, fbytes;

    /* type */
    if (!h->value[F_TYPE]) return HFAIL(h, WVOL_ERR_FORMAT, "missing 'type' field");
    h->type = -1;
    for (i = 0; i < (int)(sizeof type_names / sizeof type_names[0]); i++)
        if (strcasecmp(h->value[F_TYPE], type_names[i].name) == 0) h->type = type_names[i].type;
    if (h->type < 0) {
        if (strcasecmp(h->value[F_TYPE], "block") == 0)
            return HFAIL(h, WVOL_ERR_UNSUPPORTED, "line %d: type 'block' is not supported",
                         h->line_of[F_TYPE]);
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: unknown type '%.40s'", h->line_of[F_TYPE],
                     h->value[F_TYPE]);
    }
    h->elem = h->type == T_I64 || h->type == T_U64 ? 8 : wvol_sample_type_size((wvol_sample_type)h->type);

    /* dimension and sizes */
    if (!h->value[F_DIMENSION]) return HFAIL(h, WVOL_ERR_FORMAT, "missing 'dimension' field");
    if (!parse_ll(h->value[F_DIMENSION], 1, NRRD_MAX_DIM, &ll))
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: dimension '%.40s' is not an integer from 1 to %d",
                     h->line_of[F_DIMENSION], h->value[F_DIMENSION], NRRD_MAX_DIM);
    h->dim = (int)ll;
    if (h->dim > 3)
        return HFAIL(h, WVOL_ERR_UNSUPPORTED,
                     "dimension %d: only scalar volumes of 1 to 3 axes are read", h->dim);
    if (!h->value[F_SIZES]) return HFAIL(h, WVOL_ERR_FORMAT, "missing 'sizes' field");
    p = h->value[F_SIZES];
    for (a = 0; a < h->dim; a++) {
        t = next_token(&p);
        if (!t) return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'sizes' has %d values, dimension is %d",
                             h->line_of[F_SIZES], a, h->dim);
        if (!parse_size(t, &h->sizes[a]) || h->sizes[a] == 0)
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: size '%.40s' is not a positive integer",
                         h->line_of[F_SIZES], t);
        n3[a] = h->sizes[a];
    }
    if (next_token(&p))
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'sizes' has more than the %d values dimension says",
                     h->line_of[F_SIZES], h->dim);
    if (!wvol_size_mul3(n3[0], n3[1], n3[2], h->elem, &h->bytes) ||
        !wvol_size_mul3(n3[0], n3[1], n3[2], sizeof(float), &fbytes) || fbytes > (SIZE_MAX >> 1))
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: sizes %zux%zux%zu overflow the address space",
                     h->line_of[F_SIZES], n3[0], n3[1], n3[2]);
    h->count = n3[0] * n3[1] * n3[2];

    /* kinds: only axes of a scalar volume */
    if (h->value[F_KINDS]) {
        p = h->value[F_KINDS];
        for (a = 0; a < h->dim; a++) {
            size_t k;
            int ok = 0;
            t = next_token(&p);
            if (!t) return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'kinds' has %d values, dimension is %d",
                                 h->line_of[F_KINDS], a, h->dim);
            for (k = 0; k < sizeof scalar_kinds / sizeof scalar_kinds[0]; k++)
                if (strcasecmp(t, scalar_kinds[k]) == 0) ok = 1;
            if (!ok && h->sizes[a] > 1)
                return HFAIL(h, WVOL_ERR_UNSUPPORTED,
                             "axis %d has kind '%.40s': only scalar volumes are read", a, t);
        }
    }

    /* encoding and endianness */
    if (!h->value[F_ENCODING]) return HFAIL(h, WVOL_ERR_FORMAT, "missing 'encoding' field");
    t = h->value[F_ENCODING];
    if (!strcasecmp(t, "raw")) h->encoding = ENC_RAW;
    else if (!strcasecmp(t, "gzip") || !strcasecmp(t, "gz")) h->encoding = ENC_GZIP;
    else if (!strcasecmp(t, "ascii") || !strcasecmp(t, "text") || !strcasecmp(t, "txt")) h->encoding = ENC_ASCII;
    else if (!strcasecmp(t, "hex") || !strcasecmp(t, "bzip2") || !strcasecmp(t, "bz2") || !strcasecmp(t, "zrl"))
        return HFAIL(h, WVOL_ERR_UNSUPPORTED, "line %d: encoding '%s' is not supported (raw, gzip, ascii are)",
                     h->line_of[F_ENCODING], t);
    else
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: unknown encoding '%.40s'", h->line_of[F_ENCODING], t);
    h->big_endian = 0;
    if (h->value[F_ENDIAN]) {
        if (!strcasecmp(h->value[F_ENDIAN], "big")) h->big_endian = 1;
        else if (strcasecmp(h->value[F_ENDIAN], "little"))
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: endian '%.40s' is neither little nor big",
                         h->line_of[F_ENDIAN], h->value[F_ENDIAN]);
    } else if (h->elem > 1 && h->encoding != ENC_ASCII) {
        return HFAIL(h, WVOL_ERR_FORMAT, "missing 'endian' field (needed for %zu-byte samples)", h->elem);
    }

    /* space */
    h->space_dim = 0;
    if (h->value[F_SPACE] && h->value[F_SPACE_DIMENSION])
        return HFAIL(h, WVOL_ERR_FORMAT, "lines %d and %d: give 'space' or 'space dimension', not both",
                     h->line_of[F_SPACE], h->line_of[F_SPACE_DIMENSION]);
    if (h->value[F_SPACE]) {
        static const char *spaces3[] = {"right-anterior-superior", "RAS", "left-anterior-superior", "LAS",
                                        "left-posterior-superior", "LPS", "scanner-xyz", "3D-right-handed",
                                        "3D-left-handed"};
        size_t k;
        t = h->value[F_SPACE];
        for (k = 0; k < sizeof spaces3 / sizeof spaces3[0]; k++)
            if (strcasecmp(t, spaces3[k]) == 0) h->space_dim = 3;
        if (!h->space_dim) {
            size_t n = strlen(t);
            if (n > 5 && strcasecmp(t + n - 5, "-time") == 0)
                return HFAIL(h, WVOL_ERR_UNSUPPORTED, "line %d: space '%.60s' has a time axis: not supported",
                             h->line_of[F_SPACE], t);
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: unknown space '%.60s'", h->line_of[F_SPACE], t);
        }
    } else if (h->value[F_SPACE_DIMENSION]) {
        if (!parse_ll(h->value[F_SPACE_DIMENSION], 1, 3, &ll))
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: space dimension '%.40s' is not 1, 2 or 3",
                         h->line_of[F_SPACE_DIMENSION], h->value[F_SPACE_DIMENSION]);
        h->space_dim = (int)ll;
    }
    if (h->value[F_SPACE_DIRECTIONS]) {
        if (!h->space_dim)
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'space directions' needs a 'space' or 'space dimension'",
                         h->line_of[F_SPACE_DIRECTIONS]);
        p = h->value[F_SPACE_DIRECTIONS];
        for (a = 0; a < h->dim; a++) {
            double len = 0;
            int c;
            /* vectors may hold spaces: take everything up to the closing parenthesis */
            while (*p == ' ' || *p == '\t') p++;
            if (!*p) return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'space directions' has %d vectors, dimension is %d",
                                  h->line_of[F_SPACE_DIRECTIONS], a, h->dim);
            dir_none[a] = 0;
            if (strncmp(p, "none", 4) == 0 && (p[4] == '\0' || p[4] == ' ' || p[4] == '\t')) {
                dir_none[a] = 1;
                p += 4;
                continue;
            } else {
                char *close = strchr(p, ')'), save;
                if (!close) return HFAIL(h, WVOL_ERR_FORMAT, "line %d: direction %d is not a vector like (1,0,0)",
                                         h->line_of[F_SPACE_DIRECTIONS], a);
                save = close[1];
                close[1] = '\0';
                if (!parse_vector(p, h->space_dim, dirs[a]))
                    return HFAIL(h, WVOL_ERR_FORMAT, "line %d: direction %d '%.60s' is not a vector of %d finite numbers",
                                 h->line_of[F_SPACE_DIRECTIONS], a, p, h->space_dim);
                close[1] = save;
                p = close + 1;
            }
            for (c = 0; c < h->space_dim; c++) len += dirs[a][c] * dirs[a][c];
            if (!(len > 0))
                return HFAIL(h, WVOL_ERR_FORMAT, "line %d: direction %d has zero length",
                             h->line_of[F_SPACE_DIRECTIONS], a);
        }
        while (*p == ' ' || *p == '\t') p++;
        if (*p) return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'space directions' has more than %d vectors",
                             h->line_of[F_SPACE_DIRECTIONS], h->dim);
        have_dirs = 1;
    }
    if (h->value[F_SPACE_ORIGIN]) {
        if (!h->space_dim)
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'space origin' needs a 'space' or 'space dimension'",
                         h->line_of[F_SPACE_ORIGIN]);
        if (!parse_vector(h->value[F_SPACE_ORIGIN], h->space_dim, origin))
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: space origin '%.60s' is not a vector of %d finite numbers",
                         h->line_of[F_SPACE_ORIGIN], h->value[F_SPACE_ORIGIN], h->space_dim);
    }
    if (h->value[F_SPACINGS]) {
        p = h->value[F_SPACINGS];
        for (a = 0; a < h->dim; a++) {
            t = next_token(&p);
            if (!t) return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'spacings' has %d values, dimension is %d",
                                 h->line_of[F_SPACINGS], a, h->dim);
            if (!parse_double(t, 1, &spacings[a]) || spacings[a] == 0)
                return HFAIL(h, WVOL_ERR_FORMAT, "line %d: spacing '%.40s' is not a non-zero number",
                             h->line_of[F_SPACINGS], t);
        }
        if (next_token(&p))
            return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'spacings' has more than %d values",
                         h->line_of[F_SPACINGS], h->dim);
        have_spacings = 1;
    }
    if (h->value[F_AXIS_MINS]) {
        p = h->value[F_AXIS_MINS];
        for (a = 0; a < h->dim; a++) {
            t = next_token(&p);
            if (!t || !parse_double(t, 1, &mins[a]))
                return HFAIL(h, WVOL_ERR_FORMAT, "line %d: 'axis mins' needs %d numbers",
                             h->line_of[F_AXIS_MINS], h->dim);
        }
        have_mins = 1;
    }
    for (a = 0; a < 3; a++) {
        h->spacing[a] = 1.0;
        h->origin[a] = 0.0;
        if (a >= h->dim) continue;
        if (have_dirs && !dir_none[a]) {
            double len = 0;
            int c;
            for (c = 0; c < h->space_dim; c++) len += dirs[a][c] * dirs[a][c];
            h->spacing[a] = sqrt(len);
        } else if (have_spacings && isfinite(spacings[a])) {
            h->spacing[a] = fabs(spacings[a]);
        }
        if (h->value[F_SPACE_ORIGIN]) {
            if (a < h->space_dim) h->origin[a] = origin[a];
        } else if (have_mins && isfinite(mins[a])) {
            h->origin[a] = mins[a];
        }
        if (!isfinite(h->spacing[a]) || !(h->spacing[a] > 0))
            return HFAIL(h, WVOL_ERR_FORMAT, "axis %d: spacing %g is not finite and positive", a, h->spacing[a]);
    }

    /* where the data are */
    h->byte_skip = 0;
    h->line_skip = 0;
    if (h->value[F_BYTE_SKIP] && !parse_ll(h->value[F_BYTE_SKIP], -1, LLONG_MAX, &h->byte_skip))
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: byte skip '%.40s' is not an integer >= -1",
                     h->line_of[F_BYTE_SKIP], h->value[F_BYTE_SKIP]);
    if (h->value[F_LINE_SKIP] && !parse_ll(h->value[F_LINE_SKIP], 0, LLONG_MAX, &h->line_skip))
        return HFAIL(h, WVOL_ERR_FORMAT, "line %d: line skip '%.40s' is not an integer >= 0",
                     h->line_of[F_LINE_SKIP], h->value[F_LINE_SKIP]);
    if (h->byte_skip == -1 && h->encoding != ENC_RAW)
        return HFAIL(h, WVOL_ERR_FORMAT, "byte skip -1 (data at the end of the file) needs raw encoding");
    if (h->value[F_DATA_FILE]) {
        char *df = h->value[F_DATA_FILE], *q = df;
        int tokens = 0;
        if (strncmp(df, "LIST", 4) == 0 && (df[4] == '\0' || df[4] == ' '))
            return HFAIL(h, WVOL_ERR_UNSUPPORTED, "line %d: 'data file: LIST' (several data files) is not supported",
                         h->line_of[F_DATA_FILE]);
        while (*q) {
            while (*q == ' ') q++;
            if (*q) tokens++;
            while (*q && *q != ' ') q++;
        }
        if (strchr(df, '%') && tokens >= 4)
            return HFAIL(h, WVOL_ERR_UNSUPPORTED,
                         "line %d: a 'data file' name pattern (several data files) is not supported",
                         h->line_of[F_DATA_FILE]);
    } else if (!h->attached) {
        return HFAIL(h, WVOL_ERR_FORMAT,
                     "header names no 'data file' and no blank line separates it from attached data");
    }
    return WVOL_OK;
}

/* ---- reading the data --------------------------------------------------------- */

static void convert(float *dst, const unsigned char *src, size_t n, const nrrd_header *h)
{
    size_t i;
    int b;
    if (h->type != T_I64 && h->type != T_U64) {
        wvol_samples_to_float(dst, src, n, (wvol_sample_type)h->type, h->big_endian);
        return;
    }
    for (i = 0; i < n; i++, src += 8) {
        uint64_t u = 0;
        for (b = 0; b < 8; b++) u |= (uint64_t)src[h->big_endian ? b : 7 - b] << (8 * (7 - b));
        dst[i] = h->type == T_U64 ? (float)u : (float)(int64_t)u;
    }
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

static wvol_status read_raw(const nrrd_header *h, FILE *fp, const char *name, wvol_volume **v, wvol_error *err)
{
    float *out;
    long long size = 0, pos, left;
    size_t done = 0;
    unsigned char *buf;
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
        convert(out + done, buf, want, h);
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
            convert(out + done, chunk, filled / h->elem, h);
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

static wvol_status read_ascii(const nrrd_header *h, FILE *fp, const char *name, wvol_volume **v, wvol_error *err)
{
    float *out;
    long long size = 0, pos;
    char *text, *p;
    size_t n = 0, got;
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
        if (end == p || errno == ERANGE) {
            wvol_status s = HFAIL(h, WVOL_ERR_FORMAT, "ascii data in %s: value %zu '%.20s' is not a number", name,
                                  n + 1, p);
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

/* The detached data file's path: absolute, or relative to the header's folder. */
static char *data_path_of(const char *header_path, const char *data_file)
{
    const char *slash = strrchr(header_path, '/');
    size_t dir = slash ? (size_t)(slash - header_path) + 1 : 0, n = strlen(data_file);
    char *p;
    if (data_file[0] == '/' || dir == 0) return strdup(data_file);
    p = malloc(dir + n + 1);
    if (!p) return NULL;
    memcpy(p, header_path, dir);
    memcpy(p + dir, data_file, n + 1);
    return p;
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
    memset(&h, 0, sizeof h);
    h.path = path;
    fp = fopen(path, "rb");
    if (!fp) return wvol_error_set(err, WVOL_ERR_IO, "%s: %s", path, strerror(errno));
    s = read_fields(&h, fp, err);
    if (!s) s = interpret(&h, err);
    if (s) goto done;

    if (h.value[F_DATA_FILE]) {
        dpath = data_path_of(path, h.value[F_DATA_FILE]);
        if (!dpath) {
            s = HFAIL(&h, WVOL_ERR_NOMEM, "out of memory");
            goto done;
        }
        dfp = fopen(dpath, "rb");
        if (!dfp) {
            s = HFAIL(&h, WVOL_ERR_IO, "data file %s: %s", dpath, strerror(errno));
            goto done;
        }
        dname = dpath;
    } else {
        dfp = fp;
        dname = path;
        if (fseek(fp, h.data_offset, SEEK_SET) != 0) {
            s = HFAIL(&h, WVOL_ERR_IO, "cannot seek to the data");
            goto done;
        }
    }
    s = skip_lines(&h, dfp, err);
    if (s) goto done;
    if (h.encoding == ENC_RAW) s = read_raw(&h, dfp, dname, &v, err);
    else if (h.encoding == ENC_GZIP) s = read_gzip(&h, dfp, dname, &v, err);
    else s = read_ascii(&h, dfp, dname, &v, err);
    if (!s) s = wvol_volume_set_geometry(v, h.spacing, h.origin, err);
    if (!s) s = wvol_check_finite(v->data, v->nx, v->ny, v->nz, path, err);
done:
    if (dfp && dfp != fp) fclose(dfp);
    fclose(fp);
    free(dpath);
    header_free(&h);
    if (s) {
        wvol_volume_destroy(v);
        return s;
    }
    *out = v;
    return WVOL_OK;
}

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
