/* Private helpers shared by the render sources (not installed). */
#ifndef WVOL_RENDER_INTERNAL_H
#define WVOL_RENDER_INTERNAL_H

#include "wvol/render.h"
#include "core/status_internal.h"

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

/* The counters an integrator reduces over its threads; wvol__stats_fill writes them with
 * the times since t_start / c_start (wvol__now, wvol__cpu_now) and the ray count into
 * *stats (NULL: nothing), every other field 0. */
typedef struct wvol__counts {
    size_t rays_hit, samples, pieces, functions, skipped, skipped_tolerance, terminated, clamped;
    double skip_bound;
    size_t bytes;           /* what the walk allocated (stats->bytes) */
} wvol__counts;
void wvol__stats_fill(wvol_render_stats *stats, const wvol_image *img, double t_start, double c_start,
                      const wvol__counts *c);

/* Refuses a skip tolerance > 0 where it is not `supported` (no brick grid to skip by). */
wvol_status wvol__check_skip(const wvol_render_params *p, int supported, wvol_error *err);

/* Per-tile parallel loop helpers. The tile side: params->tile, or for its default (0) the
 * source's preferred side when it has one (a bricked source's tile rays walk its bricks
 * together, render_tile_bricked in reference.c: as large as the memory bricks.c grants allows),
 * else 16. */
int wvol__tile_side(const wvol_render_params *p, int preferred);
int wvol__tiles(int width, int height, int tile);
/* The tiles (index x + tiles_x * y) in Z order (Morton), so that consecutive tiles are
 * neighbours and share the bricks they read; malloc'ed, NULL when out of memory. */
int *wvol__tile_order(int width, int height, int tile);

/* Shading factor for a normalised gradient and the view direction (headlight). */
double wvol__shade(const double grad[3], const double dir[3], double ambient);

/* Fills defaults for a NULL params. */
void wvol__params(wvol_render_params *out, const wvol_render_params *in);

/* Checks img size against the camera, the camera, the TF (for absorption modes). */
wvol_status wvol__render_check(const wvol_image *img, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *p, wvol_error *err);

/* Voxels lo..hi (inclusive, global indices per axis) of a volume or of one brick:
 * voxel (i, j, k) at data[(i - off[0]) + sy (j - off[1]) + sz (k - off[2])]. Trilinear
 * samples clamp to that range. */
typedef struct wvol__view {
    const float *data;
    long off[3], lo[3], hi[3];
    double flo[3], fhi[3];  /* lo, hi as doubles (wvol__view_finish) */
    int blocked_ok;         /* offsets and coordinates fit 32 bits (wvol__view_finish) */
    int local;              /* a brick's small view: the blocked loop's positions in single
                               precision relative to it (reference.c, block_positions_local) */
    size_t sy, sz;
} wvol__view;

void wvol__view_finish(wvol__view *w);

/* What the reference integrator samples: trilinear interpolation of voxels, from a dense
 * volume (v, whole) or a bricked source (fetch), or a callback (eval). Bricks are cubes of
 * B^3 voxel cells: brick b covers index coordinates [b B - 1/2, (b + 1) B - 1/2) per axis,
 * and its trilinear samples (and the +-1/2 voxel differences of shading) touch voxels
 * b B - 1 .. (b + 1) B only. */
typedef struct wvol__sampler {
    const wvol_volume *v;                                             /* dense, or NULL */
    wvol__view whole;                                                 /* dense: all of v */
    double (*eval)(const void *ctx, const double x[3], double grad[3]); /* index coords; grad in index units */
    const void *ctx;
    /* bricked source: prepare() (called once the TF is in world units) sets B, bn and tctx
     * (one context per thread, indexed by omp_get_thread_num()); fetch() sets *rate to brick
     * b's contribution rate (wvol__brick_rate on its voxels' range, or on a bound of it) and,
     * unless *rate <= allow (the caller then skips the brick), *view to its voxels
     * b B - 1 .. (b + 1) B (clipped to the volume): the thread's cached view, valid until the
     * thread's next fetch. */
    wvol_status (*prepare)(struct wvol__sampler *s, const wvol_tf *tf_world, const wvol_render_params *p,
                           wvol_error *err);
    wvol_status (*fetch)(void *tctx, size_t brick, double allow, const wvol__view **view, double *rate);
    void **tctx;
    void *src;              /* the bricked source's own state */
    size_t n[3];
    double spacing[3], origin[3];
    int B;                  /* brick grid: filled by the integrator (dense) or prepare() */
    size_t walk_bytes;      /* prepare(): bytes for a tile's rays (their states and lists;
                               the tile is the largest that fits; the threads share it), 0: no
                               preference */
    size_t bn[3];
    double *rate;           /* dense: each brick's wvol__brick_rate; freed by the integrator */
} wvol__sampler;

/* The contribution rate of a brick whose samples lie in [mn, mx]: the largest kappa of the
 * TF (world units) over that range, or (X-ray) the largest |sample|. 0: the brick adds
 * nothing. A sample of step h adds at most rate h to the ray's optical depth (X-ray: to its
 * integral, in absolute value), so skipping a run of length len in it changes the pixel by
 * at most rate len (wvol_render_params.skip_tolerance). */
double wvol__brick_rate(const wvol_tf *tf, wvol_render_mode mode, double mn, double mx);

wvol_status wvol__render_sampled(wvol_image *img, wvol__sampler *s, const wvol_camera *cam, const wvol_tf *tf,
                                 const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err);

/* Monotonic seconds; OpenMP thread count for a requested count (0 = default). */
double wvol__now(void);
double wvol__cpu_now(void);
int wvol__threads(int requested);

#endif
