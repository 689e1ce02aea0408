/* SPDX-License-Identifier: MIT
 * The render context (wvol_render_context): a source and settings kept across frames, so that
 * what does not depend on the camera is built once. The bricked path's state (bricks.c,
 * wvol__bricks) is what it keeps; the method is chosen per frame as wvol_render chooses it
 * (render.c), so every frame's image is wvol_render's. */
#include "render_internal.h"

#include <stdlib.h>
#include <string.h>

struct wvol_render_context {
    wvol_render_source source;
    wvol_render_params params;
    size_t cache_given;     /* the budget asked for at create (0: the default) */
    size_t cache_bytes;     /* the brick cache's budget for the current source */
    wvol__bricks *bricks;   /* NULL until a bricked frame */
};

/* The default budget: the fraction of the dense volume's float32 bytes, at least 8 MiB. */
static size_t default_cache(const wvol_render_source *src)
{
    double n = 0, b;
    if (src->kind == WVOL_RENDER_SOURCE_STORE) {
        wvol_store_info info;
        wvol_store_get_info(src->store, &info);
        n = (double)info.nx * (double)info.ny * (double)info.nz;
    }
    b = 4.0 * n * WVOL_RENDER_CONTEXT_CACHE_DEFAULT;
    return b < (double)(8u << 20) ? (size_t)8u << 20 : (size_t)b;
}

static wvol_status check_source(const wvol_render_source *source, wvol_error *err)
{
    WVOL_RETURN_IF(!source, err, WVOL_ERR_ARG, "render context: no source");
    WVOL_RETURN_IF(source->kind == WVOL_RENDER_SOURCE_VOLUME && !source->volume, err, WVOL_ERR_ARG,
                   "render context: no volume");
    WVOL_RETURN_IF(source->kind == WVOL_RENDER_SOURCE_STORE && !source->store, err, WVOL_ERR_ARG,
                   "render context: no store");
    WVOL_RETURN_IF(source->kind != WVOL_RENDER_SOURCE_VOLUME && source->kind != WVOL_RENDER_SOURCE_STORE, err,
                   WVOL_ERR_ARG, "render context: unknown source kind %d", (int)source->kind);
    return WVOL_OK;
}

wvol_status wvol_render_context_create(wvol_render_context **out, const wvol_render_source *source,
                                       const wvol_render_params *params, size_t cache_bytes, wvol_error *err)
{
    wvol_render_context *c;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "render context: no output");
    *out = NULL;
    WVOL_FORWARD(check_source(source, err));
    if (params) WVOL_FORWARD(wvol__render_step_check(params->step, "render context", err));
    c = calloc(1, sizeof *c);
    WVOL_RETURN_IF(!c, err, WVOL_ERR_NOMEM, "render context: out of memory");
    c->source = *source;
    wvol__params(&c->params, params);
    c->cache_given = cache_bytes;
    c->cache_bytes = cache_bytes ? cache_bytes : default_cache(source);
    *out = c;
    return WVOL_OK;
}

wvol_status wvol__context_bricks(wvol_render_context *ctx, wvol_image *img, const wvol_store *st,
                                 const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *p,
                                 wvol_render_stats *stats, wvol_error *err)
{
    if (!wvol__bricks_fits(ctx->bricks, st, p)) {
        wvol__bricks_destroy(ctx->bricks);
        ctx->bricks = NULL;
        WVOL_FORWARD(wvol__render_check(img, cam, tf, p, err)); /* refusals before the set-up, as one-shot */
        WVOL_FORWARD(wvol__bricks_create(&ctx->bricks, st, p, ctx->cache_bytes, err));
    }
    return wvol__bricks_frame(ctx->bricks, img, cam, tf, p, stats, err);
}

wvol_status wvol_render_context_frame(wvol_render_context *ctx, wvol_image *img, const wvol_camera *cam,
                                      const wvol_tf *tf, const wvol_render_params *params, wvol_render_stats *stats,
                                      wvol_error *err)
{
    WVOL_RETURN_IF(!ctx, err, WVOL_ERR_ARG, "render context: none");
    if (params) wvol__params(&ctx->params, params);
    return wvol__render_dispatch(img, &ctx->source, cam, tf, &ctx->params, stats, ctx, err);
}

wvol_status wvol_render_context_set_source(wvol_render_context *ctx, const wvol_render_source *source,
                                           wvol_error *err)
{
    WVOL_RETURN_IF(!ctx, err, WVOL_ERR_ARG, "render context: none");
    WVOL_FORWARD(check_source(source, err));
    wvol__bricks_destroy(ctx->bricks);
    ctx->bricks = NULL;
    ctx->source = *source;
    ctx->cache_bytes = ctx->cache_given ? ctx->cache_given : default_cache(source); /* the default is the source's */
    return WVOL_OK;
}

const wvol_render_source *wvol_render_context_source(const wvol_render_context *ctx)
{
    return ctx ? &ctx->source : NULL;
}

const wvol_render_params *wvol_render_context_params(const wvol_render_context *ctx)
{
    return ctx ? &ctx->params : NULL;
}

size_t wvol_render_context_bytes(const wvol_render_context *ctx)
{
    return ctx && ctx->bricks ? wvol__bricks_bytes(ctx->bricks) : 0;
}

void wvol_render_context_destroy(wvol_render_context *ctx)
{
    if (!ctx) return;
    wvol__bricks_destroy(ctx->bricks);
    free(ctx);
}
