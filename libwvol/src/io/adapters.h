/* C interface of the C++ adapters (vdb_adapter.cpp, vtk_adapter.cpp).
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
/* .vti (also .mha, .nii when VTK can) */
wvol_status wvol__vtk_write(const wvol_volume *v, const char *path, wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
