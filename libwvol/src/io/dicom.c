/* SPDX-License-Identifier: MIT
 * DICOM series reader: a folder of Part 10 files (each read by dicom_file.c), one
 * grayscale slice each, uncompressed little-endian (implicit or explicit VR), stacked
 * along the slice normal. Files without the DICM preamble or without pixel data are ignored; one
 * series per folder. RescaleSlope/Intercept are applied in double and rounded to
 * float32 (not as vtkDICOMImageReader in VTK 9.1, which rescales in the stored
 * integer type, so 30000 * 4 wraps, reads a signed slice with a fractional slope as
 * unsigned, and stores rows bottom-up). The patient orientation's flips are applied (rows or
 * columns running against a patient axis are reversed), its rotations dropped, as for every
 * format (docs/formats.md, "Geometry").
 * Based on: DICOM PS3.5 (data elements, transfer syntaxes) and PS3.10 (file format). */
#define _POSIX_C_SOURCE 200809L
#include "core/file_open.h"
#include "core/status_internal.h"
#include "io/dicom_internal.h"
#include "io/io_internal.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char *or_empty(const char *s)
{
    return s ? s : "";
}

static const char *base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

/* ---- the folder ------------------------------------------------------------------ */

/* The whole file; NULL with *missing set when it cannot be opened, else NULL: no memory. */
static unsigned char *read_file(const char *path, size_t *size, int *missing)
{
    FILE *fp;
    size_t cap = 1 << 16, n = 0, got;
    unsigned char *b;
    *missing = 0;
    if (wvol__fopen_regular(&fp, path, NULL) != WVOL_OK) {
        *missing = 1;
        return NULL;
    }
    b = malloc(cap);
    while (b && (got = fread(b + n, 1, cap - n, fp)) > 0) {
        n += got;
        if (n == cap) {
            unsigned char *nb = cap > SIZE_MAX / 2 ? NULL : realloc(b, cap * 2);
            if (!nb) free(b);
            b = nb;
            cap *= 2;
        }
    }
    fclose(fp);
    *size = n;
    return b;
}

/* The pixels of one uncompressed little-endian slice, rows top to bottom, rescaled. */
static wvol_status slice_pixels(const dicom_info *s, const unsigned char *b, size_t size, float *dst, size_t n,
                                wvol_error *err)
{
    const size_t bytes_per = (size_t)s->bits / 8;
    const int stored = s->bits_stored > 0 && s->bits_stored < s->bits ? s->bits_stored : s->bits;
    const int plain = s->slope == 1.0 && s->inter == 0.0;
    const unsigned char *p = b + s->pixel_offset;
    if (s->bits != 8 && s->bits != 16 && s->bits != 32)
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: %d-bit DICOM pixels are not supported (8, 16, 32)",
                              s->file, s->bits);
    if (s->pixel_offset > size || s->pixel_bytes < n * bytes_per || size - s->pixel_offset < n * bytes_per)
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: DICOM pixel data is shorter than %d x %d pixels of %d bits",
                              s->file, s->cols, s->rows, s->bits);
    for (size_t i = 0; i < n; i++, p += bytes_per) {
        uint32_t u = p[0];
        int64_t x;
        float f;
        if (bytes_per >= 2) u |= (uint32_t)p[1] << 8;
        if (bytes_per == 4) u |= ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
        if (stored < 32) u &= ((uint32_t)1 << stored) - 1; /* bits above BitsStored are not the pixel's */
        x = (int64_t)u;
        if (s->signed_pixels && ((u >> (stored - 1)) & 1u)) x -= (int64_t)1 << stored;
        f = (float)x;
        if (plain && (int64_t)f != x)
            return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                                  "%s: pixel value %lld cannot be held exactly by float32; refused", s->file,
                                  (long long)x);
        dst[i] = plain ? f : (float)((double)x * s->slope + s->inter);
    }
    return WVOL_OK;
}

static int cmp_names(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Stable orders: by position along the normal, or by instance number. */
typedef struct order_item {
    double key;
    int instance;
    size_t index;
    dicom_info *s;
} order_item;

static int cmp_key(const void *pa, const void *pb)
{
    const order_item *a = pa, *b = pb;
    if (a->key < b->key) return -1;
    if (b->key < a->key) return 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

static int cmp_instance(const void *pa, const void *pb)
{
    const order_item *a = pa, *b = pb;
    if (a->instance != b->instance) return a->instance < b->instance ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

typedef struct series_count {
    const char *uid;
    size_t files;
} series_count;

static int cmp_series(const void *a, const void *b)
{
    return strcmp(((const series_count *)a)->uid, ((const series_count *)b)->uid);
}

/* "uid (n files), ..." in uid order, or NULL when out of memory. */
static char *series_list(const dicom_info *slices, size_t n, size_t *distinct)
{
    series_count *c = calloc(n, sizeof *c);
    size_t k = 0, len = 1;
    char *out;
    if (!c) return NULL;
    for (size_t i = 0; i < n; i++) {
        size_t j;
        for (j = 0; j < k && strcmp(c[j].uid, or_empty(slices[i].series)) != 0; j++) {
        }
        if (j == k) c[k++].uid = or_empty(slices[i].series);
        c[j].files++;
    }
    qsort(c, k, sizeof *c, cmp_series);
    for (size_t j = 0; j < k; j++) len += strlen(c[j].uid) + 48;
    out = malloc(len);
    if (out) {
        size_t at = 0;
        for (size_t j = 0; j < k; j++)
            at += (size_t)snprintf(out + at, len - at, "%s%s (%zu files)", j ? ", " : "",
                                   c[j].uid[0] ? c[j].uid : "(none)", c[j].files);
        out[at] = '\0';
    }
    *distinct = k;
    free(c);
    return out;
}

/* The slice normal: the row direction x the column direction (ImageOrientationPatient). */
static void slice_normal(const dicom_info *s, double n[3])
{
    const double *r = s->iop, *c = s->iop + 3;
    n[0] = r[1] * c[2] - r[2] * c[1], n[1] = r[2] * c[0] - r[0] * c[2], n[2] = r[0] * c[1] - r[1] * c[0];
}

static double key_of(const dicom_info *s, const double normal[3])
{
    return s->ipp[0] * normal[0] + s->ipp[1] * normal[1] + s->ipp[2] * normal[2];
}

/* Checks the slices against the first (in name order) and orders them; sets the
 * slice spacing. */
static wvol_status check_and_order(const char *dir, dicom_info *slices, size_t ns, order_item *ord, double *dz,
                                   wvol_error *err)
{
    const dicom_info *s0 = &slices[0];
    double normal[3];
    int all_ipp = 1;
    slice_normal(s0, normal);
    for (size_t i = 0; i < ns; i++) {
        const dicom_info *s = &slices[i];
        if (s->encapsulated || (strcmp(s->syntax, WVOL__DICOM_IMPLICIT_LE) && strcmp(s->syntax, WVOL__DICOM_EXPLICIT_LE)))
            return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                                  "%s: DICOM transfer syntax %s (compressed or big-endian) is not supported; only "
                                  "uncompressed little-endian",
                                  s->file, s->syntax);
        if (s->samples != 1)
            return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                                  "%s: %d samples per pixel (color); only grayscale images are supported", s->file,
                                  s->samples);
        if (s->frames > 1)
            return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: multi-frame DICOM (%d frames) is not supported",
                                  s->file, s->frames);
        if (s->rows < 1 || s->cols < 1)
            return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: DICOM image without Rows/Columns", s->file);
        if (s->rows != s0->rows || s->cols != s0->cols)
            return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: mixed DICOM series (%s is %d x %d but %s is %d x %d)",
                                  dir, base_name(s0->file), s0->cols, s0->rows, base_name(s->file), s->cols, s->rows);
        if (s->bits != s0->bits)
            return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: mixed DICOM series (%s has %d-bit pixels, %s %d-bit)",
                                  dir, base_name(s0->file), s0->bits, base_name(s->file), s->bits);
        for (int a = 0; a < 2; a++)
            if (fabs(s->pixel_spacing[a] - s0->pixel_spacing[a]) > 1e-6 * fabs(s0->pixel_spacing[a]))
                return wvol_error_set(err, WVOL_ERR_FORMAT,
                                      "%s: mixed DICOM series (PixelSpacing differs between %s and %s)", dir,
                                      base_name(s0->file), base_name(s->file));
        for (int a = 0; a < 6; a++)
            if (fabs(s->iop[a] - s0->iop[a]) > 1e-4)
                return wvol_error_set(err, WVOL_ERR_FORMAT,
                                      "%s: mixed DICOM series (ImageOrientationPatient differs between %s and %s)",
                                      dir, base_name(s0->file), base_name(s->file));
    }

    /* slice order and spacing: positions along the normal, or instance numbers */
    for (size_t i = 0; i < ns; i++) {
        all_ipp = all_ipp && slices[i].has_ipp;
        ord[i].key = key_of(&slices[i], normal);
        ord[i].instance = slices[i].instance;
        ord[i].index = i;
        ord[i].s = &slices[i];
    }
    *dz = s0->between > 0 ? s0->between : s0->thickness > 0 ? s0->thickness : 1.0;
    if (!all_ipp) {
        qsort(ord, ns, sizeof *ord, cmp_instance);
        return WVOL_OK;
    }
    qsort(ord, ns, sizeof *ord, cmp_key);
    if (ns > 1) {
        const double span = ord[ns - 1].key - ord[0].key;
        *dz = span / (double)(ns - 1);
        for (size_t i = 1; i < ns; i++) {
            const double gap = ord[i].key - ord[i - 1].key;
            if (fabs(gap) <= 1e-6 * fabs(span))
                return wvol_error_set(err, WVOL_ERR_FORMAT,
                                      "%s: mixed DICOM series (%s and %s are at the same position; several "
                                      "acquisitions in one folder?)",
                                      dir, base_name(ord[i - 1].s->file), base_name(ord[i].s->file));
            if (fabs(gap - *dz) > 1e-3 * fabs(*dz))
                return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                                      "%s: DICOM slices are not evenly spaced (gap %.10g between %s and %s, %.10g on "
                                      "average)",
                                      dir, gap, base_name(ord[i - 1].s->file), base_name(ord[i].s->file), *dz);
        }
    }
    return WVOL_OK;
}

/* Lists the folder's visible entries in name order. */
static wvol_status list_folder(const char *dir, char ***names, size_t *count, wvol_error *err)
{
    DIR *d = opendir(dir);
    struct dirent *ent;
    size_t n = 0, cap = 0;
    char **v = NULL;
    *names = NULL;
    *count = 0;
    if (!d) return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot list the folder: %s", dir, strerror(errno));
    while ((ent = readdir(d)) != NULL) {
        if (ent->d_name[0] == '.') continue;
        if (n == cap) {
            char **nv = realloc(v, (cap = cap ? 2 * cap : 64) * sizeof *v);
            if (!nv) break;
            v = nv;
        }
        if (!(v[n] = strdup(ent->d_name))) break;
        n++;
    }
    closedir(d);
    if (ent) { /* stopped early: out of memory */
        for (size_t i = 0; i < n; i++) free(v[i]);
        free(v);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
    }
    if (n) qsort(v, n, sizeof *v, cmp_names);
    *names = v;
    *count = n;
    return WVOL_OK;
}

/* Reads every file of the folder's listing; keeps the DICOM images in slices. */
static wvol_status scan_folder(const char *dir, dicom_info **slices_out, size_t *ns_out, wvol_error *err)
{
    char **names = NULL;
    size_t nnames = 0, ns = 0, looked = 0;
    dicom_info *slices = NULL;
    wvol_status s = list_folder(dir, &names, &nnames, err);
    if (s) return s;
    slices = calloc(nnames ? nnames : 1, sizeof *slices);
    if (!slices) s = wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
    for (size_t i = 0; i < nnames && !s; i++) {
        size_t plen = strlen(dir) + strlen(names[i]) + 2, size = 0;
        char *file = malloc(plen);
        struct stat st;
        unsigned char *bytes;
        int missing, r;
        if (!file) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
            break;
        }
        snprintf(file, plen, "%s/%s", dir, names[i]);
        if (stat(file, &st) != 0 || !S_ISREG(st.st_mode)) {
            free(file);
            continue;
        }
        looked++;
        bytes = read_file(file, &size, &missing);
        if (!bytes) {
            s = missing ? wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open: %s", file, strerror(errno))
                        : wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
            free(file);
            break;
        }
        wvol__dicom_info_init(&slices[ns]);
        slices[ns].file = file;
        r = wvol__dicom_parse_file(&slices[ns], bytes, size, err);
        free(bytes);
        if (r == 1 && slices[ns].has_pixels) {
            ns++; /* a DICOM image */
            continue;
        }
        wvol__dicom_info_free(&slices[ns]); /* not DICOM, or no pixels (DICOMDIR, reports, ...): ignored */
        if (r == -1) s = WVOL_ERR_FORMAT;
        else if (r == -2) s = wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
    }
    for (size_t i = 0; i < nnames; i++) free(names[i]);
    free(names);
    if (!s && ns == 0)
        s = wvol_error_set(err, WVOL_ERR_FORMAT,
                           "%s: no DICOM image files in this folder (%zu file%s looked at; files need the DICM preamble)",
                           dir, looked, looked == 1 ? "" : "s");
    if (s) {
        for (size_t i = 0; i < ns; i++) wvol__dicom_info_free(&slices[i]);
        free(slices);
        return s;
    }
    *slices_out = slices;
    *ns_out = ns;
    return WVOL_OK;
}

static wvol_status read_folder(wvol_volume **out, const char *dir, dicom_info *slices, size_t ns, wvol_error *err)
{
    const dicom_info *s0 = &slices[0];
    order_item *ord = malloc(ns * sizeof *ord);
    size_t distinct = 0, nx, ny;
    char *list;
    double dz = 1, origin[3], spacing[3];
    double axes[3][3];
    wvol_volume *v = NULL;
    wvol_error e;
    wvol_status s;

    if (!ord) return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
    /* one series only */
    list = series_list(slices, ns, &distinct);
    if (!list) {
        free(ord);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
    }
    if (distinct > 1)
        s = wvol_error_set(err, WVOL_ERR_FORMAT,
                           "%s: mixed DICOM series (SeriesInstanceUID %s); put one series per folder", dir, list);
    else
        s = check_and_order(dir, slices, ns, ord, &dz, err);
    free(list);
    if (s) {
        free(ord);
        return s;
    }
    nx = (size_t)s0->cols;
    ny = (size_t)s0->rows;
    wvol_error_clear(&e);
    if (wvol_volume_create(&v, nx, ny, ns, &e) != WVOL_OK) {
        free(ord);
        return wvol_error_set(err, e.status, "%s: %s", dir, e.message);
    }
    for (size_t k = 0; k < ns && !s; k++) {
        const dicom_info *sk = ord[k].s;
        size_t size = 0;
        int missing;
        unsigned char *bytes = read_file(sk->file, &size, &missing);
        if (!bytes) {
            s = missing ? wvol_error_set(err, WVOL_ERR_IO, "%s: read error", sk->file)
                        : wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", dir);
            break;
        }
        s = slice_pixels(sk, bytes, size, v->data + k * nx * ny, nx * ny, err);
        free(bytes);
    }
    if (!s) {
        memcpy(origin, ord[0].s->ipp, sizeof origin);
        spacing[0] = s0->pixel_spacing[1]; /* PixelSpacing is row spacing (y) \ column spacing (x) */
        spacing[1] = s0->pixel_spacing[0];
        spacing[2] = dz;
        {
            /* columns: the axes' directions, x along a row (ImageOrientationPatient's first
             * triple), y down the columns (its second), z the normal the slices are ordered along */
            double n[3];
            slice_normal(s0, n);
            for (int a = 0; a < 3; a++) axes[a][0] = s0->iop[a], axes[a][1] = s0->iop[3 + a], axes[a][2] = n[a];
        }
        if (wvol__io_apply_geometry(v, origin, spacing, axes, &e) != WVOL_OK)
            s = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: %s", dir, e.message);
    }
    if (!s && wvol_check_finite(v->data, nx, ny, ns, dir, &e) != WVOL_OK)
        s = wvol_error_set(err, e.status, "%s", e.message);
    free(ord);
    if (s) {
        wvol_volume_destroy(v);
        return s;
    }
    *out = v;
    return WVOL_OK;
}

wvol_status wvol__dicom_read(wvol_volume **out, const char *dir, wvol_error *err)
{
    dicom_info *slices = NULL;
    size_t ns = 0;
    wvol_status s;
    WVOL_RETURN_IF(!out || !dir, err, WVOL_ERR_ARG, "DICOM read: NULL argument");
    *out = NULL;
    s = scan_folder(dir, &slices, &ns, err);
    if (s) return s;
    s = read_folder(out, dir, slices, ns, err);
    for (size_t i = 0; i < ns; i++) wvol__dicom_info_free(&slices[i]);
    free(slices);
    return s;
}
