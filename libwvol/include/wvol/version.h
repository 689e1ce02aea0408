/* SPDX-License-Identifier: MIT
 * Library version and what this build includes. CMake reads the three numbers
 * below (project version, package and pkg-config versions): change them here only.
 * The .wvc file format has its own version, WVOL_WVC_FORMAT_VERSION (wvc.h). */
#ifndef WVOL_VERSION_H
#define WVOL_VERSION_H

#include "wvol/export.h"

#define WVOL_VERSION_MAJOR 0
#define WVOL_VERSION_MINOR 1
#define WVOL_VERSION_PATCH 0

#define WVOL_VERSION_NUMBER (WVOL_VERSION_MAJOR * 10000 + WVOL_VERSION_MINOR * 100 + WVOL_VERSION_PATCH)
#define WVOL__VERSION_STR_(x) #x
#define WVOL__VERSION_STR(x) WVOL__VERSION_STR_(x)
#define WVOL_VERSION_STRING                                                           \
    WVOL__VERSION_STR(WVOL_VERSION_MAJOR) "." WVOL__VERSION_STR(WVOL_VERSION_MINOR) "." \
        WVOL__VERSION_STR(WVOL_VERSION_PATCH)

#ifdef __cplusplus
extern "C" {
#endif

/* The version of the library linked in, as WVOL_VERSION_NUMBER (major * 10000 +
 * minor * 100 + patch): compare with the header's to catch a mismatch. */
WVOL_API int wvol_version(void);

/* The same as "major.minor.patch" (static storage). */
WVOL_API const char *wvol_version_string(void);

/* Optional parts of the library. A build without one has the same headers; the
 * functions that need it return WVOL_ERR_UNSUPPORTED with a message naming it. */
typedef enum wvol_feature {
    WVOL_FEATURE_OPENMP = 0,  /* threads (OpenMP) */
    WVOL_FEATURE_PNG = 1,     /* PNG images (libpng): wvol_png_write, wvol_image_write_png */
    WVOL_FEATURE_OPENEXR = 2, /* EXR images (OpenEXR): wvol_exr_write, wvol_exr_read_channel, ... */
    WVOL_FEATURE_LAPACKE = 3, /* PCA (LAPACKE): wvol_features_pca */
    WVOL_FEATURE_VTK = 4,     /* VTK formats (.vti .vtk .mha .mhd .nii .nii.gz, DICOM, .vtp meshes) */
    WVOL_FEATURE_OPENVDB = 5, /* OpenVDB grids (.vdb) */
    WVOL_FEATURE_TINYOBJLOADER = 6 /* Wavefront OBJ scenes (tinyobjloader): wvol_radiosity_scene_load_obj */
} wvol_feature;

/* 1 if this build includes the feature, 0 if not (or if f is unknown). */
WVOL_API int wvol_has_feature(wvol_feature f);

#ifdef __cplusplus
}
#endif
#endif
