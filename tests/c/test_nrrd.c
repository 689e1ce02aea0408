/* SPDX-License-Identifier: MIT */
/* NRRD reader and writer: round trips, every sample type, both byte orders, gzip,
 * ascii, detached headers, header variants, a table of malformed files (each
 * refused with a message), and a deterministic mutation run for the sanitizers. */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include "check.h"
#include "wvol/io.h"
#include "wvol_synth.h"

#define DIR_ "test_nrrd_tmp"

/* ---- helpers --------------------------------------------------------------- */

static void write_file(const char *path, const void *a, size_t na, const void *b, size_t nb)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) {
        CHECK(0, "cannot write %s", path);
        return;
    }
    if (na) fwrite(a, 1, na, fp);
    if (nb) fwrite(b, 1, nb, fp);
    fclose(fp);
}

/* gzip-compresses src into a malloc'd buffer. */
static unsigned char *gzip_bytes(const void *src, size_t n, size_t *out_n)
{
    z_stream z;
    size_t cap = compressBound((uLong)n) + 64;
    unsigned char *out = malloc(cap);
    memset(&z, 0, sizeof z);
    deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);
    z.next_in = (Bytef *)src;
    z.avail_in = (uInt)n;
    z.next_out = out;
    z.avail_out = (uInt)cap;
    deflate(&z, Z_FINISH);
    *out_n = cap - z.avail_out;
    deflateEnd(&z);
    return out;
}

static int count_dir_entries(const char *dir)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    int n = 0;
    if (!d) return -1;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    closedir(d);
    return n;
}

/* The process's umask from /proc/self/status, -1 where it cannot be read (the umask call
 * would set it). */
static int proc_umask(void)
{
    char line[128];
    unsigned m;
    int found = 0;
    FILE *fp = fopen("/proc/self/status", "r");
    if (!fp) return -1;
    while (!found && fgets(line, sizeof line, fp)) found = sscanf(line, "Umask: %o", &m) == 1;
    fclose(fp);
    return found ? (int)m : -1;
}

static void clean_dir(const char *dir)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    char p[1024];
    if (!d) return;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (remove(p) != 0) rmdir(p);
    }
    closedir(d);
}

static wvol_volume *test_volume(size_t nx, size_t ny, size_t nz)
{
    wvol_volume *v = NULL;
    size_t i;
    wvol_error err;
    double sp[3] = {0.5, 0.75, 1.25}, org[3] = {-10.25, 3.0, 1e-3};
    if (wvol_volume_create(&v, nx, ny, nz, &err) != WVOL_OK) return NULL;
    for (i = 0; i < nx * ny * nz; i++) v->data[i] = (float)((double)i * 0.37 - 11.0 + 1e-7 * (double)(i * i));
    wvol_volume_set_geometry(v, sp, org, &err);
    return v;
}

static int volumes_equal(const wvol_volume *a, const wvol_volume *b)
{
    int k;
    if (!a || !b || a->nx != b->nx || a->ny != b->ny || a->nz != b->nz) return 0;
    for (k = 0; k < 3; k++)
        if (a->spacing[k] != b->spacing[k] || a->origin[k] != b->origin[k]) return 0;
    return memcmp(a->data, b->data, wvol_volume_count(a) * sizeof(float)) == 0;
}

/* ---- round trips ------------------------------------------------------------- */

static void round_trips_both_header_kinds(void)
{
    static const char *names[] = {DIR_ "/rt.nrrd", DIR_ "/rt.nhdr", DIR_ "/rt2.NRRD"};
    wvol_volume *v = test_volume(13, 7, 5), *w = NULL;
    wvol_error err;
    int n, gz;
    char dpath[256];
    for (gz = 0; gz <= 1; gz++)
        for (n = 0; n < 3; n++) {
            CHECK(wvol_nrrd_write_gzip(v, names[n], gz ? 9 : 0, &err) == WVOL_OK, "write %s: %s", names[n], err.message);
            CHECK(wvol_volume_load(&w, names[n], NULL, &err) == WVOL_OK, "read %s: %s", names[n], err.message);
            CHECK(volumes_equal(v, w), "%s gzip=%d round trip is exact", names[n], gz);
            wvol_volume_destroy(w);
            w = NULL;
        }
    /* detached: the data file sits beside the header and is named after it */
    CHECK(wvol_nrrd_data_path(dpath, sizeof dpath, DIR_ "/rt.nhdr", 1) && !strcmp(dpath, DIR_ "/rt.raw.gz"),
          "data path %s", dpath);
    CHECK(access(DIR_ "/rt.raw", F_OK) == 0 && access(DIR_ "/rt.raw.gz", F_OK) == 0, "detached data files exist");
    CHECK(!wvol_nrrd_data_path(dpath, 8, DIR_ "/rt.nhdr", 0), "data path too long for the buffer");
    /* the generic save picks NRRD by extension, raw encoding */
    CHECK(wvol_volume_save(v, DIR_ "/save.nrrd", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_nrrd_read(&w, DIR_ "/save.nrrd", &err) == WVOL_OK && volumes_equal(v, w), "save/read");
    wvol_volume_destroy(w);
    /* a big, compressible volume exercises the chunked paths */
    {
        wvol_synth_params p;
        wvol_volume *s = NULL;
        wvol_synth_params_default(&p);
        p.dims[0] = 97, p.dims[1] = 83, p.dims[2] = 41;
        wvol_synth_skull(&s, NULL, &p, &err);
        CHECK(wvol_nrrd_write_gzip(s, DIR_ "/big.nrrd", 1, &err) == WVOL_OK, "%s", err.message);
        w = NULL;
        CHECK(wvol_nrrd_read(&w, DIR_ "/big.nrrd", &err) == WVOL_OK && volumes_equal(s, w), "big gzip round trip: %s",
              err.message);
        wvol_volume_destroy(w);
        wvol_volume_destroy(s);
    }
    wvol_volume_destroy(v);
}

/* ---- every sample type, both byte orders, raw/gzip/ascii -------------------- */

static const double test_values[6] = {0, 1, 7, 100, 126, 2};
static const double signed_values[6] = {-128, -1, 0, 5, 127, -7};

static void put(unsigned char *dst, const char *type, double x, int big)
{
    unsigned char b[8];
    size_t size = 0, k;
    if (!strcmp(type, "int8")) { int8_t t = (int8_t)x; memcpy(b, &t, size = 1); }
    else if (!strcmp(type, "uchar")) { uint8_t t = (uint8_t)x; memcpy(b, &t, size = 1); }
    else if (!strcmp(type, "short")) { int16_t t = (int16_t)x; memcpy(b, &t, size = 2); }
    else if (!strcmp(type, "ushort")) { uint16_t t = (uint16_t)x; memcpy(b, &t, size = 2); }
    else if (!strcmp(type, "int")) { int32_t t = (int32_t)x; memcpy(b, &t, size = 4); }
    else if (!strcmp(type, "uint")) { uint32_t t = (uint32_t)x; memcpy(b, &t, size = 4); }
    else if (!strcmp(type, "int64")) { int64_t t = (int64_t)x; memcpy(b, &t, size = 8); }
    else if (!strcmp(type, "uint64")) { uint64_t t = (uint64_t)x; memcpy(b, &t, size = 8); }
    else if (!strcmp(type, "float")) { float t = (float)x; memcpy(b, &t, size = 4); }
    else { double t = x; memcpy(b, &t, size = 8); }
    for (k = 0; k < size; k++) dst[k] = big ? b[size - 1 - k] : b[k]; /* host is little-endian */
}

static void every_type_and_byte_order(void)
{
    static const struct {
        const char *type;
        size_t size;
        int is_signed;
    } types[] = {{"int8", 1, 1},  {"uchar", 1, 0},  {"short", 2, 1}, {"ushort", 2, 0}, {"int", 4, 1},
                 {"uint", 4, 0},  {"int64", 8, 1},  {"uint64", 8, 0}, {"float", 4, 1},  {"double", 8, 1}};
    size_t t;
    int big, enc, i;
    for (t = 0; t < sizeof types / sizeof types[0]; t++)
        for (enc = 0; enc < 3; enc++)
            for (big = 0; big <= 1; big++) {
                const double *vals = types[t].is_signed ? signed_values : test_values;
                unsigned char data[48], *gz = NULL;
                char hdr[512], body[256];
                size_t n = 0, gzn = 0;
                wvol_volume *v = NULL;
                wvol_error err;
                const char *path = DIR_ "/type.nrrd";
                if (enc == 2 && big) continue; /* byte order means nothing to ascii */
                for (i = 0; i < 6; i++) put(data + (size_t)i * types[t].size, types[t].type, vals[i], big);
                snprintf(hdr, sizeof hdr,
                         "NRRD0005\ntype: %s\ndimension: 2\nsizes: 3 2\nencoding: %s\n%s\n", types[t].type,
                         enc == 0 ? "raw" : enc == 1 ? "gzip" : "ascii",
                         types[t].size > 1 && enc != 2 ? (big ? "endian: big\n" : "endian: little\n") : "");
                if (enc == 0) write_file(path, hdr, strlen(hdr), data, 6 * types[t].size);
                else if (enc == 1) {
                    gz = gzip_bytes(data, 6 * types[t].size, &gzn);
                    write_file(path, hdr, strlen(hdr), gz, gzn);
                    free(gz);
                } else {
                    for (i = 0; i < 6; i++) n += (size_t)snprintf(body + n, sizeof body - n, "%g%s", vals[i], i == 2 ? "\n" : " ");
                    write_file(path, hdr, strlen(hdr), body, n);
                }
                CHECK(wvol_nrrd_read(&v, path, &err) == WVOL_OK, "%s enc %d big %d: %s", types[t].type, enc, big,
                      err.message);
                if (!v) continue;
                CHECK(v->nx == 3 && v->ny == 2 && v->nz == 1, "%s: 2D sizes", types[t].type);
                for (i = 0; i < 6; i++)
                    CHECK(v->data[i] == (float)vals[i], "%s enc %d big %d sample %d: %g vs %g", types[t].type, enc,
                          big, i, v->data[i], vals[i]);
                wvol_volume_destroy(v);
            }
}

/* ---- header variants that must be accepted ----------------------------------- */

static wvol_volume *read_text(const char *name, const char *text, const void *data, size_t n, wvol_error *err)
{
    char path[256];
    wvol_volume *v = NULL;
    snprintf(path, sizeof path, DIR_ "/%s", name);
    write_file(path, text, strlen(text), data, n);
    if (wvol_nrrd_read(&v, path, err) != WVOL_OK) return NULL;
    return v;
}

static void header_variants_accepted(void)
{
    float d8[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    wvol_volume *v;
    wvol_error err;

    v = read_text("spacings.nrrd", "NRRD0001\n# comment\nkey:=value\ncontent: x\ntype: float\ndimension: 3\n"
                                   "sizes: 2 2 2\nspacings: 0.5 -2 nan\naxis mins: 1 2 3\nendian: little\n"
                                   "encoding: raw\n\n", d8, sizeof d8, &err);
    CHECK(v && v->spacing[0] == 0.5 && v->spacing[1] == 2 && v->spacing[2] == 1, "spacings: %s", v ? "" : err.message);
    /* spacing -2: y runs backwards, so the axis is reversed and the origin is the last row's */
    CHECK(v && v->origin[0] == 1 && v->origin[1] == 0 && v->origin[2] == 3, "axis mins give the origin");
    CHECK(v && v->data[7] == 6 && v->data[5] == 8 && v->data[0] == 3, "data, y reversed");
    wvol_volume_destroy(v);

    v = read_text("crlf.nrrd", "NRRD0004\r\ntype: float\r\ndimension: 3\r\nspace: RAS\r\nsizes: 2 2 2\r\n"
                               "space directions: (0,0.5,0) (2,0,0) (0,0,-3)\r\nkinds: domain space domain\r\n"
                               "endian: little\r\nencoding: raw\r\nspace origin: (1.5, -2,3)\r\n\r\n", d8, sizeof d8, &err);
    CHECK(v && v->spacing[0] == 0.5 && v->spacing[1] == 2 && v->spacing[2] == 3, "CRLF, rotated directions: %s",
          v ? "" : err.message);
    /* RAS into LPS: the origin's x and y negated; the x-y swap is dropped; z, left on its own
     * axis, runs down and is reversed */
    CHECK(v && v->origin[0] == -1.5 && v->origin[1] == 2 && v->origin[2] == 0, "space origin with spaces");
    CHECK(v && v->data[0] == 5 && v->data[4] == 1, "z reversed");
    wvol_volume_destroy(v);

    v = read_text("sd2.nrrd", "NRRD0005\ntype: float\ndimension: 2\nspace dimension: 2\nsizes: 4 2\n"
                              "space directions: (3,0) (0,4)\nspace origin: (7,8)\nendian: little\nencoding: raw\n\n",
                  d8, sizeof d8, &err);
    CHECK(v && v->nx == 4 && v->ny == 2 && v->nz == 1 && v->spacing[1] == 4 && v->origin[1] == 8, "2D space: %s",
          v ? "" : err.message);
    wvol_volume_destroy(v);

    v = read_text("dim1.nrrd", "NRRD0005\ntype: float\ndimension: 1\nsizes: 8\nendian: little\nencoding: raw\n\n",
                  d8, sizeof d8, &err);
    CHECK(v && v->nx == 8 && v->ny == 1 && v->nz == 1, "1D: %s", v ? "" : err.message);
    wvol_volume_destroy(v);

    {
        unsigned char skip[5 + sizeof d8];
        memcpy(skip, "JUNK\n", 5);
        memcpy(skip + 5, d8, sizeof d8);
        v = read_text("skips.nrrd", "NRRD0005\ntype: float\ndimension: 3\nsizes: 2 2 2\nline skip: 1\n"
                                    "byte skip: 0\nendian: little\nencoding: raw\n\n", skip, sizeof skip, &err);
        CHECK(v && v->data[0] == 1 && v->data[7] == 8, "line skip: %s", v ? "" : err.message);
        wvol_volume_destroy(v);
        v = read_text("skipm1.nrrd", "NRRD0005\ntype: float\ndimension: 3\nsizes: 2 2 2\nbyte skip: -1\n"
                                     "endian: little\nencoding: raw\n\n", skip, sizeof skip, &err);
        CHECK(v && v->data[0] == 1 && v->data[7] == 8, "byte skip -1: %s", v ? "" : err.message);
        wvol_volume_destroy(v);
        v = read_text("skip5.nrrd", "NRRD0005\ntype: float\ndimension: 3\nsizes: 2 2 2\nbyte skip: 5\n"
                                    "endian: little\nencoding: raw\n\n", skip, sizeof skip, &err);
        CHECK(v && v->data[0] == 1 && v->data[7] == 8, "byte skip 5: %s", v ? "" : err.message);
        wvol_volume_destroy(v);
    }
    {
        /* gzip with a byte skip inside the decompressed data, and two gzip members */
        unsigned char raw[3 + sizeof d8], *g1, *g2, both[1024];
        size_t n1, n2;
        memcpy(raw, "abc", 3);
        memcpy(raw + 3, d8, sizeof d8);
        g1 = gzip_bytes(raw, 3 + 16, &n1);
        g2 = gzip_bytes(raw + 3 + 16, 16, &n2);
        memcpy(both, g1, n1);
        memcpy(both + n1, g2, n2);
        v = read_text("gzskip.nrrd", "NRRD0005\ntype: float\ndimension: 3\nsizes: 2 2 2\nbyte skip: 3\n"
                                     "endian: little\nencoding: gz\n\n", both, n1 + n2, &err);
        CHECK(v && v->data[0] == 1 && v->data[7] == 8, "gzip members + byte skip: %s", v ? "" : err.message);
        wvol_volume_destroy(v);
        free(g1);
        free(g2);
    }
    /* detached header naming a data file in a sub-folder, and an attached header
     * whose data are elsewhere anyway */
    mkdir(DIR_ "/sub", 0777);
    write_file(DIR_ "/sub/d.bin", d8, sizeof d8, NULL, 0);
    v = read_text("det.nhdr", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\n"
                              "encoding: raw\ndata file: sub/d.bin", NULL, 0, &err);
    CHECK(v && v->data[5] == 6, "detached, no final newline: %s", v ? "" : err.message);
    wvol_volume_destroy(v);
    v = read_text("det2.nrrd", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\n"
                               "encoding: raw\ndatafile: ./sub/d.bin\n\ntrailing bytes are not data\n", NULL, 0, &err);
    CHECK(v && v->data[5] == 6, "data file in a .nrrd: %s", v ? "" : err.message);
    wvol_volume_destroy(v);
}

/* ---- malformed files -------------------------------------------------------- */

typedef struct bad_case {
    const char *what;
    const char *header;  /* written as is */
    int data;            /* 0: none; 1: 8 floats; 2: 7 floats; 3: 9 floats; 4: gzip 8 floats;
                            5: gzip truncated; 6: gzip corrupt; 7: gzip 9 floats; 8: gzip + junk;
                            9: 8 floats with a NaN; 10: ascii 7 values; 11: ascii 9; 12: ascii junk;
                            13: ascii 300 third; 14: ascii -1 second; 15: ascii 1e40 sixth;
                            16: ascii 2.5 second (the types' limits are read: every_type_and_byte_order) */
    wvol_status status;
    const char *needle;  /* must appear in the message */
} bad_case;

#define H3 "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\n"

static const bad_case bad_cases[] = {
    {"empty file", "", 0, WVOL_ERR_FORMAT, "not a NRRD"},
    {"wrong magic", "NRRD0009\n", 0, WVOL_ERR_FORMAT, "not a NRRD"},
    {"no magic", "type: float\n", 0, WVOL_ERR_FORMAT, "not a NRRD"},
    {"missing type", "NRRD0004\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT, "missing 'type'"},
    {"missing dimension", "NRRD0004\ntype: float\nsizes: 2 2 2\nencoding: raw\nendian: little\n\n", 1, WVOL_ERR_FORMAT,
     "missing 'dimension'"},
    {"missing sizes", "NRRD0004\ntype: float\ndimension: 3\nencoding: raw\nendian: little\n\n", 1, WVOL_ERR_FORMAT,
     "missing 'sizes'"},
    {"missing encoding", H3 "\n", 1, WVOL_ERR_FORMAT, "missing 'encoding'"},
    {"missing endian", "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT,
     "missing 'endian'"},
    {"unknown type", "NRRD0004\ntype: float32x\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT,
     "unknown type"},
    {"block type", "NRRD0004\ntype: block\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_UNSUPPORTED,
     "block"},
    {"dimension not a number", "NRRD0004\ntype: float\ndimension: three\nsizes: 2 2 2\nencoding: raw\n\n", 1,
     WVOL_ERR_FORMAT, "dimension"},
    {"dimension 0", "NRRD0004\ntype: float\ndimension: 0\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT, "dimension"},
    {"dimension 3x", "NRRD0004\ntype: float\ndimension: 3x\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT, "dimension"},
    {"dimension 99", "NRRD0004\ntype: float\ndimension: 99\nsizes: 2 2 2\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT, "dimension"},
    {"dimension 4", "NRRD0004\ntype: float\ndimension: 4\nsizes: 2 2 2 1\nencoding: raw\n\n", 1, WVOL_ERR_UNSUPPORTED,
     "1 to 3 axes"},
    {"too few sizes", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2\nendian: little\nencoding: raw\n\n", 1,
     WVOL_ERR_FORMAT, "sizes"},
    {"too many sizes", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2 2\nendian: little\nencoding: raw\n\n", 1,
     WVOL_ERR_FORMAT, "more than"},
    {"size 0", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 0 2\nendian: little\nencoding: raw\n\n", 1, WVOL_ERR_FORMAT,
     "positive integer"},
    {"negative size", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 -2 2\nendian: little\nencoding: raw\n\n", 1,
     WVOL_ERR_FORMAT, "positive integer"},
    {"size 1e3", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1e3 2\nendian: little\nencoding: raw\n\n", 1,
     WVOL_ERR_FORMAT, "positive integer"},
    {"size beyond 64 bits", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 99999999999999999999999 2\nendian: little\n"
     "encoding: raw\n\n", 1, WVOL_ERR_FORMAT, "positive integer"},
    {"sizes overflow", "NRRD0004\ntype: float\ndimension: 3\nsizes: 4294967296 4294967296 4294967296\nendian: little\n"
     "encoding: raw\n\n", 1, WVOL_ERR_FORMAT, "overflow"},
    {"huge sizes, tiny file", "NRRD0004\ntype: float\ndimension: 3\nsizes: 100000 100000 1000\nendian: little\n"
     "encoding: raw\n\n", 1, WVOL_ERR_FORMAT, "truncated"},
    {"huge sizes, tiny gzip", "NRRD0004\ntype: float\ndimension: 3\nsizes: 100000 100000 1000\nendian: little\n"
     "encoding: gzip\n\n", 4, WVOL_ERR_FORMAT, "cannot hold"},
    {"huge sizes, tiny ascii", "NRRD0004\ntype: float\ndimension: 3\nsizes: 100000 100000 1000\nencoding: ascii\n\n",
     10, WVOL_ERR_FORMAT, "too short"},
    {"bzip2", H3 "encoding: bzip2\n\n", 1, WVOL_ERR_UNSUPPORTED, "bzip2"},
    {"unknown encoding", H3 "encoding: lz4\n\n", 1, WVOL_ERR_FORMAT, "unknown encoding"},
    {"bad endian", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: middle\nencoding: raw\n\n", 1,
     WVOL_ERR_FORMAT, "endian"},
    {"unknown space", H3 "encoding: raw\nspace: sideways\n\n", 1, WVOL_ERR_FORMAT, "unknown space"},
    {"space with time", H3 "encoding: raw\nspace: RAS-time\n\n", 1, WVOL_ERR_UNSUPPORTED, "time"},
    {"space twice over", H3 "encoding: raw\nspace: RAS\nspace dimension: 3\n\n", 1, WVOL_ERR_FORMAT, "not both"},
    {"space dimension 7", H3 "encoding: raw\nspace dimension: 7\n\n", 1, WVOL_ERR_FORMAT, "space dimension"},
    {"directions without space", H3 "encoding: raw\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n\n", 1, WVOL_ERR_FORMAT,
     "needs a 'space'"},
    {"too few directions", H3 "encoding: raw\nspace: LPS\nspace directions: (1,0,0) (0,1,0)\n\n", 1, WVOL_ERR_FORMAT,
     "vectors"},
    {"too many directions", H3 "encoding: raw\nspace: LPS\nspace directions: (1,0,0) (0,1,0) (0,0,1) (1,1,1)\n\n", 1,
     WVOL_ERR_FORMAT, "more than"},
    {"short direction", H3 "encoding: raw\nspace: LPS\nspace directions: (1,0) (0,1,0) (0,0,1)\n\n", 1, WVOL_ERR_FORMAT,
     "vector of 3"},
    {"unclosed direction", H3 "encoding: raw\nspace: LPS\nspace directions: (1,0,0 (0,1,0) (0,0,1\n\n", 1,
     WVOL_ERR_FORMAT, "direction"},
    {"nan direction", H3 "encoding: raw\nspace: LPS\nspace directions: (nan,0,0) (0,1,0) (0,0,1)\n\n", 1,
     WVOL_ERR_FORMAT, "finite"},
    {"zero direction", H3 "encoding: raw\nspace: LPS\nspace directions: (0,0,0) (0,1,0) (0,0,1)\n\n", 1,
     WVOL_ERR_FORMAT, "zero length"},
    {"bad origin", H3 "encoding: raw\nspace: LPS\nspace origin: (1,2)\n\n", 1, WVOL_ERR_FORMAT, "space origin"},
    {"origin without space", H3 "encoding: raw\nspace origin: (1,2,3)\n\n", 1, WVOL_ERR_FORMAT, "needs a 'space'"},
    {"zero spacing", H3 "encoding: raw\nspacings: 1 0 1\n\n", 1, WVOL_ERR_FORMAT, "spacing"},
    {"bad spacing", H3 "encoding: raw\nspacings: 1 x 1\n\n", 1, WVOL_ERR_FORMAT, "spacing"},
    {"infinite spacing", H3 "encoding: raw\nspacings: 1 inf 1\n\n", 1, WVOL_ERR_FORMAT, "spacing"},
    {"few spacings", H3 "encoding: raw\nspacings: 1 1\n\n", 1, WVOL_ERR_FORMAT, "spacings"},
    {"bad axis mins", H3 "encoding: raw\naxis mins: 1 1\n\n", 1, WVOL_ERR_FORMAT, "axis mins"},
    {"unknown field", H3 "encoding: raw\nsizez: 2 2 2\n\n", 1, WVOL_ERR_FORMAT, "unknown field 'sizez'"},
    {"field twice", H3 "encoding: raw\nendian: little\n\n", 1, WVOL_ERR_FORMAT, "twice"},
    {"empty value", H3 "encoding:\n\n", 1, WVOL_ERR_FORMAT, "no value"},
    {"line without colon", H3 "encoding raw\n\n", 1, WVOL_ERR_FORMAT, "expected 'field: value'"},
    {"vector kind", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nkinds: RGB-color domain domain\n"
     "endian: little\nencoding: raw\n\n", 1, WVOL_ERR_UNSUPPORTED, "RGB-color"},
    {"no blank line, no data file", H3 "encoding: raw\n", 0, WVOL_ERR_FORMAT, "no 'data file'"},
    {"missing data file", H3 "encoding: raw\ndata file: nowhere.raw\n", 0, WVOL_ERR_IO, "nowhere.raw"},
    {"data file LIST", H3 "encoding: raw\ndata file: LIST\na.raw\n", 0, WVOL_ERR_UNSUPPORTED, "LIST"},
    {"data file pattern", H3 "encoding: raw\ndata file: d%03d.raw 1 8 1\n", 0, WVOL_ERR_UNSUPPORTED, "pattern"},
    {"raw data short", H3 "encoding: raw\n\n", 2, WVOL_ERR_FORMAT, "truncated"},
    {"raw data long", H3 "encoding: raw\n\n", 3, WVOL_ERR_FORMAT, "too long"},
    {"byte skip past the end", H3 "encoding: raw\nbyte skip: 1000\n\n", 1, WVOL_ERR_FORMAT, "byte skip"},
    {"byte skip -2", H3 "encoding: raw\nbyte skip: -2\n\n", 1, WVOL_ERR_FORMAT, "byte skip"},
    {"byte skip -1 gzip", H3 "encoding: gzip\nbyte skip: -1\n\n", 4, WVOL_ERR_FORMAT, "byte skip -1"},
    {"line skip past the end", H3 "encoding: raw\nline skip: 100\n\n", 1, WVOL_ERR_FORMAT, "line skip"},
    {"gzip truncated", H3 "encoding: gzip\n\n", 5, WVOL_ERR_FORMAT, "truncated"},
    {"gzip corrupt", H3 "encoding: gzip\n\n", 6, WVOL_ERR_FORMAT, "gzip"},
    {"gzip data long", H3 "encoding: gzip\n\n", 7, WVOL_ERR_FORMAT, "too long"},
    {"gzip trailing junk", H3 "encoding: gzip\n\n", 8, WVOL_ERR_FORMAT, "after the end"},
    {"gzip of nothing", H3 "encoding: gzip\n\n", 0, WVOL_ERR_FORMAT, "truncated"},
    {"NaN sample", H3 "encoding: raw\n\n", 9, WVOL_ERR_NONFINITE, "NaN"},
    {"ascii short", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 10, WVOL_ERR_FORMAT,
     "truncated"},
    {"ascii long", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 11, WVOL_ERR_FORMAT,
     "too long"},
    {"ascii junk", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 12, WVOL_ERR_FORMAT,
     "not a number"},
    /* a text value the declared type cannot hold is malformed, as a binary file cannot hold it */
    {"ascii uchar 300", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 13,
     WVOL_ERR_FORMAT, "value 3 '300' is outside the range of type 'uchar' (0 to 255)"},
    {"ascii ushort -1", "NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 14,
     WVOL_ERR_FORMAT, "value 2 '-1' is outside the range of type 'ushort' (0 to 65535)"},
    {"ascii float 1e40", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 15,
     WVOL_ERR_FORMAT, "value 6 '1e40' is outside the range of type 'float'"},
    {"ascii int 2.5", "NRRD0004\ntype: int\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n", 16,
     WVOL_ERR_FORMAT, "value 2 '2.5' is not an integer (type 'int')"},
};

static void malformed_headers_refused(void)
{
    float d9[9] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
    size_t c;
    for (c = 0; c < sizeof bad_cases / sizeof bad_cases[0]; c++) {
        const bad_case *b = &bad_cases[c];
        unsigned char *gz = NULL, junk[600];
        size_t gzn = 0;
        const void *data = NULL;
        size_t n = 0;
        wvol_volume *v = (wvol_volume *)&gzn; /* must come back NULL */
        wvol_error err;
        wvol_status s;
        char path[64];
        snprintf(path, sizeof path, DIR_ "/bad%02zu.nrrd", c);
        switch (b->data) {
        case 1: data = d9, n = 32; break;
        case 2: data = d9, n = 28; break;
        case 3: data = d9, n = 36; break;
        case 4: case 5: case 6: case 8:
            gz = gzip_bytes(d9, 32, &gzn);
            data = gz, n = gzn;
            if (b->data == 5) n = gzn - 10;
            if (b->data == 6) gz[gzn / 2] ^= 0x5a, gz[gzn / 2 + 1] ^= 0xff;
            if (b->data == 8) {
                memcpy(junk, gz, gzn);
                memcpy(junk + gzn, "JUNK", 4);
                data = junk, n = gzn + 4;
            }
            break;
        case 7: gz = gzip_bytes(d9, 36, &gzn); data = gz, n = gzn; break;
        case 9: d9[3] = NAN; data = d9, n = 32; break;
        case 10: data = "1 2 3 4 5 6 7", n = 13; break;
        case 11: data = "1 2 3 4 5 6 7 8 9", n = 17; break;
        case 12: data = "1 2 3 four 5 6 7 8", n = 18; break;
        case 13: data = "1 2 300 4 5 6 7 8", n = 17; break;
        case 14: data = "1 -1 3 4 5 6 7 8", n = 16; break;
        case 15: data = "1 2 3 4 5 1e40 7 8", n = 18; break;
        case 16: data = "1 2.5 3 4 5 6 7 8", n = 17; break;
        }
        write_file(path, b->header, strlen(b->header), data, n);
        d9[3] = 4;
        s = wvol_nrrd_read(&v, path, &err);
        CHECK(s == b->status, "%s: status %d (%s), want %d", b->what, (int)s, err.message, (int)b->status);
        CHECK(v == NULL, "%s: no volume on failure", b->what);
        CHECK(s == WVOL_OK || (strstr(err.message, b->needle) && strstr(err.message, path)),
              "%s: message '%s' should name the file and say '%s'", b->what, err.message, b->needle);
        free(gz);
    }
}

static void long_and_binary_header_lines_refused(void)
{
    char *text = malloc(80000);
    wvol_volume *v;
    wvol_error err;
    memcpy(text, "NRRD0004\n# ", 11);
    memset(text + 11, 'x', 70000);
    strcpy(text + 70011, "\ntype: float\n\n");
    v = read_text("longline.nrrd", text, NULL, 0, &err);
    CHECK(!v && strstr(err.message, "longer than"), "long header line: %s", err.message);
    v = read_text("nul.nrrd", "NRRD0004\ntype: fl", "\0at\n\n", 5, &err);
    CHECK(!v && strstr(err.message, "NUL"), "NUL in header: %s", err.message);
    free(text);
}

/* Flipped, dropped and inserted bytes in valid files: every result is either a
 * clean refusal with a message or a volume of the declared size (the sanitizer
 * build turns any out-of-bounds access into a failure). */
static void mutations_never_crash(void)
{
    static const char *hdrs[2] = {"NRRD0004\ntype: short\ndimension: 3\nsizes: 4 3 2\nspace: LPS\n"
                                  "space directions: (1,0,0) (0,2,0) (0,0,3)\nspace origin: (1,2,3)\n"
                                  "endian: big\nencoding: raw\n\n",
                                  "NRRD0004\ntype: float\ndimension: 3\nsizes: 4 3 2\nspacings: 1 2 3\n"
                                  "endian: little\nencoding: gzip\n\n"};
    unsigned char base[2][2048], buf[2100];
    size_t blen[2], gzn;
    float f[24];
    int i, k, refused = 0, accepted = 0;
    unsigned char *gz;
    wvol_rng r;
    for (i = 0; i < 24; i++) f[i] = (float)i;
    blen[0] = strlen(hdrs[0]);
    memcpy(base[0], hdrs[0], blen[0]);
    memcpy(base[0] + blen[0], f, 48);
    blen[0] += 48;
    gz = gzip_bytes(f, 96, &gzn);
    blen[1] = strlen(hdrs[1]);
    memcpy(base[1], hdrs[1], blen[1]);
    memcpy(base[1] + blen[1], gz, gzn);
    blen[1] += gzn;
    free(gz);
    wvol_rng_seed(&r, 2024);
    for (i = 0; i < 3000; i++) {
        int which = i & 1, edits = 1 + (int)(wvol_rng_next(&r) % 4);
        size_t n = blen[which];
        wvol_volume *v = NULL;
        wvol_error err;
        memcpy(buf, base[which], n);
        for (k = 0; k < edits; k++) {
            size_t at = (size_t)(wvol_rng_next(&r) % n);
            switch (wvol_rng_next(&r) % 4) {
            case 0: buf[at] = (unsigned char)wvol_rng_next(&r); break;
            case 1: buf[at] ^= (unsigned char)(1u << (wvol_rng_next(&r) % 8)); break;
            case 2: if (n > 1) { memmove(buf + at, buf + at + 1, n - at - 1); n--; } break;
            case 3: if (n < sizeof buf) { memmove(buf + at + 1, buf + at, n - at); buf[at] = "0 \n:(,-9"[wvol_rng_next(&r) % 8]; n++; } break;
            }
        }
        if (wvol_rng_next(&r) % 5 == 0) n = (size_t)(wvol_rng_next(&r) % n);
        write_file(DIR_ "/mut.nrrd", buf, n, NULL, 0);
        if (wvol_nrrd_read(&v, DIR_ "/mut.nrrd", &err) == WVOL_OK) {
            accepted++;
            CHECK(v && wvol_volume_count(v) >= 1 && wvol_volume_count(v) <= 1000000, "accepted mutant has a sane size");
            wvol_volume_destroy(v);
        } else {
            refused++;
            CHECK(v == NULL && err.message[0], "refused mutant %d has a message", i);
        }
    }
    CHECK(refused > 1000, "most mutants are refused (%d refused, %d accepted)", refused, accepted);
}

/* ---- writer failures -------------------------------------------------------- */

static void writer_leaves_nothing_on_failure(void)
{
    wvol_volume *v = test_volume(4, 4, 4);
    wvol_error err;
    struct stat st;
    mode_t old;
    mkdir(DIR_ "/w", 0777);
    CHECK(wvol_nrrd_write(v, DIR_ "/w/missing/x.nrrd", &err) == WVOL_ERR_IO, "unwritable folder: %s", err.message);
    CHECK(strstr(err.message, "x.nrrd") != NULL, "message names the file: %s", err.message);
    /* a folder where the header should go: the data file is written first, then
     * renaming the header fails, and the data file must go too */
    mkdir(DIR_ "/w/h.nhdr", 0777);
    CHECK(wvol_nrrd_write(v, DIR_ "/w/h.nhdr", &err) == WVOL_ERR_IO, "header path is a folder: %s", err.message);
    CHECK(access(DIR_ "/w/h.raw", F_OK) != 0, "no orphan data file");
    CHECK(count_dir_entries(DIR_ "/w") == 1, "only the folder remains (%d entries)", count_dir_entries(DIR_ "/w"));
    rmdir(DIR_ "/w/h.nhdr");
    CHECK(wvol_nrrd_write_gzip(v, DIR_ "/w/x.nrrd", 10, &err) == WVOL_ERR_ARG, "gzip level 10 refused");
    CHECK(count_dir_entries(DIR_ "/w") == 0, "nothing written");
    /* NaN samples and a spacing or origin the readers would refuse are not written */
    {
        wvol_slab_writer *sw = NULL;
        const size_t dims[3] = {4, 4, 4};
        const double sp[3] = {1, 1, 1}, org[3] = {0, 0, 0}, bad_sp[3] = {1, NAN, 1}, zero_sp[3] = {1, 1, 0},
                     neg_sp[3] = {-1, 1, 1}, inf_org[3] = {0, INFINITY, 0};
        CHECK(wvol_slab_writer_open(&sw, DIR_ "/w/g.nrrd", dims, bad_sp, org, 0, &err) == WVOL_ERR_ARG && !sw &&
                  strstr(err.message, "spacing"),
              "NaN spacing: %s", err.message);
        CHECK(wvol_slab_writer_open(&sw, DIR_ "/w/g.nrrd", dims, zero_sp, org, 0, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "spacing"),
              "zero spacing: %s", err.message);
        CHECK(wvol_slab_writer_open(&sw, DIR_ "/w/g.raw", dims, neg_sp, org, 0, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "spacing"),
              "negative spacing: %s", err.message);
        CHECK(wvol_slab_writer_open(&sw, DIR_ "/w/g.nrrd", dims, sp, inf_org, 0, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "origin"),
              "infinite origin: %s", err.message);
        CHECK(count_dir_entries(DIR_ "/w") == 0, "nothing written for a bad geometry");
        CHECK(wvol_slab_writer_open(&sw, DIR_ "/w/g.nrrd", dims, sp, org, 0, &err) == WVOL_OK, "%s", err.message);
        if (sw) {
            float slab[16] = {0};
            CHECK(wvol_slab_writer_put(sw, slab, 1, &err) == WVOL_OK, "%s", err.message);
            slab[7] = NAN; /* written as given, as the whole-volume writers write it */
            CHECK(wvol_slab_writer_put(sw, slab, 1, &err) == WVOL_OK, "NaN sample: %s", err.message);
            wvol_slab_writer_abort(sw);
        }
        CHECK(count_dir_entries(DIR_ "/w") == 0, "nothing left after the abort");
        v->spacing[2] = 0;
        CHECK(wvol_volume_save(v, DIR_ "/w/s.raw", &err) == WVOL_ERR_ARG && strstr(err.message, "spacing"),
              "save with zero spacing: %s", err.message);
        v->spacing[2] = 1;
        v->origin[0] = -INFINITY;
        CHECK(wvol_volume_save(v, DIR_ "/w/s.nrrd", &err) == WVOL_ERR_ARG && strstr(err.message, "origin"),
              "save with an infinite origin: %s", err.message);
        v->origin[0] = 0;
        CHECK(count_dir_entries(DIR_ "/w") == 0, "nothing saved");
    }
    /* written files get the usual mode (0666 less the umask), not mkstemp's 0600, and the
     * library never sets the umask (reading it means setting it: racy with other threads;
     * /proc reads it without) */
    old = umask(022);
    CHECK(wvol_nrrd_write(v, DIR_ "/w/mode.nrrd", &err) == WVOL_OK, "%s", err.message);
    CHECK(stat(DIR_ "/w/mode.nrrd", &st) == 0 && (st.st_mode & 0777) == 0644, "mode %o", (unsigned)(st.st_mode & 0777));
    umask(027);
    CHECK(wvol_nrrd_write(v, DIR_ "/w/mode.nrrd", &err) == WVOL_OK && proc_umask() == 027, "%s, umask %o",
          err.message, proc_umask());
    CHECK(remove(DIR_ "/w/mode.nrrd") == 0 && wvol_nrrd_write(v, DIR_ "/w/mode.nrrd", &err) == WVOL_OK &&
              stat(DIR_ "/w/mode.nrrd", &st) == 0 && (st.st_mode & 0777) == 0640,
          "umask 027: mode %o", (unsigned)(st.st_mode & 0777));
    umask(old);
    wvol_volume_destroy(v);
}

/* A detached header whose write fails (a file size limit the header crosses and its 2x2x2
 * data does not) keeps the old pair: the data must not replace the old data file before the
 * header is known to be written (else a failed header leaves the old one naming no data). */
static void detached_pair_kept_when_the_header_fails(void)
{
    wvol_volume *v = test_volume(2, 2, 2);
    pid_t pid;
    int status = 0;
    mkdir(DIR_ "/pair", 0777);
    clean_dir(DIR_ "/pair");
    fflush(NULL);
    pid = fork();
    if (pid == 0) {
        struct rlimit lim = {100, 100};
        wvol_error err;
        char buf[64] = {0};
        FILE *fp;
        int bad = 0;
        if (!v) _exit(64);
        for (int k = 0; k < 2; k++) {
            fp = fopen(k ? DIR_ "/pair/d.raw" : DIR_ "/pair/d.nhdr", "w");
            if (!fp || fputs(k ? "old data" : "old header", fp) == EOF || fclose(fp) != 0) _exit(65);
        }
        signal(SIGXFSZ, SIG_IGN);
        if (setrlimit(RLIMIT_FSIZE, &lim) != 0) _exit(66);
        if (wvol_nrrd_write(v, DIR_ "/pair/d.nhdr", &err) != WVOL_ERR_IO) bad |= 1;
        else if (!strstr(err.message, "d.nhdr") || !strstr(err.message, strerror(EFBIG))) bad |= 2;
        fp = fopen(DIR_ "/pair/d.raw", "r");
        if (!fp || !fgets(buf, sizeof buf, fp) || strcmp(buf, "old data") != 0) bad |= 4;
        if (fp) fclose(fp);
        fp = fopen(DIR_ "/pair/d.nhdr", "r");
        if (!fp || !fgets(buf, sizeof buf, fp) || strcmp(buf, "old header") != 0) bad |= 8;
        if (fp) fclose(fp);
        _exit(bad);
    }
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0,
          "detached write failing in its header: status %d (1: not an I/O error, 2: message without the file or "
          "cause, 4: old data replaced, 8: old header replaced)",
          WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    CHECK(count_dir_entries(DIR_ "/pair") == 2, "the old pair alone (no temporaries)");
    clean_dir(DIR_ "/pair");
    rmdir(DIR_ "/pair");
    wvol_volume_destroy(v);
}

int main(void)
{
    mkdir(DIR_, 0777);
    clean_dir(DIR_ "/sub");
    clean_dir(DIR_ "/w");
    clean_dir(DIR_);
    round_trips_both_header_kinds();
    every_type_and_byte_order();
    header_variants_accepted();
    malformed_headers_refused();
    long_and_binary_header_lines_refused();
    mutations_never_crash();
    writer_leaves_nothing_on_failure();
    detached_pair_kept_when_the_header_fails();
    return check_summary("test_nrrd");
}
