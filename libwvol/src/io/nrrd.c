/* NRRD reader/writer: owned by the foundation issue (to be completed). */
#include "wvol/io.h"

wvol_status wvol_nrrd_read(wvol_volume **out, const char *path, wvol_error *err)
{
    if (out) *out = NULL;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: NRRD reading is not built yet", path);
}

wvol_status wvol_nrrd_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    (void)v;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: NRRD writing is not built yet", path);
}
