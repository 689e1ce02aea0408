/* SPDX-License-Identifier: MIT */
/* Fallbacks for adapters this build does not include (see adapters.h). */
#include "io/adapters.h"

#include <string.h>

#ifndef WVOL_HAVE_OPENVDB
wvol_status wvol__vdb_read(wvol_volume **out, const char *path, const char *grid_name, wvol_error *err)
{
    (void)grid_name;
    if (out) *out = NULL;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no OpenVDB support", path);
}
wvol_status wvol__vdb_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    (void)v;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no OpenVDB support", path);
}
#endif

#ifndef WVOL_HAVE_VTK
wvol_status wvol__vtk_read(wvol_volume **out, const char *path, wvol_error *err)
{
    if (out) *out = NULL;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no VTK support", path);
}
wvol_status wvol__vtk_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    (void)v;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no VTK support", path);
}
wvol_status wvol__vtk_write_mesh(const char *path, const float *xyz, size_t nverts, const unsigned *tris,
                                 size_t ntris, const float *normals, wvol_error *err)
{
    (void)xyz, (void)nverts, (void)tris, (void)ntris, (void)normals;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no VTK support", path);
}
#endif

#ifndef WVOL_HAVE_TINYOBJLOADER
wvol_status wvol__obj_read(wvol__obj *out, const char *path, wvol_error *err)
{
    if (out) memset(out, 0, sizeof *out);
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no OBJ support (tinyobjloader)", path);
}
void wvol__obj_free(wvol__obj *o)
{
    (void)o;
}
#endif
