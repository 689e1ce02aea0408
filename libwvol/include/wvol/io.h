/* SPDX-License-Identifier: MIT */
/* Volume files. The format follows the extension:
 *   .raw        headerless samples; dimensions and sample type from wvol_load_options
 *   .nrrd .nhdr NRRD, attached or detached header, raw or gzip encoding (built in)
 *   .vdb        OpenVDB FloatGrid/DoubleGrid (OpenVDB adapter)
 *   .vti .vtk .mha .mhd .nii .nii.gz, a DICOM folder   (VTK adapter)
 * Writers never leave a partial file: they write a temporary name and rename it. */
#ifndef WVOL_IO_H
#define WVOL_IO_H

#include <stdio.h>
#include "wvol/volume.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum wvol_sample_type {
    WVOL_SAMPLE_TYPE_F32 = 0, WVOL_SAMPLE_TYPE_F64, WVOL_SAMPLE_TYPE_U8, WVOL_SAMPLE_TYPE_I8,
    WVOL_SAMPLE_TYPE_U16, WVOL_SAMPLE_TYPE_I16, WVOL_SAMPLE_TYPE_U32, WVOL_SAMPLE_TYPE_I32
} wvol_sample_type;
/* Deprecated names, removed after 0.1 (docs/conventions.md). */
#define WVOL_F32 WVOL_SAMPLE_TYPE_F32
#define WVOL_F64 WVOL_SAMPLE_TYPE_F64
#define WVOL_U8 WVOL_SAMPLE_TYPE_U8
#define WVOL_I8 WVOL_SAMPLE_TYPE_I8
#define WVOL_U16 WVOL_SAMPLE_TYPE_U16
#define WVOL_I16 WVOL_SAMPLE_TYPE_I16
#define WVOL_U32 WVOL_SAMPLE_TYPE_U32
#define WVOL_I32 WVOL_SAMPLE_TYPE_I32

/* Parses "float32", "f32", "uint8", "int16", ...; returns -1 if unknown. */
WVOL_API int wvol_sample_type_parse(const char *name);
WVOL_API const char *wvol_sample_type_name(wvol_sample_type t);
WVOL_API size_t wvol_sample_type_size(wvol_sample_type t);

typedef struct wvol_load_options {
    size_t dims[3];            /* raw only: required */
    wvol_sample_type raw_type; /* raw only: default float32 */
    int big_endian;            /* raw only: default 0 (little-endian) */
    double spacing[3];         /* raw only: default 1 */
    double origin[3];          /* raw only: default 0 */
    const char *grid_name;     /* .vdb only: NULL = first float grid */
} wvol_load_options;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_load_options_default(wvol_load_options *opt);

/* Loads any supported format (by extension; a directory is read as a DICOM series; a
 * .wvc file is decoded whole and reconstructed).
 * Integer samples become float32 without loss; NaN/Inf are refused. opt may be NULL. */
WVOL_API wvol_status wvol_volume_load(wvol_volume **out, const char *path, const wvol_load_options *opt,
                                      wvol_error *err);

/* Saves to any supported format, by extension. */
WVOL_API wvol_status wvol_volume_save(const wvol_volume *v, const char *path, wvol_error *err);

/* The formats behind the dispatch. */
WVOL_API wvol_status wvol_raw_read(wvol_volume **out, const char *path, const wvol_load_options *opt,
                                   wvol_error *err);
WVOL_API wvol_status wvol_raw_write(const wvol_volume *v, const char *path, wvol_error *err);
/* NRRD (NRRD0001-0005): attached (.nrrd) or detached (.nhdr + the file its
 * "data file" names, relative to the header's folder); encodings raw, gzip and
 * ascii; types int8 .. int64, uint8 .. uint64, float, double, either endianness;
 * 1 to 3 axes (a 2D image becomes nz = 1). Spacing is the length of each axis's
 * "space directions" vector (else "spacings", else 1); the origin is "space
 * origin" (else "axis mins", else 0). The orientation (direction signs, rotation,
 * the named space) is not kept, as in VTK's vtkNrrdReader. Anything malformed
 * (missing or repeated fields, bad numbers, sizes that overflow, data shorter or
 * longer than the sizes say, truncated or corrupt gzip) is refused with a message
 * naming the file, the line and the problem. docs/datasets.md has the details. */
WVOL_API wvol_status wvol_nrrd_read(wvol_volume **out, const char *path, wvol_error *err);
/* Writes float32 samples in raw encoding (same as wvol_nrrd_write_gzip(v, path, 0, err)). */
WVOL_API wvol_status wvol_nrrd_write(const wvol_volume *v, const char *path, wvol_error *err);
/* Writes "NRRD0004", type float, dimension 3, space left-posterior-superior,
 * space directions diag(spacing), space origin, host endianness.
 * gzip_level 0: raw encoding; 1..9: gzip at that zlib level. For a path ending in
 * .nhdr the samples go to a detached data file beside it (wvol_nrrd_data_path);
 * both files are written to temporary names first, and neither is left behind
 * on failure. */
WVOL_API wvol_status wvol_nrrd_write_gzip(const wvol_volume *v, const char *path, int gzip_level,
                                          wvol_error *err);
/* The data file a detached header gets: "<path minus .nhdr>.raw" (".raw.gz" with
 * gzip). Writes it into buf; returns 0 if it does not fit in cap bytes. */
WVOL_API int wvol_nrrd_data_path(char *buf, size_t cap, const char *nhdr_path, int gzip);

/* Writing a volume slab by slab (slices in order, x fastest), so a volume larger than
 * memory can be written: .raw (samples only), .nrrd or .nhdr (the header NRRD writers
 * write, raw or gzip_level 1..9 encoding). Nothing appears under path until commit,
 * which refuses a volume with slices missing; abort (or any failure) leaves no file.
 * commit and abort free the writer; bytes (may be NULL) gets the bytes written. The
 * spacing must be finite and positive, the origin finite; the samples are written as given
 * (NaN and Inf too, as the raw and NRRD writers write a volume's). */
typedef struct wvol_slab_writer wvol_slab_writer;
WVOL_API wvol_status wvol_slab_writer_open(wvol_slab_writer **out, const char *path, const size_t dims[3],
                                           const double spacing[3], const double origin[3], int gzip_level,
                                           wvol_error *err);
WVOL_API wvol_status wvol_slab_writer_put(wvol_slab_writer *w, const float *slab, size_t nz, wvol_error *err);
WVOL_API wvol_status wvol_slab_writer_commit(wvol_slab_writer *w, unsigned long long *bytes, wvol_error *err);
WVOL_API void wvol_slab_writer_abort(wvol_slab_writer *w); /* NULL is fine */
/* 1 if the format of this path can be read / written with this build. */
WVOL_API int wvol_format_supported(const char *path, int for_writing);

/* Converts n samples of type t (byte order as given) to float32; reports values
 * that float32 cannot hold exactly only through the return of non-finite checks. */
WVOL_API void wvol_samples_to_float(float *dst, const void *src, size_t n, wvol_sample_type t, int big_endian);

/* Atomic output file: write to "<path>.tmp-XXXXXX" beside the target, then rename.
 * wvol_atomic_abort removes the temporary file. */
typedef struct wvol_atomic_file {
    FILE *fp;
    char *tmp_path;
    char *final_path;
} wvol_atomic_file;

WVOL_API wvol_status wvol_atomic_open(wvol_atomic_file *f, const char *path, wvol_error *err);
WVOL_API wvol_status wvol_atomic_commit(wvol_atomic_file *f, wvol_error *err);
WVOL_API void wvol_atomic_abort(wvol_atomic_file *f);
/* After a write to f->fp failed: aborts f and returns WVOL_ERR_IO with "PATH: write failed:
 * CAUSE", the cause from errno as the failed call left it (a full disk, a size limit). */
WVOL_API wvol_status wvol_atomic_fail(wvol_atomic_file *f, wvol_error *err);

/* Removes every temporary output file the library has open (an output's "<path>.tmp-XXXXXX"
 * that is neither committed nor aborted yet, of any thread). Async-signal-safe: for a program's
 * SIGINT or SIGTERM handler, which then ends the process (the library installs no handler).
 * The writers whose temporaries it removed fail if they go on. */
WVOL_API void wvol_atomic_remove_pending(void);

/* 1 if path ends with ext (case-insensitive). */
WVOL_API int wvol_path_has_ext(const char *path, const char *ext);

#ifdef __cplusplus
}
#endif
#endif
