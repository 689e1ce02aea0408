/* SPDX-License-Identifier: MIT
 * OpenEXR images through OpenEXR's C API (OpenEXRCore): scanline, float32, ZIP.
 * Writing goes through wvol_atomic_file (a custom write function on its stream), so a
 * failure never leaves a partial file; OpenEXR's error handler is redirected into the
 * wvol_error so the library prints nothing. */
#define _POSIX_C_SOURCE 200809L
#include "core/status_internal.h"
#include "wvol/image.h"
#include "wvol/io.h"

#include <errno.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>

typedef struct exr_io {
    FILE *fp;
    char msg[256];
} exr_io;

/* The calls of one read or write on this thread, for the error handler. It cannot ask the
 * context for its user data: OpenEXR may report an error while it holds the context's lock
 * (a write that fails inside exr_write_header), and exr_get_user_data takes that lock again. */
static _Thread_local exr_io *current_io;

static void on_exr_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    exr_io *io = current_io;
    (void)ctxt;
    if (io && !io->msg[0])
        snprintf(io->msg, sizeof io->msg, "%s (%s)", msg ? msg : "", exr_get_error_code_as_string(code));
}

static int64_t write_at(exr_const_context_t ctxt, void *ud, const void *buf, uint64_t sz, uint64_t off,
                        exr_stream_error_func_ptr_t error_cb)
{
    exr_io *io = ud;
    if (fseeko(io->fp, (off_t)off, SEEK_SET) != 0 || fwrite(buf, 1, sz, io->fp) != sz) {
        const int e = errno;
        if (error_cb)
            error_cb(ctxt, EXR_ERR_WRITE_IO, "write of %llu bytes failed: %s", (unsigned long long)sz,
                     e ? strerror(e) : "stream error");
        return -1;
    }
    return (int64_t)sz;
}

static wvol_status exr_fail(wvol_error *err, const char *path, const char *what, exr_result_t rv, const exr_io *io)
{
    return wvol_error_set(err, rv == EXR_ERR_OUT_OF_MEMORY ? WVOL_ERR_NOMEM : WVOL_ERR_IO, "%s: %s: %s", path, what,
                          io->msg[0] ? io->msg : exr_get_default_error_message(rv));
}

wvol_status wvol_exr_write(const char *path, int width, int height, const wvol_exr_channel *channels,
                           int nchannels, wvol_error *err)
{
    wvol_atomic_file f;
    exr_io io;
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_encode_pipeline_t enc;
    exr_result_t rv;
    int part = 0, lines = 1, y, c, k, have_enc = 0;
    const char *what = "";

    WVOL_RETURN_IF(!path || !*path, err, WVOL_ERR_ARG, "EXR output path is empty");
    WVOL_RETURN_IF(width < 1 || height < 1 || width > 65536 || height > 65536, err, WVOL_ERR_DIMS,
                   "%s: image size %dx%d out of range", path, width, height);
    WVOL_RETURN_IF(!channels || nchannels < 1 || nchannels > 64, err, WVOL_ERR_ARG,
                   "%s: %d channels (1..64 expected)", path, nchannels);
    for (c = 0; c < nchannels; c++) {
        WVOL_RETURN_IF(!channels[c].name || !*channels[c].name || strlen(channels[c].name) > 31 || !channels[c].data ||
                           channels[c].stride < 1,
                       err, WVOL_ERR_ARG, "%s: channel %d is malformed (name, data and stride are required)", path, c);
        for (k = 0; k < c; k++)
            WVOL_RETURN_IF(!strcmp(channels[c].name, channels[k].name), err, WVOL_ERR_ARG,
                           "%s: channel '%s' given twice", path, channels[c].name);
    }
    WVOL_FORWARD(wvol_atomic_open(&f, path, err));
    memset(&io, 0, sizeof io);
    io.fp = f.fp;
    current_io = &io;
    init.error_handler_fn = on_exr_error;
    init.user_data = &io;
    init.write_fn = write_at;
    memset(&enc, 0, sizeof enc);

#define EXR_TRY(call, label)              \
    do {                                  \
        what = label;                     \
        if ((rv = (call)) != EXR_ERR_SUCCESS) goto fail; \
    } while (0)
    EXR_TRY(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), "starting the file");
    EXR_TRY(exr_add_part(ctx, "image", EXR_STORAGE_SCANLINE, &part), "adding the image part");
    EXR_TRY(exr_initialize_required_attr_simple(ctx, part, width, height, EXR_COMPRESSION_ZIP), "setting the header");
    for (c = 0; c < nchannels; c++)
        EXR_TRY(exr_add_channel(ctx, part, channels[c].name, EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1),
                "adding a channel");
    EXR_TRY(exr_write_header(ctx), "writing the header");
    EXR_TRY(exr_get_scanlines_per_chunk(ctx, part, &lines), "querying the chunk size");
    for (y = 0; y < height; y += lines) {
        exr_chunk_info_t ci;
        EXR_TRY(exr_write_scanline_chunk_info(ctx, part, y, &ci), "preparing a chunk");
        if (!have_enc) {
            EXR_TRY(exr_encoding_initialize(ctx, part, &ci, &enc), "initialising the encoder");
            have_enc = 1;
        } else {
            EXR_TRY(exr_encoding_update(ctx, part, &ci, &enc), "updating the encoder");
        }
        for (k = 0; k < enc.channel_count; k++) {
            exr_coding_channel_info_t *ch = &enc.channels[k];
            const wvol_exr_channel *src = NULL;
            for (c = 0; c < nchannels; c++)
                if (!strcmp(channels[c].name, ch->channel_name)) src = &channels[c];
            if (!src) {
                rv = EXR_ERR_INVALID_ARGUMENT;
                what = "matching channels";
                goto fail;
            }
            ch->user_bytes_per_element = 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_pixel_stride = (int32_t)(src->stride * sizeof(float));
            ch->user_line_stride = (int32_t)(src->stride * sizeof(float) * (size_t)width);
            ch->encode_from_ptr = (const uint8_t *)(src->data + (size_t)ci.start_y * (size_t)width * src->stride);
        }
        if (y == 0) EXR_TRY(exr_encoding_choose_default_routines(ctx, part, &enc), "choosing the encoder");
        EXR_TRY(exr_encoding_run(ctx, part, &enc), "encoding a chunk");
    }
    if (have_enc) exr_encoding_destroy(ctx, &enc);
    have_enc = 0;
    what = "finishing the file";
    rv = exr_finish(&ctx);
    ctx = NULL;
    if (rv != EXR_ERR_SUCCESS) goto fail;
#undef EXR_TRY
    return wvol_atomic_commit(&f, err);

fail: {
    wvol_status s = exr_fail(err, path, what, rv, &io);
    if (have_enc) exr_encoding_destroy(ctx, &enc);
    if (ctx) exr_finish(&ctx);
    wvol_atomic_abort(&f);
    return s;
}
}

wvol_status wvol_image_write_exr(const wvol_image *img, const char *path, const float *depth,
                                 wvol_error *err)
{
    wvol_exr_channel ch[5];
    static const char *names[4] = {"R", "G", "B", "A"};
    int c;
    WVOL_RETURN_IF(!img || !img->rgba, err, WVOL_ERR_ARG, "%s: no image", path ? path : "(null)");
    for (c = 0; c < 4; c++) {
        ch[c].name = names[c];
        ch[c].data = img->rgba + c;
        ch[c].stride = 4;
    }
    ch[4].name = "Z";
    ch[4].data = depth;
    ch[4].stride = 1;
    return wvol_exr_write(path, img->width, img->height, ch, depth ? 5 : 4, err);
}

wvol_status wvol_exr_read_channel(float **out, int *width, int *height, const char *path, const char *name,
                                  wvol_error *err)
{
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_decode_pipeline_t dec;
    exr_attr_box2i_t dw;
    exr_storage_t storage;
    exr_io io;
    exr_result_t rv;
    float *buf = NULL;
    int w, h, lines, y, k, found = 0, have_dec = 0;
    const char *what = "";

    WVOL_RETURN_IF(!out || !width || !height, err, WVOL_ERR_ARG,
                   "EXR read: the data, width and height output pointers are required");
    *out = NULL;
    WVOL_RETURN_IF(!path || !name, err, WVOL_ERR_ARG, "EXR read: path and channel name are required");
    memset(&io, 0, sizeof io);
    memset(&dec, 0, sizeof dec);
    current_io = &io;
    init.error_handler_fn = on_exr_error;
    init.user_data = &io;
#define EXR_TRY(call, label)              \
    do {                                  \
        what = label;                     \
        if ((rv = (call)) != EXR_ERR_SUCCESS) goto fail; \
    } while (0)
    EXR_TRY(exr_start_read(&ctx, path, &init), "opening");
    EXR_TRY(exr_get_storage(ctx, 0, &storage), "reading the part type");
    if (storage != EXR_STORAGE_SCANLINE) {
        exr_finish(&ctx);
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: only scanline EXR images are read", path);
    }
    EXR_TRY(exr_get_data_window(ctx, 0, &dw), "reading the data window");
    EXR_TRY(exr_get_scanlines_per_chunk(ctx, 0, &lines), "querying the chunk size");
    w = dw.max.x - dw.min.x + 1;
    h = dw.max.y - dw.min.y + 1;
    if (w < 1 || h < 1 || w > 65536 || h > 65536) {
        exr_finish(&ctx);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: data window %dx%d out of range", path, w, h);
    }
    buf = calloc((size_t)w * (size_t)h, sizeof *buf);
    if (!buf) {
        exr_finish(&ctx);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    for (y = dw.min.y; y <= dw.max.y; y += lines) {
        exr_chunk_info_t ci;
        EXR_TRY(exr_read_scanline_chunk_info(ctx, 0, y, &ci), "reading a chunk table entry");
        if (!have_dec) {
            EXR_TRY(exr_decoding_initialize(ctx, 0, &ci, &dec), "initialising the decoder");
            have_dec = 1;
        } else {
            EXR_TRY(exr_decoding_update(ctx, 0, &ci, &dec), "updating the decoder");
        }
        found = 0;
        for (k = 0; k < dec.channel_count; k++) {
            exr_coding_channel_info_t *ch = &dec.channels[k];
            if (strcmp(ch->channel_name, name) || ch->x_samples != 1 || ch->y_samples != 1) {
                ch->decode_to_ptr = NULL;
                continue;
            }
            found = 1;
            ch->user_bytes_per_element = 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_pixel_stride = 4;
            ch->user_line_stride = 4 * w;
            ch->decode_to_ptr = (uint8_t *)(buf + (size_t)(ci.start_y - dw.min.y) * (size_t)w);
        }
        if (!found) {
            exr_decoding_destroy(ctx, &dec);
            exr_finish(&ctx);
            free(buf);
            return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: no full-resolution channel '%s'", path, name);
        }
        if (y == dw.min.y) EXR_TRY(exr_decoding_choose_default_routines(ctx, 0, &dec), "choosing the decoder");
        EXR_TRY(exr_decoding_run(ctx, 0, &dec), "decoding a chunk");
    }
#undef EXR_TRY
    exr_decoding_destroy(ctx, &dec);
    exr_finish(&ctx);
    *out = buf;
    *width = w;
    *height = h;
    return WVOL_OK;

fail: {
    wvol_status s = exr_fail(err, path, what, rv, &io);
    if (rv == EXR_ERR_FILE_ACCESS || rv == EXR_ERR_FILE_BAD_HEADER) s = wvol_error_set(err, rv == EXR_ERR_FILE_ACCESS ? WVOL_ERR_IO : WVOL_ERR_FORMAT, "%s: %s: %s", path, what, io.msg[0] ? io.msg : exr_get_default_error_message(rv));
    if (have_dec) exr_decoding_destroy(ctx, &dec);
    if (ctx) exr_finish(&ctx);
    free(buf);
    return s;
}
}
