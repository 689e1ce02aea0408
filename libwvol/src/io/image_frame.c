/* SPDX-License-Identifier: MIT
 * Float RGBA frames: allocation and the linear -> sRGB transfer shared by the writers. */
#include "core/status_internal.h"
#include "wvol/image.h"

#include <math.h>
#include <stdlib.h>

wvol_status wvol_image_create(wvol_image **out, int width, int height, wvol_error *err)
{
    wvol_image *img;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "image: output pointer is NULL");
    *out = NULL;
    WVOL_RETURN_IF(width < 1 || height < 1 || width > 65536 || height > 65536, err, WVOL_ERR_DIMS,
                   "image size %dx%d: each side must be 1..65536", width, height);
    img = calloc(1, sizeof *img);
    if (img) img->rgba = calloc((size_t)width * (size_t)height * 4, sizeof(float));
    if (!img || !img->rgba) {
        free(img);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "image %dx%d: out of memory", width, height);
    }
    img->width = width;
    img->height = height;
    *out = img;
    return WVOL_OK;
}

void wvol_image_destroy(wvol_image *img)
{
    if (!img) return;
    free(img->rgba);
    free(img);
}

double wvol_linear_to_srgb(double v)
{
    if (!(v > 0.0)) return 0.0; /* also maps NaN to 0 */
    if (v >= 1.0) return 1.0;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}
