/* SPDX-License-Identifier: MIT
 * MetaImage (.mha/.mhd) header check: the VTK adapter reads the samples with
 * vtkMetaImageReader, which takes what is not a MetaImage header for one and keeps
 * spacing and origin as float; this reads the header first, refuses what is not one,
 * and keeps the numbers VTK rounds at full precision.
 * Based on: the MetaIO documentation (itk.org, "MetaIO"), the header's keys. */
#define _POSIX_C_SOURCE 200809L
#include "core/file_open.h"
#include "core/status_internal.h"
#include "io/io_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char *known_keys[] = {"ObjectType", "ObjectSubType", "NDims", "Comment", "TransformType",
                                   "Name", "ID", "ParentID", "CompressedData", "CompressedDataSize",
                                   "BinaryData", "BinaryDataByteOrderMSB", "ElementByteOrderMSB", "Color",
                                   "Position", "Offset", "Origin", "Orientation", "Rotation",
                                   "TransformMatrix", "CenterOfRotation", "AnatomicalOrientation",
                                   "ElementSpacing", "ElementSize", "DimSize", "HeaderSize",
                                   "Modality", "SequenceID", "ElementMin", "ElementMax",
                                   "ElementNumberOfChannels", "ElementType", "ElementDataFile",
                                   "AcquisitionDate", "FileName", "HeaderSizes", NULL};

static int blank(char c)
{
    return c == ' ' || c == '\t';
}

/* key[0, klen) == name (a key may hold NUL bytes: then it matches nothing) */
static int key_is(const char *key, size_t klen, const char *name)
{
    return strlen(name) == klen && memcmp(key, name, klen) == 0;
}

/* Bytes per sample of a MetaIO ElementType (0: unknown). */
static size_t element_bytes(const char *v)
{
    static const struct {
        const char *name;
        size_t bytes;
    } types[] = {{"MET_CHAR", 1}, {"MET_UCHAR", 1}, {"MET_SHORT", 2}, {"MET_USHORT", 2}, {"MET_INT", 4},
                 {"MET_UINT", 4}, {"MET_LONG", 4}, {"MET_ULONG", 4}, {"MET_LONG_LONG", 8},
                 {"MET_ULONG_LONG", 8}, {"MET_FLOAT", 4}, {"MET_DOUBLE", 8}};
    while (blank(*v)) v++;
    for (size_t i = 0; i < sizeof types / sizeof *types; i++) {
        size_t n = strlen(types[i].name);
        if (strncmp(v, types[i].name, n) == 0 && (v[n] == '\0' || blank(v[n]))) return types[i].bytes;
    }
    return 0;
}

/* deflate expands no stream more than 1032-fold: a compressed image's samples can never need
 * more bytes than that many times what holds them */
#define META_DEFLATE_MAX_RATIO 1032.0

/* The samples the header asks for must fit what the file holds, checked before VTK's reader
 * allocates them (it takes the header's sizes on trust: a 100-byte file could ask for a
 * terabyte). */
static wvol_status check_data_size(const char *path, const double *dims, size_t ndims, size_t elem, int compressed,
                                   double compressed_size, long data_offset, const char *data_file,
                                   wvol_error *err)
{
    double need = (double)elem, have;
    struct stat st;
    for (size_t a = 0; a < ndims; a++) {
        WVOL_RETURN_IF(!(dims[a] >= 1 && dims[a] <= 1048576 && dims[a] == floor(dims[a])), err, WVOL_ERR_FORMAT,
                       "%s: DimSize %g is not a size (an integer in 1..1048576)", path, dims[a]);
        need *= dims[a];
    }
    if (strcmp(data_file, "LOCAL") == 0) {
        WVOL_RETURN_IF(stat(path, &st) != 0, err, WVOL_ERR_IO, "%s: %s", path, strerror(errno));
        have = (double)st.st_size - (double)data_offset;
    } else {
        char *dp;
        WVOL_RETURN_IF(strcmp(data_file, "LIST") == 0 || strchr(data_file, '%'), err, WVOL_ERR_UNSUPPORTED,
                       "%s: ElementDataFile %s (a list of files) is not supported", path, data_file);
        dp = wvol__io_data_path_of(path, data_file);
        WVOL_RETURN_IF(!dp, err, WVOL_ERR_NOMEM, "%s: out of memory", path);
        if (stat(dp, &st) != 0 || !S_ISREG(st.st_mode)) {
            wvol_status r =
                wvol_error_set(err, WVOL_ERR_IO, "%s: data file %s is missing or not a regular file", path, dp);
            free(dp);
            return r;
        }
        free(dp);
        have = (double)st.st_size;
    }
    if (compressed) {
        WVOL_RETURN_IF(compressed_size > have, err, WVOL_ERR_FORMAT,
                       "%s: CompressedDataSize %.0f but only %.0f bytes of data follow the header", path,
                       compressed_size, have);
        WVOL_RETURN_IF(need > META_DEFLATE_MAX_RATIO * have + 1024, err, WVOL_ERR_FORMAT,
                       "%s: the header's %.0f bytes of samples cannot come from %.0f compressed bytes", path, need,
                       have);
    } else {
        WVOL_RETURN_IF(need > have, err, WVOL_ERR_FORMAT,
                       "%s: the header asks for %.0f bytes of samples but only %.0f follow (truncated, or a wrong "
                       "DimSize or ElementType)",
                       path, need, have);
    }
    return WVOL_OK;
}

wvol_status wvol__meta_read_header(wvol__meta_header *h, const char *path, wvol_error *err)
{
    FILE *fp;
    char *line = NULL;
    size_t cap = 0, ndimsize = 0, elem = 0;
    ssize_t got;
    int lines = 0, have_dims = 0, have_data_file = 0, compressed = 0;
    double dims[WVOL__META_MAX_NUMBERS], csize = 0;
    char data_file[1024] = "";
    long data_offset = 0;
    wvol_status s = WVOL_OK;

    memset(h, 0, sizeof *h);
    h->channels = 1;
    WVOL_FORWARD(wvol__fopen_regular(&fp, path, err));
    while (lines < 200 && (got = getline(&line, &cap, fp)) >= 0) {
        size_t n = (size_t)got, eq, ka = 0, kb;
        const char *val;
        int ok;
        lines++;
        if (n > 0 && line[n - 1] == '\n') n--;
        if (n > 0 && line[n - 1] == '\r') n--;
        line[n] = '\0';
        {
            size_t i = 0;
            while (i < n && blank(line[i])) i++;
            if (i == n) continue; /* blank line */
        }
        for (eq = 0; eq < n && line[eq] != '='; eq++) {
        }
        /* the key: the text before '=' (the whole line without one), blanks trimmed */
        kb = eq;
        while (kb > 0 && blank(line[kb - 1])) kb--;
        while (ka < kb && blank(line[ka])) ka++;
        ok = eq < n;
        if (ok) {
            ok = 0;
            for (int i = 0; known_keys[i]; i++)
                if (key_is(line + ka, kb - ka, known_keys[i])) ok = 1;
            if (!ok && lines > 1) ok = 1; /* unknown keys are allowed once the header has started */
        }
        if (!ok) {
            s = wvol_error_set(err, WVOL_ERR_FORMAT,
                               "%s: not a MetaImage file (line %d is not a 'Key = Value' header line)", path, lines);
            break;
        }
        val = line + eq + 1;
#define KEY(name) key_is(line + ka, kb - ka, name)
        if (KEY("NDims")) h->ndims = atoi(val);
        else if (KEY("ElementSpacing")) h->nspacing = wvol__io_parse_numbers(val, h->spacing, WVOL__META_MAX_NUMBERS);
        else if (KEY("ElementSize") && h->nspacing == 0)
            h->nspacing = wvol__io_parse_numbers(val, h->spacing, WVOL__META_MAX_NUMBERS);
        else if (KEY("Offset") || KEY("Origin") || KEY("Position"))
            h->norigin = wvol__io_parse_numbers(val, h->origin, WVOL__META_MAX_NUMBERS);
        else if (KEY("TransformMatrix") || KEY("Rotation") || KEY("Orientation"))
            h->nmatrix = wvol__io_parse_numbers(val, h->matrix, WVOL__META_MAX_NUMBERS);
        else if (KEY("ElementNumberOfChannels")) h->channels = atoi(val);
        else if (KEY("DimSize")) {
            have_dims = 1;
            ndimsize = wvol__io_parse_numbers(val, dims, WVOL__META_MAX_NUMBERS);
        } else if (KEY("ElementType")) elem = element_bytes(val);
        else if (KEY("CompressedData")) {
            while (blank(*val)) val++;
            compressed = strncmp(val, "True", 4) == 0 || strncmp(val, "true", 4) == 0;
        } else if (KEY("CompressedDataSize")) csize = atof(val);
        else if (KEY("ElementDataFile")) {
            size_t i = (size_t)(val - line), e = n;
            while (i < n && blank(line[i])) i++;
            while (e > i && blank(line[e - 1])) e--;
            have_data_file = i < n;
            if (e - i < sizeof data_file) memcpy(data_file, line + i, e - i), data_file[e - i] = '\0';
            data_offset = ftell(fp);
            break;
        }
#undef KEY
    }
    free(line);
    fclose(fp);
    if (s) return s;
    if (h->ndims < 1 || !have_dims || !have_data_file)
        return wvol_error_set(err, WVOL_ERR_FORMAT,
                              "%s: not a MetaImage file (NDims, DimSize or ElementDataFile missing)", path);
    if (h->ndims > 3)
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: %d-D MetaImage; only 2-D and 3-D images are supported",
                              path, h->ndims);
    if (h->channels != 1)
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                              "%s: %d channels per voxel; only scalar volumes are supported", path, h->channels);
    WVOL_RETURN_IF(ndimsize != (size_t)h->ndims, err, WVOL_ERR_FORMAT, "%s: DimSize has %zu numbers for NDims = %d",
                   path, ndimsize, h->ndims);
    WVOL_RETURN_IF(!elem, err, WVOL_ERR_FORMAT, "%s: ElementType missing or not a MetaIO type (MET_UCHAR ... MET_DOUBLE)",
                   path);
    WVOL_RETURN_IF(!data_file[0], err, WVOL_ERR_FORMAT, "%s: ElementDataFile name too long", path);
    return check_data_size(path, dims, ndimsize, elem, compressed, csize, data_offset, data_file, err);
}

double wvol__meta_precise(double vtk_value, const double *hdr, size_t n, size_t i)
{
    double v;
    if (i >= n || i >= WVOL__META_MAX_NUMBERS) return vtk_value;
    v = hdr[i];
    /* by magnitude: VTK's MetaIO returns a negative ElementSpacing as positive, and the header's
     * sign is what says the axis runs backwards (the reader then reverses it) */
    return fabs((double)(float)fabs(v) - fabs(vtk_value)) <= 1e-6 * fabs(v) + 1e-300 ? v : vtk_value;
}
