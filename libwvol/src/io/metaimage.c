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

wvol_status wvol__meta_read_header(wvol__meta_header *h, const char *path, wvol_error *err)
{
    FILE *fp;
    char *line = NULL;
    size_t cap = 0;
    ssize_t got;
    int lines = 0, have_dims = 0, have_data_file = 0;
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
        else if (KEY("DimSize")) have_dims = 1;
        else if (KEY("ElementDataFile")) {
            size_t i = (size_t)(val - line);
            while (i < n && blank(line[i])) i++;
            have_data_file = i < n;
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
    return WVOL_OK;
}

double wvol__meta_precise(double vtk_value, const double *hdr, size_t n, size_t i)
{
    double v;
    if (i >= n || i >= WVOL__META_MAX_NUMBERS) return vtk_value;
    v = hdr[i];
    return fabs((double)(float)v - vtk_value) <= 1e-6 * fabs(v) + 1e-300 ? v : vtk_value;
}
