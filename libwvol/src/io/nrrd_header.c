/* SPDX-License-Identifier: MIT
 * NRRD header: the fields of the format, parsed and checked (nrrd_read.c reads the
 * samples they describe).
 * Based on: the NRRD file format, teem.sourceforge.net/nrrd/format.html (NRRD0005).
 *
 * The reader trusts nothing in the file: every number is parsed in full and range
 * checked, and sizes are multiplied with overflow checks. */
#define _POSIX_C_SOURCE 200809L
#include "core/file_open.h"
#include "io/nrrd_internal.h"

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

void wvol__nrrd_header_free(nrrd_header *h)
{
    int f;
    for (f = 0; f < F_COUNT; f++) free(h->value[f]);
}

wvol_status wvol__nrrd_header_fail(const nrrd_header *h, wvol_error *err, wvol_status status, const char *fmt, ...)
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
    for (a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) h->dir[c][a] = a == c;
    for (a = 0; a < 3; a++) {
        h->spacing[a] = 1.0;
        h->origin[a] = 0.0;
        if (a >= h->dim) continue;
        if (have_dirs && !dir_none[a]) {
            double len = 0;
            int c;
            /* hypot: the squares of a spacing near 1e300 would overflow where its length does not */
            for (c = 0; c < h->space_dim; c++) len = hypot(len, dirs[a][c]);
            h->spacing[a] = len;
            for (c = 0; c < 3; c++) h->dir[c][a] = c < h->space_dim ? dirs[a][c] / len : 0;
        } else if (have_spacings && isfinite(spacings[a])) {
            h->spacing[a] = spacings[a]; /* negative: the reader reverses the axis */
        }
        if (h->value[F_SPACE_ORIGIN]) {
            if (a < h->space_dim) h->origin[a] = origin[a];
        } else if (have_mins && isfinite(mins[a])) {
            h->origin[a] = mins[a];
        }
        if (!isfinite(h->spacing[a]) || h->spacing[a] == 0)
            return HFAIL(h, WVOL_ERR_FORMAT, "axis %d: spacing %g is not finite and non-zero", a, h->spacing[a]);
    }
    /* into the frame the writer declares, left-posterior-superior (DICOM's): a right- or
     * anterior-pointing space's x or y is negated, directions and origin alike (the reader then
     * reverses the axes that run backwards); other spaces are taken as they are */
    if (h->value[F_SPACE]) {
        const char *t = h->value[F_SPACE];
        const int right = !strcasecmp(t, "RAS") || !strcasecmp(t, "right-anterior-superior");
        const int anterior = right || !strcasecmp(t, "LAS") || !strcasecmp(t, "left-anterior-superior");
        for (a = 0; a < 3; a++) {
            if (right) h->dir[0][a] = -h->dir[0][a];
            if (anterior) h->dir[1][a] = -h->dir[1][a];
        }
        if (h->value[F_SPACE_ORIGIN]) {
            if (right) h->origin[0] = -h->origin[0];
            if (anterior) h->origin[1] = -h->origin[1];
        }
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

wvol_status wvol__nrrd_read_header(nrrd_header *h, FILE *fp, wvol_error *err)
{
    wvol_status s = read_fields(h, fp, err);
    if (!s) s = interpret(h, err);
    return s;
}

wvol_status wvol__nrrd_open_header(nrrd_header *h, const char *path, FILE **fp, wvol_error *err)
{
    memset(h, 0, sizeof *h);
    h->path = path;
    WVOL_FORWARD(wvol__fopen_regular(fp, path, err));
    return wvol__nrrd_read_header(h, *fp, err);
}
