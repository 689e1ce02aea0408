/* SPDX-License-Identifier: MIT
 * Version and build features, answered from what this build was compiled with. */
#include "wvol/version.h"

int wvol_version(void)
{
    return WVOL_VERSION_NUMBER;
}

const char *wvol_version_string(void)
{
    return WVOL_VERSION_STRING;
}

int wvol_has_feature(wvol_feature f)
{
    switch (f) {
#ifdef _OPENMP
    case WVOL_FEATURE_OPENMP: return 1;
#endif
#ifdef WVOL_HAVE_PNG
    case WVOL_FEATURE_PNG: return 1;
#endif
#ifdef WVOL_HAVE_OPENEXR
    case WVOL_FEATURE_OPENEXR: return 1;
#endif
#ifdef WVOL_HAVE_LAPACKE
    case WVOL_FEATURE_LAPACKE: return 1;
#endif
#ifdef WVOL_HAVE_VTK
    case WVOL_FEATURE_VTK: return 1;
#endif
#ifdef WVOL_HAVE_OPENVDB
    case WVOL_FEATURE_OPENVDB: return 1;
#endif
#ifdef WVOL_HAVE_TINYOBJLOADER
    case WVOL_FEATURE_TINYOBJLOADER: return 1;
#endif
    default: return 0;
    }
}
