/* Private helpers shared by the render sources (not installed). */
#ifndef WVOL_RENDER_INTERNAL_H
#define WVOL_RENDER_INTERNAL_H

#include "wvol/render.h"

/* A camera with its frame precomputed for ray generation. */
typedef struct wvol__cam {
    wvol_camera c;
    double fwd[3], right[3], up[3];
    double half_w, half_h;    /* ortho: world half extents; persp: tan(fov/2) * aspect, tan(fov/2) */
} wvol__cam;

void wvol__cam_init(wvol__cam *k, const wvol_camera *cam);
void wvol__cam_ray(const wvol__cam *k, double px, double py, double o[3], double d[3]);

/* Slab test of the line o + t d against the box [lo, hi]: 1 and [*t0, *t1] (t0 < t1) when
 * the line crosses the box's interior, else 0. Parallel components outside the slab miss. */
int wvol__ray_box(const double o[3], const double d[3], const double lo[3], const double hi[3], double *t0,
                  double *t1);

/* The TF resolved for one volume: kappa in per-world-unit. */
void wvol__tf_world(wvol_tf *out, const wvol_tf *tf, const wvol_geometry *g);

/* Checks params->colors (if set) against a grid of n voxels; `supported` is 0 for methods
 * that cannot use a colour volume (they refuse it rather than ignore it). */
wvol_status wvol__check_colors(const wvol_render_params *p, const size_t n[3], int supported, wvol_error *err);

/* Per-tile parallel loop helpers. */
int wvol__tiles(int width, int height, int tile);

/* Shading factor for a normalised gradient and the view direction (headlight). */
double wvol__shade(const double grad[3], const double dir[3], double ambient);

/* Fills defaults for a NULL params. */
void wvol__params(wvol_render_params *out, const wvol_render_params *in);

/* Checks img size against the camera, the camera, the TF (for absorption modes). */
wvol_status wvol__render_check(const wvol_image *img, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *p, wvol_error *err);

/* What the reference integrator samples: a dense volume (trilinear) or a callback. */
typedef struct wvol__sampler {
    const wvol_volume *v;                                             /* trilinear, or NULL */
    double (*eval)(const void *ctx, const double x[3], double grad[3]); /* index coords; grad in index units */
    const void *ctx;
    size_t n[3];
    double spacing[3], origin[3];
    int B;                  /* brick grid, filled by the integrator */
    size_t bn[3];
    unsigned char *empty;
} wvol__sampler;

wvol_status wvol__render_sampled(wvol_image *img, wvol__sampler *s, const wvol_camera *cam, const wvol_tf *tf,
                                 const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err);

/* Monotonic seconds; OpenMP thread count for a requested count (0 = default). */
double wvol__now(void);
double wvol__cpu_now(void);
int wvol__threads(int requested);

#endif
