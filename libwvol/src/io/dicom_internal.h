/* SPDX-License-Identifier: MIT
 * The DICOM reader's two halves (not installed): dicom_file.c reads the elements of
 * one Part 10 file into a dicom_info, dicom.c checks, orders and stacks a folder's. */
#ifndef WVOL_IO_DICOM_INTERNAL_H
#define WVOL_IO_DICOM_INTERNAL_H

#include <stddef.h>

#include "wvol/status.h"

#define WVOL__DICOM_IMPLICIT_LE "1.2.840.10008.1.2"
#define WVOL__DICOM_EXPLICIT_LE "1.2.840.10008.1.2.1"

typedef struct dicom_info {
    char *file, *series, *syntax; /* malloc'ed; series and syntax NULL until read */
    int rows, cols, bits, bits_stored, signed_pixels, samples, frames, instance;
    size_t pixel_offset, pixel_bytes;
    int has_pixels, encapsulated, has_ipp, has_iop, has_spacing;
    double ipp[3], iop[6], pixel_spacing[2];
    double slope, inter, thickness, between;
} dicom_info;

/* Defaults before a file is read (one sample, one frame, identity orientation,
 * spacing 1, slope 1), and the strings freed. */
void wvol__dicom_info_init(dicom_info *s);
void wvol__dicom_info_free(dicom_info *s);

/* Reads the elements of the file in b[0, n) into info (info->file names it in
 * messages): 1 if it is a DICOM Part 10 file (read up to its pixel data), 0 if not,
 * -1 if it is malformed (err set, WVOL_ERR_FORMAT), -2 when out of memory. */
int wvol__dicom_parse_file(dicom_info *info, const unsigned char *b, size_t n, wvol_error *err);

#endif
