/* SPDX-License-Identifier: MIT
 * Private helpers shared by the render sources (not installed). */
#ifndef WVOL_RENDER_INTERNAL_H
#define WVOL_RENDER_INTERNAL_H

#include "core/clock.h"
#include "wvol/render.h"
#include "core/status_internal.h"

/* The bricked path's brick side by default (wvol_render_params_default, and a 0 the caller
 * leaves). Larger bricks cost less per voxel to reconstruct (the apron and the filters' reach
 * are a smaller share: 34^3 voxels for 32^3 cells against 18^3 for 16^3) and halve a ray's
 * runs, but skip empty space more coarsely; 32 was the fastest side measured
 * (bench/bench_render.py). */
#define WVOL__BRICKS_BRICK_DEFAULT 32

/* A camera with its frame precomputed for ray generation. */
typedef struct wvol__cam {
    wvol_camera c;
    double fwd[3], right[3], up[3];
    double half_w, half_h;    /* ortho: world half extents; persp: tan(fov/2) * aspect, tan(fov/2) */
} wvol__cam;

void wvol__cam_init(wvol__cam *k, const wvol_camera *cam);
void wvol__cam_ray(const wvol__cam *k, double px, double py, double o[3], double d[3]);
/* The pixels whose rays may meet the box [lo, hi] (index r[0] <= x < r[2], r[1] <= y < r[3]):
 * a rectangle holding the projection of the box's corners with two pixels to spare, the whole
 * image when a corner lies at or behind a perspective eye's plane. The rays of the pixels
 * outside it miss the box (the projection of a box is the hull of its corners'), so a caller
 * may skip them without changing anything. */
void wvol__cam_box_pixels(const wvol__cam *k, const double lo[3], const double hi[3], int r[4]);

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

/* Refuses an image with a NaN or Inf pixel, naming the first: a result that leaves float32's
 * range (an X-ray integral beyond 3.4e38, or differences of values near +-FLT_MAX in the
 * float32 interpolation). One pass over the pixels after the render: nothing in the sample
 * loops. Every integrator ends with it (docs/conventions.md, "Supported magnitudes"). */
wvol_status wvol__image_check_range(const wvol_image *img, wvol_error *err);

/* Refuses a skip tolerance > 0 where it is not `supported` (no brick grid to skip by). */
wvol_status wvol__check_skip(const wvol_render_params *p, int supported, wvol_error *err);

/* Per-tile parallel loop helpers. The tile side: params->tile, or for its default (0) the
 * source's preferred side when it has one (a bricked source's tile rays walk its bricks
 * together, ref_bricks.c: as large as the memory bricks.c grants allows),
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

/* Refuses a sampling step below 1e-4 voxels or not finite (what: the caller's name for
 * messages): wvol__render_check's step rule, which a render context checks at creation too. */
wvol_status wvol__render_step_check(double step, const char *what, wvol_error *err);

/* Checks img size against the camera, the camera, the TF (for absorption modes). */
wvol_status wvol__render_check(const wvol_image *img, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *p, wvol_error *err);

/* Sub-cells per axis of a brick (wvol__view.sub_zero): 4-voxel sub-cells in the default
 * 32-voxel bricks, the grain of VTK's fixed-point mapper's min/max volume. */
#define WVOL__SUB_N 8

/* Voxels lo..hi (inclusive, global indices per axis) of a volume or of one brick:
 * voxel (i, j, k) at data[(i - off[0]) + sy (j - off[1]) + sz (k - off[2])]. Trilinear
 * samples clamp to that range. */
typedef struct wvol__view wvol__view;
struct wvol__view {
    const float *data;
    long off[3], lo[3], hi[3];
    double flo[3], fhi[3];  /* lo, hi as doubles (wvol__view_finish) */
    int blocked_ok;         /* offsets and coordinates fit 32 bits (wvol__view_finish) */
    int local;              /* a brick's small view: the blocked loop's positions in single
                               precision relative to it (ref_samples.h, block_positions_local) */
    size_t sy, sz;
    /* A brick's sub-cells (bricks.c; sub_any 0 elsewhere): the brick's voxel cells cut into at
     * most WVOL__SUB_N per axis of sub_S cells each, sub-cell c per axis covering index
     * coordinates [sub_org + c sub_S - 1/2, sub_org + (c + 1) sub_S - 1/2); bit
     * c0 + N c1 + N^2 c2 of sub_zero set when the TF's kappa (X-ray: the value) is 0 over the range of the voxels
     * its samples touch (sub_org + c sub_S - 1 .. sub_org + (c + 1) sub_S). The walk skips the
     * samples that lie in such sub-cells (ref_walk.c): they add exactly nothing. */
    uint64_t sub_zero[WVOL__SUB_N * WVOL__SUB_N * WVOL__SUB_N / 64];
    /* the view shading takes its gradient from (the same voxels of a smoother field:
     * wvol_render_params.gradient_levels), NULL: this one */
    const struct wvol__view *grad;
    int sub_any, sub_S;     /* sub_any: some bit of sub_zero is set */
    double sub_S_inv;       /* 1 / sub_S when sub_S is a power of two (x sub_S_inv is then exactly
                               x / sub_S), else 0 */
    long sub_org[3];
};

void wvol__view_finish(wvol__view *w);

/* ---- what the reference integrator samples (ref_*.c) ------------------------------------ */

/* A source of samples: a table of operations, one per kind of source (a dense volume:
 * ref_view.c; f^ through the spline tables: reference_fhat.c; bricks reconstructed from a
 * store: bricks.c), and the kind's context. Samples are trilinear interpolation of voxels,
 * read from views that the integrator's inlined loops take apart, or (a source without
 * voxels) the kind's eval. Function pointers are called per render (prepare), per run of
 * samples in one brick (fetch), or per sample only where the sample itself is a function
 * evaluation (eval). Bricks are cubes of B^3 voxel cells: brick b covers index coordinates
 * [b B - 1/2, (b + 1) B - 1/2) per axis, and its trilinear samples (and the +-1/2 voxel
 * differences of shading) touch voxels b B - 1 .. (b + 1) B only. */
typedef struct wvol__source wvol__source;

typedef struct wvol__source_ops {
    /* Called once the TF is in world units (tf_world): sets up the brick grid of side s->B
     * (s->bn, and what fetch reads) where the source has one, the per-thread contexts (s->tctx, indexed by
     * omp_get_thread_num()) and s->walk_bytes. What it allocates, the kind's entry point
     * frees after the render. NULL: nothing to prepare. */
    wvol_status (*prepare)(wvol__source *s, const wvol_tf *tf_world, const wvol_render_params *p,
                           wvol_error *err);
    /* Brick b of the grid: *rate, its contribution rate (wvol__brick_rate on its voxels'
     * range, or on a bound of it), and, unless *rate <= allow (the caller then skips the
     * brick), *view, its voxels b B - 1 .. (b + 1) B (clipped to the volume), valid until the
     * thread's next fetch. tctx: the calling thread's context. */
    wvol_status (*fetch)(const wvol__source *s, void *tctx, size_t brick, double allow, const wvol__view **view,
                         double *rate);
    /* The smallest contribution rate of the brick known without building it (thread-safe), or
     * -1 when none is; 0 promises that fetch skips it (a rate of 0 whatever allow). NULL: never
     * known. The walk passes rays through such bricks without queueing them there. */
    double (*known_rate)(const wvol__source *s, size_t brick);
    /* A source without voxels: the value at index position x and, when grad is not NULL,
     * the gradient in index units. NULL: trilinear samples of the views. */
    double (*eval)(const void *ctx, const double x[3], double grad[3]);
    /* 1: a tile's rays walk its bricks together, front to back, the threads sharing the tile
     * (bricks built on demand, each once per tile: ref_bricks.c), or each thread walking tiles
     * of its own where prepare sets walk_own; 0: the threads take tiles, each ray walked on
     * its own. */
    int walk_bricks;
    /* 1: the source honours wvol_render_params.gradient_levels (views with a low-pass
     * gradient field, wvol__view.grad); others refuse it */
    int lowpass_gradient;
} wvol__source_ops;

struct wvol__source {
    const wvol__source_ops *ops;
    void *ctx;              /* the kind's own state */
    size_t n[3];
    double spacing[3], origin[3];
    wvol__view whole;       /* a voxel source's view where no fetch gives one (a dense
                               volume: all of it) */
    int B;                  /* brick side in voxel cells, set by the kind's entry point; 0: no
                               grid (skip_tolerance needs one) */
    double B_inv;           /* 1 / B when B is a power of two (x B_inv is then exactly x / B,
                               a multiplication where the walk divided per axis and run), else
                               0 (set by wvol__render_sampled) */
    double dt_inv;          /* 1 / the step in world units (set by wvol__render_sampled): the
                               walk's first guesses of a step index, which it then corrects */
    size_t bn[3];           /* bricks per axis (prepare) */
    void **tctx;            /* per-thread contexts (prepare), or NULL */
    size_t walk_bytes;      /* prepare(): bytes for a tile's rays (their states and lists;
                               the tile is the largest that fits; the threads share it), 0: no
                               preference */
    int walk_own;           /* prepare(): 1 when the threads may walk tiles of their own rather
                               than share each tile (ref_tiles.c): the bricks the frame needs
                               are kept built, so a shared tile would share no builds */
};

/* The contribution rate of a brick whose samples lie in [mn, mx]: the largest kappa of the
 * TF (world units) over that range, or (X-ray) the largest |sample|. 0: the brick adds
 * nothing. A sample of step h adds at most rate h to the ray's optical depth (X-ray: to its
 * integral, in absolute value), so skipping a run of length len in it changes the pixel by
 * at most rate len (wvol_render_params.skip_tolerance). */
double wvol__brick_rate(const wvol_tf *tf, wvol_render_mode mode, double mn, double mx);

/* The bricked path's state (bricks.c): the store's block view and bounds, the per-brick rates
 * (kept while the TF's kappa and the mode stay the same), the threads' brick caches and, with
 * cache_bytes > 0, a cache of built bricks shared by the threads and kept across frames
 * (at most cache_bytes of voxels). wvol_render_bricks makes one per call (cache_bytes 0); a
 * render context keeps one (context.c). The store must outlive it. A frame's image does not
 * depend on what the state holds: it is the one-shot frame's bit for bit. */
typedef struct wvol__bricks wvol__bricks;
wvol_status wvol__bricks_create(wvol__bricks **out, const wvol_store *st, const wvol_render_params *p,
                                size_t cache_bytes, wvol_error *err);
/* 1 when the state serves frames of st with p: the same store, threads, brick side, sub-cell
 * skipping and low-pass gradient levels (the rest of p may change from frame to frame). */
int wvol__bricks_fits(const wvol__bricks *b, const wvol_store *st, const wvol_render_params *p);
/* One frame (wvol_render_bricks' contract); stats->cpu_seconds includes the set-up once, in
 * the first frame after create. */
wvol_status wvol__bricks_frame(wvol__bricks *b, wvol_image *img, const wvol_camera *cam, const wvol_tf *tf,
                               const wvol_render_params *p, wvol_render_stats *stats, wvol_error *err);
size_t wvol__bricks_bytes(const wvol__bricks *b);       /* all it holds */
size_t wvol__bricks_cache_bytes(const wvol__bricks *b); /* the shared cache's bricks */
void wvol__bricks_destroy(wvol__bricks *b);             /* NULL is fine */

/* wvol_render with a context (NULL: none): the same method chosen, the bricked method through
 * the context's kept state (render.c). */
wvol_status wvol__render_dispatch(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                                  const wvol_tf *tf, const wvol_render_params *params, wvol_render_stats *stats,
                                  wvol_render_context *ctx, wvol_error *err);
/* The bricked method through the context's state, made (again) when missing or made for other
 * settings (context.c). */
wvol_status wvol__context_bricks(wvol_render_context *ctx, wvol_image *img, const wvol_store *st,
                                 const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *p,
                                 wvol_render_stats *stats, wvol_error *err);

/* The reference integrator (ref_tiles.c) on a source. */
wvol_status wvol__render_sampled(wvol_image *img, wvol__source *s, const wvol_camera *cam, const wvol_tf *tf,
                                 const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err);

#endif
