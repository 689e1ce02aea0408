/* SPDX-License-Identifier: MIT */
/* Progressive rendering with per-pixel error bounds (docs/render.md, "Progressive rendering").
 *
 * The volume is transformed once; pass k renders from the largest n_k coefficients (the
 * low-pass cube alone first, then growth times more each pass, largest |c| first: the energy
 * order) and, with its image, the bound on how far that image can be from the image of all
 * the coefficients (wvol_render_bound). Passes stop at a bound the caller gives, at a time
 * budget, or when everything is kept. An iterator, so that a caller (the CLI, Python's
 * generator) shows each pass as it comes.
 *
 * Threading: one wvol_progressive is used by one thread at a time; the calls use OpenMP
 * threads inside. */
#ifndef WVOL_PROGRESSIVE_H
#define WVOL_PROGRESSIVE_H

#include "wvol/compress.h"
#include "wvol/export.h"
#include "wvol/image.h"
#include "wvol/render.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct wvol_progressive_params {
    double max_error;   /* > 0: the pass whose bound (largest colour channel over the image)
                           is <= this is the last; 0 (default): no target */
    double seconds;     /* > 0: wall-clock budget from wvol_progressive_begin: a pass is the last
                           when the next one (predicted: this one's time times growth) would
                           end beyond it; 0 (default): none */
    double growth;      /* kept coefficients multiplied by this each pass, > 1 (default 4) */
    wvol_bound_method bound; /* each pass's bound: WVOL_BOUND_EXACT (default), _COARSE (any camera
                           at O(1) a pixel) or _NONE; max_error needs one */
} wvol_progressive_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_progressive_params_default(wvol_progressive_params *p);

typedef struct wvol_progressive_pass {
    int index;              /* 0, 1, ... */
    size_t kept, total;     /* coefficients kept (low-pass cube included) of all */
    double bound_max, bound_mean;   /* the pass's bound (0 without one) */
    double seconds;         /* this pass: selection, stores, render, bound */
    double elapsed;         /* since wvol_progressive_begin (its transform included) */
    wvol_render_method method;      /* what rendered the image */
    int last;               /* 1: no pass follows */
    const char *stop;       /* when last: "max-error", "budget" or "complete"; else "" */
} wvol_progressive_pass;

typedef struct wvol_progressive wvol_progressive;

/* Transforms v with cp (family, levels, spline knots; its selection is ignored: the passes
 * choose theirs). pp NULL: defaults. Refuses bad parameters (growth <= 1, a negative or
 * non-finite target or budget, max_error without bound) with WVOL_ERR_ARG. */
WVOL_API wvol_status wvol_progressive_begin(wvol_progressive **out, const wvol_volume *v,
                                            const wvol_compress_params *cp, const wvol_progressive_params *pp,
                                            wvol_error *err);

/* Renders the next pass into img (and its bound into `bound`, which may be NULL without
 * pp.bound; same size as img). After the last pass: WVOL_ERR_ARG. The camera, TF and render
 * parameters may change between passes. */
WVOL_API wvol_status wvol_progressive_next(wvol_progressive *pr, wvol_image *img, wvol_image *bound,
                                           const wvol_camera *cam, const wvol_tf *tf,
                                           const wvol_render_params *rp, wvol_progressive_pass *pass,
                                           wvol_error *err);

WVOL_API void wvol_progressive_end(wvol_progressive *pr); /* NULL is fine */

#ifdef __cplusplus
}
#endif

#endif
