/* SPDX-License-Identifier: MIT */
/* Level of detail by screen size (docs/render.md, "Level of detail").
 *
 * A frame of a volume much larger than the image renders from the wavelet level whose voxel
 * matches the pixel footprint: the level-L low-pass volume (wvol_idwt3_level's grid: 2^L times
 * coarser, spacing 2^L times larger, origin on the level's scaling-function centres, so its
 * image lines up with the full one), whose extra error is the energy of the dropped detail
 * levels 1..L (Parseval: the drop_levels figure). The choice is made in one place,
 * wvol_lod_level; wvol_render_lod applies it to a frame (the CLI's `wvol render` and Python's
 * wvol.render call it; --full-resolution / lod=False turn it off).
 *
 * Threading: as wvol_render. */
#ifndef WVOL_LOD_H
#define WVOL_LOD_H

#include "wvol/export.h"
#include "wvol/render.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The coarsest level L in 0..levels whose voxel still fits the pixel footprint:
 * 2^L * (largest spacing of a transformed axis, dims > 1) <= footprint (to a relative 1e-9,
 * so an exact 2:1 ratio gives level 1). The footprint, in world units, is the pixel's size:
 * orthographic, view_height / height (pixels are square); perspective, 2 d tan(fov_y / 2) /
 * height at the distance d from the eye to the nearest point of the volume's box
 * (wvol_geometry_bounds; 0 with the eye inside it, giving level 0): the finest footprint any
 * part of the volume is seen with. *footprint (may be NULL) receives it. The camera must have
 * passed wvol_camera_check; levels < 0 reads as 0. */
WVOL_API int wvol_lod_level(const wvol_camera *cam, const wvol_geometry *g, int levels, double *footprint);

typedef struct wvol_lod_params {
    int enabled;                 /* 1: choose the level by screen size; 0: full resolution */
    const wvol_filter *filter;   /* a dense volume's family for its coarser levels (NULL: db2) */
    int level;                   /* >= 0 with enabled = 0: this level exactly (0 = full
                                    resolution); -1 (default) for the screen-size choice when
                                    enabled */
} wvol_lod_params;

/* enabled 1, filter NULL, level -1. NULL: does nothing. */
WVOL_API void wvol_lod_params_default(wvol_lod_params *p);

typedef struct wvol_lod_stats {
    int level;                   /* the level rendered (0: full resolution) */
    int levels;                  /* the largest level the source allowed */
    double footprint;            /* the pixel footprint (world units; wvol_lod_level) */
    double voxel;                /* the voxel size of the level rendered (largest spacing) */
    size_t dims[3];              /* the grid rendered */
    double energy;               /* sum c^2 of the dropped detail levels 1..level */
    double rmse;                 /* sqrt(energy / voxels of the original grid) */
    double seconds;              /* wall time spent forming the coarser volume */
} wvol_lod_stats;

/* wvol_render of one frame with the level of detail chosen by wvol_lod_level (or lod->level).
 * It applies to the sampling methods on the source's grid: params->method AUTO (a store in
 * X-ray mode tries the exact axis path first, which costs O(kept + pixels) and keeps full
 * resolution where it applies), REFERENCE on a dense volume and BRICKS on a store, with no
 * colour volume and no gradient_levels (both live on the original grid); other methods, and a
 * level of 0, render exactly as wvol_render does (bit for bit). At a level L > 0 the frame is
 * wvol_render_reference of the level-L volume (a store: wvol_store_level_volume, which from a
 * file decodes only the chunks of the levels above L; a dense volume: wvol_volume_level with
 * lod->filter), the same samples, step (in voxels of the coarser grid) and compositing;
 * stats->method says REFERENCE and stats->seconds includes forming the level's volume. lod
 * NULL: wvol_lod_params_default; lod_stats may be NULL. A dense volume whose transform would
 * overflow float32 renders the full grid (level 0). A level outside 0..the source's levels is
 * refused (WVOL_ERR_ARG). The level's volume is held for the frame: a file's level-L grid
 * costs its samples (n / 2^L per axis, float32) besides the file's chunk cache. */
WVOL_API wvol_status wvol_render_lod(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                                     const wvol_tf *tf, const wvol_render_params *params,
                                     const wvol_lod_params *lod, wvol_render_stats *stats,
                                     wvol_lod_stats *lod_stats, wvol_error *err);

/* wvol_render_lod with the context's source (and params when params is NULL): a frame at full
 * resolution goes through the context (wvol_render_context_frame: its set-up kept), a coarser
 * level renders as wvol_render_lod does. */
WVOL_API wvol_status wvol_render_lod_context(wvol_render_context *ctx, wvol_image *img, const wvol_camera *cam,
                                             const wvol_tf *tf, const wvol_render_params *params,
                                             const wvol_lod_params *lod, wvol_render_stats *stats,
                                             wvol_lod_stats *lod_stats, wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
