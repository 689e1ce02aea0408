/* SPDX-License-Identifier: MIT
 * 8-bit PNG through libpng: linear floats, sRGB-encoded, written atomically. */
#include "core/file_open.h"
#include "core/status_internal.h"
#include "wvol/image.h"
#include "wvol/io.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct png_err_ctx {
    char msg[200];
} png_err_ctx;

static void on_png_error(png_structp png, png_const_charp msg)
{
    png_err_ctx *e = png_get_error_ptr(png);
    snprintf(e->msg, sizeof e->msg, "%s", msg);
    png_longjmp(png, 1);
}

static void on_png_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg; /* the library never prints */
}

static unsigned char to_u8(double v)
{
    double s = v * 255.0 + 0.5;
    return (unsigned char)(s < 0 ? 0 : s > 255 ? 255 : s);
}

wvol_status wvol_png_write(const char *path, int width, int height, int channels, const float *data,
                           wvol_error *err)
{
    wvol_atomic_file f;
    png_structp png = NULL;
    png_infop info = NULL;
    png_err_ctx ectx;
    unsigned char *volatile row = NULL;
    int color_type, y, x, c;
    wvol_status s;

    WVOL_RETURN_IF(width < 1 || height < 1 || width > 65536 || height > 65536, err, WVOL_ERR_DIMS,
                   "%s: image size %dx%d out of range", path ? path : "(null)", width, height);
    WVOL_RETURN_IF(channels != 1 && channels != 3 && channels != 4, err, WVOL_ERR_ARG,
                   "%s: PNG needs 1, 3 or 4 channels, got %d", path ? path : "(null)", channels);
    WVOL_RETURN_IF(!data, err, WVOL_ERR_ARG, "%s: no pixel data", path ? path : "(null)");
    color_type = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
    WVOL_FORWARD(wvol_atomic_open(&f, path, err));
    ectx.msg[0] = 0;
    row = malloc((size_t)width * (size_t)channels);
    png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ectx, on_png_error, on_png_warning);
    if (png) info = png_create_info_struct(png);
    if (!row || !png || !info) {
        png_destroy_write_struct(&png, &info);
        free(row);
        wvol_atomic_abort(&f);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        free(row);
        wvol_atomic_abort(&f);
        return wvol_error_set(err, WVOL_ERR_IO, "%s: PNG write failed: %s", path, ectx.msg);
    }
    png_init_io(png, f.fp);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, color_type, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (y = 0; y < height; y++) {
        const float *src = data + (size_t)y * (size_t)width * (size_t)channels;
        for (x = 0; x < width; x++)
            for (c = 0; c < channels; c++) {
                double v = src[(size_t)x * channels + c];
                row[(size_t)x * channels + c] = c == 3 ? to_u8(v != v ? 0.0 : v) : to_u8(wvol_linear_to_srgb(v));
            }
        png_write_row(png, row);
    }
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    free(row);
    s = wvol_atomic_commit(&f, err);
    return s;
}

wvol_status wvol_image_write_png(const wvol_image *img, const char *path, const float background[3],
                                 double exposure, wvol_error *err)
{
    static const float black[3] = {0, 0, 0};
    size_t i, n;
    float *rgb;
    wvol_status s;
    WVOL_RETURN_IF(!img || !img->rgba, err, WVOL_ERR_ARG, "%s: no image", path ? path : "(null)");
    WVOL_RETURN_IF(!(exposure >= 0) || !isfinite(exposure), err, WVOL_ERR_ARG,
                   "%s: PNG exposure %g (must be finite and >= 0)", path ? path : "(null)", exposure);
    for (int c = 0; background && c < 3; c++)
        WVOL_RETURN_IF(!isfinite(background[c]), err, WVOL_ERR_ARG, "%s: PNG background[%d] = %g (must be finite)",
                       path ? path : "(null)", c, (double)background[c]);
    if (!background) background = black;
    n = (size_t)img->width * (size_t)img->height;
    rgb = malloc(n * 3 * sizeof *rgb);
    WVOL_RETURN_IF(!rgb, err, WVOL_ERR_NOMEM, "%s: out of memory", path ? path : "(null)");
    for (i = 0; i < n; i++) {
        const float *p = img->rgba + 4 * i;
        float a = p[3] < 0 ? 0 : p[3] > 1 ? 1 : p[3];
        int c;
        for (c = 0; c < 3; c++) rgb[3 * i + c] = (float)(exposure * p[c] + (1.0f - a) * background[c]);
    }
    s = wvol_png_write(path, img->width, img->height, 3, rgb, err);
    free(rgb);
    return s;
}

wvol_status wvol_png_read_rgb(float **out, int *width, int *height, int *colour, const char *path,
                              wvol_error *err)
{
    png_image im;
    unsigned char *buf;
    size_t n;
    FILE *fp;
    WVOL_RETURN_IF(!out || !width || !height || !path, err, WVOL_ERR_ARG, "PNG read: NULL argument");
    *out = NULL;
    *width = *height = 0;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    /* opened here, so that a file that cannot be read (IO) and one that is not a PNG (FORMAT)
     * are told apart: libpng's file reader reports both alike */
    WVOL_FORWARD(wvol__fopen_regular(&fp, path, err));
    if (!png_image_begin_read_from_stdio(&im, fp)) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: not a readable PNG: %s", path, im.message);
    }
    if (im.width < 1 || im.height < 1 || im.width > 65536 || im.height > 65536) {
        png_image_free(&im);
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_DIMS, "%s: %ux%u outside 1..65536 per side", path, im.width,
                              im.height);
    }
    if (colour) *colour = (im.format & PNG_FORMAT_FLAG_COLOR) != 0;
    im.format = PNG_FORMAT_RGB; /* 8-bit sRGB; alpha composited away, palettes expanded */
    buf = malloc(PNG_IMAGE_SIZE(im));
    if (!buf) {
        png_image_free(&im);
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    if (!png_image_finish_read(&im, NULL, buf, 0, NULL)) { /* frees im on failure */
        free(buf);
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: PNG decoding failed: %s", path, im.message);
    }
    fclose(fp);
    n = (size_t)im.width * im.height * 3;
    *out = malloc(n * sizeof **out);
    if (!*out) {
        free(buf);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    for (size_t i = 0; i < n; i++) {
        double v = buf[i] / 255.0;
        (*out)[i] = (float)(v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4));
    }
    *width = (int)im.width;
    *height = (int)im.height;
    free(buf);
    return WVOL_OK;
}
