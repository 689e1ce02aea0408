/* SPDX-License-Identifier: MIT */
/* Level of detail by screen size: the choice of level (wvol_lod_level, the one place it is
 * made) and a frame rendered from that level (wvol_render_lod). The coarser grid is the one
 * `wvol decompress --level` writes (wvol_idwt3_level), so a coarse frame is the reference
 * frame of the coarse decode, and its extra error is the dropped detail levels' energy. */
#include <math.h>
#include <string.h>

#include "core/clock.h"
#include "core/status_internal.h"
#include "wvol/lod.h"

static const double PI = 3.14159265358979323846;

void wvol_lod_params_default(wvol_lod_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->enabled = 1;
    p->filter = NULL;
    p->level = -1;
}

/* Largest spacing over the transformed axes (dims > 1); 0 when no axis is. */
static double voxel_size(const wvol_geometry *g)
{
    double v = 0.0;
    for (int a = 0; a < 3; a++)
        if (g->dims[a] > 1 && g->spacing[a] > v) v = g->spacing[a];
    return v;
}

/* Distance from p to the closed box [lo, hi] (0 inside). */
static double box_distance(const double p[3], const double lo[3], const double hi[3])
{
    double d2 = 0.0;
    for (int a = 0; a < 3; a++) {
        double d = p[a] < lo[a] ? lo[a] - p[a] : p[a] > hi[a] ? p[a] - hi[a] : 0.0;
        d2 += d * d;
    }
    return sqrt(d2);
}

int wvol_lod_level(const wvol_camera *cam, const wvol_geometry *g, int levels, double *footprint)
{
    double fp, vox, lo[3], hi[3];
    int L = 0;
    if (footprint) *footprint = 0.0;
    if (!cam || !g || cam->height < 1) return 0;
    if (cam->projection == WVOL_PROJECTION_ORTHOGRAPHIC) {
        fp = cam->view_height / cam->height;
    } else {
        wvol_geometry_bounds(g, lo, hi);
        fp = 2.0 * box_distance(cam->eye, lo, hi) * tan(0.5 * cam->fov_y * PI / 180.0) / cam->height;
    }
    if (!(fp >= 0) || !isfinite(fp)) fp = 0.0;
    if (footprint) *footprint = fp;
    vox = voxel_size(g);
    if (!(vox > 0)) return 0;
    while (L < levels && ldexp(vox, L + 1) <= fp * (1.0 + 1e-9)) L++;
    return L;
}

/* Whether a frame with these settings may render from a coarser grid: the sampling methods
 * on the source's grid, with nothing that lives on the original grid only. */
static int lod_applies(const wvol_render_source *src, const wvol_render_params *p)
{
    if (p->colors || p->gradient_levels > 0) return 0;
    if (p->method == WVOL_RENDER_METHOD_AUTO) return 1;
    if (src->kind == WVOL_RENDER_SOURCE_VOLUME) return p->method == WVOL_RENDER_METHOD_REFERENCE;
    return p->method == WVOL_RENDER_METHOD_BRICKS;
}

static void source_geometry(const wvol_render_source *src, wvol_geometry *g, int *levels)
{
    if (src->kind == WVOL_RENDER_SOURCE_STORE) {
        wvol_store_info si;
        wvol_store_get_info(src->store, &si);
        g->dims[0] = si.nx, g->dims[1] = si.ny, g->dims[2] = si.nz;
        memcpy(g->spacing, si.spacing, sizeof g->spacing);
        memcpy(g->origin, si.origin, sizeof g->origin);
        *levels = si.levels;
    } else {
        wvol_geometry_of_volume(g, src->volume);
        *levels = wvol_dwt_max_levels(src->volume->nx, src->volume->ny, src->volume->nz);
    }
}

/* The level-L volume of the source and the energy dropped to reach it. */
static wvol_status coarse_volume(wvol_volume **out, double *energy, const wvol_render_source *src,
                                 const wvol_lod_params *lod, int L, wvol_error *err)
{
    if (src->kind == WVOL_RENDER_SOURCE_STORE) {
        WVOL_FORWARD(wvol_store_level_energy(src->store, L, energy, err));
        return wvol_store_level_volume(out, src->store, L, err);
    }
    const wvol_filter *f = lod->filter;
    if (!f) WVOL_FORWARD(wvol_filter_get(&f, "db2", err));
    return wvol_volume_level(out, src->volume, f, L, energy, err);
}

/* wvol_render_lod, its full-resolution frames through ctx when not NULL. */
static wvol_status render_lod(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                              const wvol_tf *tf, const wvol_render_params *params, const wvol_lod_params *lod,
                              wvol_render_stats *stats, wvol_lod_stats *lod_stats, wvol_render_context *ctx,
                              wvol_error *err)
{
    wvol_lod_params lp;
    wvol_render_params p;
    wvol_lod_stats ls;
    wvol_geometry g;
    wvol_volume *coarse = NULL;
    wvol_render_source csrc;
    wvol_status s;
    int levels = 0, L = 0;
    double t0;
    if (lod) lp = *lod;
    else wvol_lod_params_default(&lp);
    if (params) p = *params;
    else wvol_render_params_default(&p);
    memset(&ls, 0, sizeof ls);
    if (lod_stats) memset(lod_stats, 0, sizeof *lod_stats);
    WVOL_RETURN_IF(!source || (source->kind == WVOL_RENDER_SOURCE_VOLUME && !source->volume) ||
                       (source->kind == WVOL_RENDER_SOURCE_STORE && !source->store),
                   err, WVOL_ERR_ARG, "render: no source");
    WVOL_RETURN_IF(source->kind != WVOL_RENDER_SOURCE_VOLUME && source->kind != WVOL_RENDER_SOURCE_STORE, err,
                   WVOL_ERR_ARG, "render: unknown source kind %d", (int)source->kind);
    WVOL_FORWARD(wvol_camera_check(cam, err));
    source_geometry(source, &g, &levels);
    WVOL_RETURN_IF(lp.level < -1 || lp.level > levels, err, WVOL_ERR_ARG,
                   "render: level of detail %d outside 0..%d (the source's levels)", lp.level, levels);
    ls.levels = levels;
    L = wvol_lod_level(cam, &g, levels, &ls.footprint);
    if (lp.level >= 0) L = lp.level;
    else if (!lp.enabled) L = 0;
    if (L > 0 && !lod_applies(source, &p)) L = 0;
    if (L > 0 && source->kind == WVOL_RENDER_SOURCE_STORE && p.method == WVOL_RENDER_METHOD_AUTO &&
        p.mode == WVOL_RENDER_MODE_XRAY) {
        /* the exact axis path where it applies, at full resolution (wvol_render's AUTO order) */
        wvol_error axis_err;
        wvol_render_params ap = p;
        ap.method = WVOL_RENDER_METHOD_AXIS;
        wvol_error_clear(&axis_err);
        s = wvol_render(img, source, cam, tf, &ap, stats, &axis_err);
        if (s != WVOL_ERR_UNSUPPORTED) {
            if (s != WVOL_OK && err) *err = axis_err;
            if (s == WVOL_OK) L = -1;
            else return s;
        }
    }
    if (L == -1) {
        ls.level = 0;
        s = WVOL_OK;
    } else if (L == 0) {
        s = ctx ? wvol_render_context_frame(ctx, img, cam, tf, &p, stats, err)
                : wvol_render(img, source, cam, tf, &p, stats, err);
    } else {
        wvol_error cerr;
        t0 = wvol__now();
        wvol_error_clear(&cerr);
        s = coarse_volume(&coarse, &ls.energy, source, &lp, L, &cerr);
        ls.seconds = wvol__now() - t0;
        if (s == WVOL_ERR_NONFINITE && source->kind == WVOL_RENDER_SOURCE_VOLUME) {
            /* values the transform cannot hold in float32: the full grid, whose renderer says
             * what it makes of them (the level of detail is a saving, never a new failure) */
            L = 0, ls.energy = 0.0;
            s = wvol_render(img, source, cam, tf, &p, stats, err);
        } else if (s != WVOL_OK) {
            if (err) *err = cerr;
        } else {
            csrc = wvol_render_source_volume(coarse);
            p.method = WVOL_RENDER_METHOD_REFERENCE;
            s = wvol_render(img, &csrc, cam, tf, &p, stats, err);
            if (s == WVOL_OK && stats) stats->seconds += ls.seconds; /* the frame's time includes the level's volume */
        }
        ls.level = L;
    }
    if (s == WVOL_OK) {
        wvol_geometry cg;
        if (coarse) wvol_geometry_of_volume(&cg, coarse);
        else cg = g;
        memcpy(ls.dims, cg.dims, sizeof ls.dims);
        ls.voxel = voxel_size(&cg);
        if (ls.voxel == 0) ls.voxel = voxel_size(&g);
        ls.rmse = sqrt(ls.energy / ((double)g.dims[0] * (double)g.dims[1] * (double)g.dims[2]));
        if (lod_stats) *lod_stats = ls;
    }
    wvol_volume_destroy(coarse);
    return s;
}

wvol_status wvol_render_lod(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                            const wvol_tf *tf, const wvol_render_params *params, const wvol_lod_params *lod,
                            wvol_render_stats *stats, wvol_lod_stats *lod_stats, wvol_error *err)
{
    return render_lod(img, source, cam, tf, params, lod, stats, lod_stats, NULL, err);
}

wvol_status wvol_render_lod_context(wvol_render_context *ctx, wvol_image *img, const wvol_camera *cam,
                                    const wvol_tf *tf, const wvol_render_params *params, const wvol_lod_params *lod,
                                    wvol_render_stats *stats, wvol_lod_stats *lod_stats, wvol_error *err)
{
    WVOL_RETURN_IF(!ctx, err, WVOL_ERR_ARG, "render: no context");
    return render_lod(img, wvol_render_context_source(ctx), cam, tf, params ? params : wvol_render_context_params(ctx),
                      lod, stats, lod_stats, ctx, err);
}
