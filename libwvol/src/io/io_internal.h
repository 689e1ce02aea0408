/* SPDX-License-Identifier: MIT
 * What the io module's files share with each other and with the C++ adapters (not
 * installed): the axis-flipping geometry every image reader applies, the number
 * syntax of text headers, the DICOM series reader, the MetaImage header check and the
 * raw file source. */
#ifndef WVOL_IO_INTERNAL_H
#define WVOL_IO_INTERNAL_H

#include <stddef.h>

#include "wvol/io.h"
#include "wvol/source.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Sets v's spacing and origin from an image's geometry: origin = world position of
 * the first sample as stored, spacing per axis (may be negative: the axis runs
 * backwards), dir the direction matrix (rows: world axes). Axes whose direction is
 * -1 (or whose spacing is negative) are reversed in place so that the spacing is
 * positive, also when a rotation of the other axes comes with it; any other rotation is
 * dropped. Fails as wvol_volume_set_geometry does. */
wvol_status wvol__io_apply_geometry(wvol_volume *v, const double origin[3], const double spacing[3],
                                    const double dir[3][3], wvol_error *err);
/* The axes wvol__io_apply_geometry reverses for this spacing and direction: bit a for axis a. */
int wvol__io_reversed_axes(const double spacing[3], const double dir[3][3]);

/* A raw file as a volume source (wvol/source.h), whatever its name: the dimensions, sample
 * type, byte order and geometry from opt, the file's length checked against them
 * (io/source_file.c); wvol_raw_read reads the whole volume through it. */
wvol_status wvol__source_open_raw(wvol_source **out, const char *path, const wvol_load_options *opt,
                                  wvol_error *err);

/* Numbers of a text header, as C++'s `istream >> double` reads them one after the
 * other: whitespace, then [+-]digits[.digits][e[+-]digits]; stops at the first text
 * that is not such a number, or that overflows. Stores at most cap values in out;
 * returns how many numbers were read (possibly more than cap). */
size_t wvol__io_parse_numbers(const char *s, double *out, size_t cap);

/* A folder holding one DICOM series (uncompressed little-endian grayscale Part 10
 * files, one slice each): stacked along the slice normal, RescaleSlope/Intercept
 * applied. Other files in the folder are ignored. */
/* The file an output written to `path` replaces (by a temporary beside it, renamed over it):
 * path itself, or, when path is a symbolic link, the regular file it names, so that the link
 * stays a link; *final is malloc'ed. Refused (WVOL_ERR_IO, nothing touched): an existing path
 * that is not a regular file (a device, a FIFO, a folder), whose rename would replace it, and
 * a link to nothing. */
wvol_status wvol__output_path(char **final, const char *path, wvol_error *err);

/* Creates and opens (write only, close-on-exec) a new file named by tmpl, whose six 'X'
 * characters before its last suffix_len characters are replaced by random ones until the name
 * is new, with the mode a plain fopen gives (0666 less the umask, which the kernel applies:
 * mkstemp's 0600 would need the umask read, and reading it sets it, which races with other
 * threads). Returns the descriptor, or -1 with errno set. */
int wvol__create_temp(char *tmpl, size_t suffix_len);
/* A temporary from wvol__create_temp was renamed into place or removed: it is no longer one that
 * wvol_atomic_remove_pending removes. */
void wvol__temp_done(const char *path);

/* WVOL_ERR_UNSUPPORTED "PATH: sample INDEX holds the integer VALUE, which float32 cannot hold
 * exactly ...; refused": the readers' one message for integers above 2^24 that would be rounded. */
wvol_status wvol__inexact_integer(const char *path, unsigned long long index, const char *value, wvol_error *err);

/* WVOL_ERR_IO "PATH: write failed: CAUSE", the cause from errno as a failed write left it. */
wvol_status wvol__write_failed(const char *path, wvol_error *err);

/* A header's detached data file (NRRD "data file:", MetaImage ElementDataFile): data_file
 * itself when absolute, else relative to the header's folder (malloc'ed; NULL when out of
 * memory). */
char *wvol__io_data_path_of(const char *header_path, const char *data_file);

wvol_status wvol__dicom_read(wvol_volume **out, const char *dir, wvol_error *err);

/* The fields of a MetaImage header (.mha/.mhd) the VTK adapter checks or takes at
 * full precision (VTK's MetaIO keeps spacing as float). Counts are of the numbers
 * given; at most WVOL__META_MAX_NUMBERS are kept. */
#define WVOL__META_MAX_NUMBERS 16
typedef struct wvol__meta_header {
    int ndims;
    int channels;
    size_t nspacing, norigin, nmatrix;
    double spacing[WVOL__META_MAX_NUMBERS], origin[WVOL__META_MAX_NUMBERS], matrix[WVOL__META_MAX_NUMBERS];
} wvol__meta_header;

/* Reads and checks the header (first 200 lines, up to ElementDataFile): refuses what
 * is not a 'Key = Value' header, lacks NDims, DimSize or ElementDataFile, has more
 * than 3 dimensions or more than one channel. */
wvol_status wvol__meta_read_header(wvol__meta_header *h, const char *path, wvol_error *err);

/* VTK's value (float precision) of header number i, or the header's own text of it
 * when that is the same magnitude more precisely (its sign kept: a negative spacing). */
double wvol__meta_precise(double vtk_value, const double *hdr, size_t n, size_t i);

#ifdef __cplusplus
}
#endif
#endif
