/* SPDX-License-Identifier: MIT */
/* C interface of the C++ adapters (vdb_adapter.cpp, vtk_adapter.cpp, obj_adapter.cpp).
 * When an adapter is not built, adapters_missing.c supplies versions that
 * return WVOL_ERR_UNSUPPORTED with a message saying which library is missing. */
#ifndef WVOL_IO_ADAPTERS_H
#define WVOL_IO_ADAPTERS_H

#include "wvol/io.h"

#ifdef __cplusplus
extern "C" {
#endif

wvol_status wvol__vdb_read(wvol_volume **out, const char *path, const char *grid_name, wvol_error *err);
wvol_status wvol__vdb_write(const wvol_volume *v, const char *path, wvol_error *err);
/* .vti .vtk .mha .mhd .nii .nii.gz or a DICOM directory */
wvol_status wvol__vtk_read(wvol_volume **out, const char *path, wvol_error *err);
/* .vti .mha .nii .nii.gz, and legacy .vtk (float32 samples named "density") */
wvol_status wvol__vtk_write(const wvol_volume *v, const char *path, wvol_error *err);
/* A triangle mesh as VTK XML polydata (.vtp): nverts points (xyz: 3 floats each),
 * ntris triangles (tris: 3 vertex indices each, < nverts), optional per-vertex
 * normals (3 floats each, NULL for none). Written to a temporary name, then renamed. */
wvol_status wvol__vtk_write_mesh(const char *path, const float *xyz, size_t nverts, const unsigned *tris,
                                 size_t ntris, const float *normals /* may be NULL */, wvol_error *err);

/* A Wavefront OBJ file with its MTL libraries as tinyobjloader reads it, faces kept as
 * written (not triangulated). Faces in file order; face f has face_nv[f] vertices, whose
 * indices (0-based, into v) start at face_v[face_first[f]]; face_mtl[f] indexes the
 * materials (-1: none). Double precision throughout. Any warning tinyobjloader gives (a
 * missing .mtl, an unknown material) is refused as an error naming the file. */
typedef struct wvol__obj {
    double *v;                  /* 3 per vertex */
    size_t nv, nfaces, nmtl;
    int *face_nv, *face_mtl;
    size_t *face_first;
    long *face_v;
    char (*mtl_name)[128];
    double (*kd)[3], (*ke)[3];
} wvol__obj;
wvol_status wvol__obj_read(wvol__obj *out, const char *path, wvol_error *err);
void wvol__obj_free(wvol__obj *o); /* NULL and a zeroed struct are fine */

#ifdef __cplusplus
}
#endif
#endif
