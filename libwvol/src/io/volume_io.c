/* SPDX-License-Identifier: MIT */
/* Load/save dispatch by extension (see wvol/io.h for the table). */
#define _POSIX_C_SOURCE 200809L
#include "core/file_open.h"
#include "core/finite.h"
#include "core/status_internal.h"
#include "wvol/io.h"
#include "io/adapters.h"
#include "io/io_internal.h"
#include "wvol/wvc.h"

#include <errno.h>
#include <string.h>
#include <sys/stat.h>

typedef enum { FMT_UNKNOWN, FMT_RAW, FMT_NRRD, FMT_VDB, FMT_VTK, FMT_VTI, FMT_DICOM, FMT_WVC } fmt_kind;

static fmt_kind format_of(const char *path)
{
    static const char *vtk_ext[] = {".vtk", ".mha", ".mhd", ".nii", ".nii.gz"};
    struct stat st;
    size_t i;
    if (wvol_path_has_ext(path, ".raw") || wvol_path_has_ext(path, ".bin")) return FMT_RAW;
    if (wvol_path_has_ext(path, ".nrrd") || wvol_path_has_ext(path, ".nhdr")) return FMT_NRRD;
    if (wvol_path_has_ext(path, ".vdb")) return FMT_VDB;
    if (wvol_path_has_ext(path, ".wvc")) return FMT_WVC;
    if (wvol_path_has_ext(path, ".vti")) return FMT_VTI;
    for (i = 0; i < sizeof vtk_ext / sizeof vtk_ext[0]; i++)
        if (wvol_path_has_ext(path, vtk_ext[i])) return FMT_VTK;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) return FMT_DICOM;
    return FMT_UNKNOWN;
}

int wvol_format_supported(const char *path, int for_writing)
{
    (void)for_writing; /* used only when the VTK adapter is built */
    switch (format_of(path)) {
    case FMT_RAW:
    case FMT_NRRD: return 1;
    case FMT_DICOM: return !for_writing; /* io/dicom.c */
    case FMT_WVC: return !for_writing;   /* decoded whole; wvol compress writes one */
#ifdef WVOL_HAVE_OPENVDB
    case FMT_VDB: return 1;
#endif
#ifdef WVOL_HAVE_VTK
    case FMT_VTI: return 1;
    case FMT_VTK: return !for_writing || !wvol_path_has_ext(path, ".mhd"); /* .mhd: header + data pair */
#endif
    default: return 0;
    }
}

/* A .wvc file as a volume: decoded whole and reconstructed (a command that can work
 * within a memory budget opens it as a store instead, wvol_store_open). */
static wvol_status load_wvc(wvol_volume **out, const char *path, wvol_error *err)
{
    wvol_coeffs *c = NULL;
    wvol_status st = wvol_wvc_read(&c, path, NULL, NULL, err);
    if (st == WVOL_OK) st = wvol_idwt3_consume(out, &c, err);
    wvol_coeffs_destroy(c);
    return st;
}

wvol_status wvol_volume_load(wvol_volume **out, const char *path, const wvol_load_options *opt,
                             wvol_error *err)
{
    wvol_load_options defaults;
    struct stat st;
    fmt_kind fmt;
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "load: NULL argument");
    *out = NULL;
    if (!opt) {
        wvol_load_options_default(&defaults);
        opt = &defaults;
    }
    WVOL_RETURN_IF(stat(path, &st) != 0, err, WVOL_ERR_IO, "%s: %s", path, strerror(errno));
    fmt = format_of(path);
    /* a FIFO or device would make the format libraries wait or read without end */
    if (fmt != FMT_DICOM) WVOL_FORWARD(wvol__check_regular(path, err));
    switch (fmt) {
    case FMT_RAW: return wvol_raw_read(out, path, opt, err);
    case FMT_NRRD: return wvol_nrrd_read(out, path, err);
    case FMT_VDB: return wvol__vdb_read(out, path, opt->grid_name, err);
    case FMT_VTI:
    case FMT_VTK: return wvol__vtk_read(out, path, err);
    case FMT_DICOM: return wvol__dicom_read(out, path, err);
    case FMT_WVC: return load_wvc(out, path, err);
    default:
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                              "%s: unknown volume format (known: .raw .nrrd .nhdr .vdb .vti .vtk .mha "
                              ".mhd .nii .nii.gz .wvc, or a DICOM folder)", path);
    }
}

wvol_status wvol_volume_save(const wvol_volume *v, const char *path, wvol_error *err)
{
    WVOL_RETURN_IF(!v || !path, err, WVOL_ERR_ARG, "save: NULL argument");
    WVOL_FORWARD(wvol__geometry_check(v->spacing, v->origin, err));
    switch (format_of(path)) {
    case FMT_RAW: return wvol_raw_write(v, path, err);
    case FMT_NRRD: return wvol_nrrd_write(v, path, err);
    case FMT_VDB: return wvol__vdb_write(v, path, err);
    case FMT_VTI:
    case FMT_VTK: return wvol__vtk_write(v, path, err);
    default:
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                              "%s: cannot write this format (known: .raw .nrrd .nhdr .vdb .vti .vtk .mha .nii "
                              ".nii.gz)",
                              path);
    }
}
