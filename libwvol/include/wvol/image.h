/* SPDX-License-Identifier: MIT */
/* Images: float RGBA frames and their files.
 *   OpenEXR   float32 channels through OpenEXR's C API (OpenEXRCore): R G B A plus any
 *             extra named float channels (a "Z" depth channel, ...); ZIP compressed.
 *   PNG       8-bit, linear values encoded with the sRGB transfer function (IEC 61966-2-1):
 *             v <= 0.0031308 ? 12.92 v : 1.055 v^(1/2.4) - 0.055, after clamping to [0, 1];
 *             alpha, when written, is stored linearly.
 * Pixel (x, y) with row 0 at the top; interleaved channels, x fastest.
 * Writers never leave a partial file: they write a temporary name and rename it. */
#ifndef WVOL_IMAGE_H
#define WVOL_IMAGE_H

#include <stddef.h>
#include "wvol/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A frame of linear, premultiplied (associated) RGBA floats: rgba[4*(x + width*y) + c]. */
typedef struct wvol_image {
    int width, height;
    float *rgba;
} wvol_image;

/* Allocates a zero-filled frame (1 <= width, height <= 65536). */
WVOL_API wvol_status wvol_image_create(wvol_image **out, int width, int height, wvol_error *err);
WVOL_API void wvol_image_destroy(wvol_image *img); /* NULL is fine */

/* One float channel of an EXR file: value of pixel (x, y) at data[(x + width*y) * stride]. */
typedef struct wvol_exr_channel {
    const char *name;   /* "R", "G", "B", "A", "Z", ... (at most 31 characters) */
    const float *data;
    size_t stride;      /* in floats; 1 for a plain plane, 4 for one channel of RGBA */
} wvol_exr_channel;

/* Writes a scanline EXR (float32, ZIP) with the given channels (1..64, unique names). */
WVOL_API wvol_status wvol_exr_write(const char *path, int width, int height, const wvol_exr_channel *channels,
                                    int nchannels, wvol_error *err);

/* Writes the frame as R, G, B, A; depth (width*height floats, may be NULL) becomes "Z". */
WVOL_API wvol_status wvol_image_write_exr(const wvol_image *img, const char *path, const float *depth,
                                          wvol_error *err);

/* Reads one float channel of a scanline EXR (any pixel type, converted to float). *out
 * gets width*height floats (free() it); *width and *height the data window's size. */
WVOL_API wvol_status wvol_exr_read_channel(float **out, int *width, int *height, const char *path,
                                           const char *name, wvol_error *err);

/* Writes 8-bit PNG from interleaved linear floats with `channels` = 1 (grey), 3 (RGB) or
 * 4 (RGBA, alpha not premultiplied): colour channels are clamped to [0, 1] and sRGB-encoded. */
WVOL_API wvol_status wvol_png_write(const char *path, int width, int height, int channels, const float *data,
                                    wvol_error *err);

/* Reads a PNG as linear RGB floats: 8-bit sRGB decoded, palettes expanded, alpha composited
 * over black, grey copied to the three channels. *out gets width*height*3 floats, x fastest
 * (free() it); *colour (may be NULL) is 0 for a greyscale file. Sides above 65536 are refused
 * before the pixels are decoded. */
WVOL_API wvol_status wvol_png_read_rgb(float **out, int *width, int *height, int *colour, const char *path,
                                       wvol_error *err);

/* Writes the frame as an RGB PNG composited over a background colour (linear; NULL = black),
 * each colour channel scaled by `exposure` first (1 = as is). */
WVOL_API wvol_status wvol_image_write_png(const wvol_image *img, const char *path, const float background[3],
                                          double exposure, wvol_error *err);

/* Linear -> sRGB-encoded value in [0, 1] (the PNG writer's transfer). */
WVOL_API double wvol_linear_to_srgb(double v);

#ifdef __cplusplus
}
#endif
#endif
