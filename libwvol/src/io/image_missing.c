/* SPDX-License-Identifier: MIT
 * Image writers and readers of a build without libpng or OpenEXR (CMake leaves out
 * image_png.c / image_exr.c then): same functions, answering WVOL_ERR_UNSUPPORTED
 * with a message naming the missing library. */
#include "wvol/image.h"

#ifndef WVOL_HAVE_PNG
wvol_status wvol_png_write(const char *path, int width, int height, int channels, const float *data,
                           wvol_error *err)
{
    (void)width, (void)height, (void)channels, (void)data;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no PNG support (libpng)",
                          path ? path : "(null)");
}

wvol_status wvol_image_write_png(const wvol_image *img, const char *path, const float background[3],
                                 double exposure, wvol_error *err)
{
    (void)img, (void)background, (void)exposure;
    return wvol_png_write(path, 0, 0, 0, NULL, err);
}

wvol_status wvol_png_read_rgb(float **out, int *width, int *height, int *colour, const char *path,
                              wvol_error *err)
{
    if (out) *out = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (colour) *colour = 0;
    return wvol_png_write(path, 0, 0, 0, NULL, err);
}
#endif

#ifndef WVOL_HAVE_OPENEXR
wvol_status wvol_exr_write(const char *path, int width, int height, const wvol_exr_channel *channels,
                           int nchannels, wvol_error *err)
{
    (void)width, (void)height, (void)channels, (void)nchannels;
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: this build has no EXR support (OpenEXR)",
                          path ? path : "(null)");
}

wvol_status wvol_image_write_exr(const wvol_image *img, const char *path, const float *depth, wvol_error *err)
{
    (void)img, (void)depth;
    return wvol_exr_write(path, 0, 0, NULL, 0, err);
}

wvol_status wvol_exr_read_channel(float **out, int *width, int *height, const char *path, const char *name,
                                  wvol_error *err)
{
    (void)name;
    if (out) *out = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (!out || !width || !height)
        return wvol_error_set(err, WVOL_ERR_ARG, "EXR read: the data, width and height output pointers are required");
    return wvol_exr_write(path, 0, 0, NULL, 0, err);
}
#endif

/* ISO C wants at least one declaration in a translation unit. */
typedef int wvol__image_missing_unused;
