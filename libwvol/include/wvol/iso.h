/* SPDX-License-Identifier: MIT
 * Isosurfaces: marching cubes on dense volumes (flying-edges passes), triangle
 * meshes (measures, topology checks, PLY/OBJ/STL/VTP output), and guaranteed ray
 * tracing of the implicit surface f^ = iso of a coefficient store (DESIGN.md section 9).
 *
 * Conventions. A sample is "positive" when f >= iso. Meshes carry world
 * coordinates (origin + index * spacing). Triangles are wound so that their
 * right-hand normal points from the positive side (f >= iso) to the negative
 * side (f < iso), i.e. along -grad f; vertex normals point the same way. For a
 * bright blob (a Gaussian, bone in CT) that is outward and the signed enclosed
 * volume is positive.
 *
 * Threading: the functions here take const inputs and may run concurrently;
 * each extraction uses up to `threads` OpenMP threads internally. */
#ifndef WVOL_ISO_H
#define WVOL_ISO_H

#include "wvol/export.h"
#include <stddef.h>
#include <stdint.h>
#include "wvol/image.h"
#include "wvol/render.h"
#include "wvol/status.h"
#include "wvol/store.h"
#include "wvol/volume.h"
#include "wvol/wavelet.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A triangle mesh owned by the library (free with wvol_mesh_destroy). */
typedef struct wvol_mesh {
    size_t nverts, ntris;
    float *verts;    /* nverts * 3, world coordinates */
    float *normals;  /* nverts * 3 unit normals, or NULL when not computed */
    uint32_t *tris;  /* ntris * 3 vertex indices */
} wvol_mesh;

/* Allocates a mesh with room for exactly nverts / ntris (normals if with_normals). */
WVOL_API wvol_status wvol_mesh_create(wvol_mesh **out, size_t nverts, size_t ntris, int with_normals,
                                      wvol_error *err);
WVOL_API void wvol_mesh_destroy(wvol_mesh *m); /* NULL is fine */

/* Surface area (float64 accumulation). Both measures give NaN for a mesh whose arrays are
 * missing or whose triangles name vertices it does not have, and 0 for NULL. */
WVOL_API double wvol_mesh_area(const wvol_mesh *m);
/* Signed enclosed volume by the divergence theorem: positive when the mesh is
 * closed and wound as above around a region of f >= iso. Meaningful only for a
 * closed mesh (see wvol_mesh_topology). */
WVOL_API double wvol_mesh_volume(const wvol_mesh *m);
/* Axis-aligned bounds of the vertices; lo/hi untouched for an empty mesh. */
WVOL_API void wvol_mesh_bounds(const wvol_mesh *m, double lo[3], double hi[3]);

/* Combinatorial checks on the index structure (positions are not compared). */
typedef struct wvol_mesh_topo {
    size_t edges;              /* distinct undirected edges */
    size_t boundary_edges;     /* edges used by one triangle */
    size_t nonmanifold_edges;  /* edges used by more than two triangles */
    size_t misoriented_edges;  /* edges used twice in the same direction */
    size_t nonmanifold_verts;  /* vertices whose triangle fan is not one disc or half-disc */
    size_t degenerate_tris;    /* triangles repeating a vertex index */
    size_t unused_verts;       /* vertices no triangle uses */
    size_t components;         /* connected components (through shared vertices) */
    long long euler;           /* V - E + F over used vertices */
    int watertight;            /* 1: no boundary, non-manifold or misoriented edge, no bad vertex */
} wvol_mesh_topo;

WVOL_API wvol_status wvol_mesh_topology(const wvol_mesh *m, wvol_mesh_topo *out, wvol_error *err);

/* Writes a mesh; the format follows the extension: .ply (binary little-endian,
 * with normals when present), .obj (text), .stl (binary, facet normals from the
 * triangles), .vtp (VTK XML PolyData, through the VTK adapter when built; else
 * WVOL_ERR_UNSUPPORTED). The file is written to a temporary name and renamed. */
WVOL_API wvol_status wvol_mesh_save(const wvol_mesh *m, const char *path, wvol_error *err);
WVOL_API wvol_status wvol_mesh_write_ply(const wvol_mesh *m, const char *path, wvol_error *err);
WVOL_API wvol_status wvol_mesh_write_obj(const wvol_mesh *m, const char *path, wvol_error *err);
WVOL_API wvol_status wvol_mesh_write_stl(const wvol_mesh *m, const char *path, wvol_error *err);
WVOL_API wvol_status wvol_mesh_write_vtp(const wvol_mesh *m, const char *path, wvol_error *err);
/* Reads a binary little-endian PLY as written by wvol_mesh_write_ply (vertices
 * x y z [nx ny nz] float, faces as uchar count + int/uint indices). */
WVOL_API wvol_status wvol_mesh_read_ply(wvol_mesh **out, const char *path, wvol_error *err);

/* ---- extraction -------------------------------------------------------------- */

typedef enum wvol_iso_normals {
    WVOL_ISO_NORMALS_NONE = 0,      /* no vertex normals */
    WVOL_ISO_NORMALS_GRADIENT = 1,  /* -grad f by central differences on the grid (one-sided at
                                       borders), interpolated along the edge like the position */
    WVOL_ISO_NORMALS_ANALYTIC = 2   /* -grad from params.gradient at the vertex's world position */
} wvol_iso_normals;
/* Deprecated names, removed after 0.1 (docs/conventions.md). */
#define WVOL_NORMALS_NONE WVOL_ISO_NORMALS_NONE
#define WVOL_NORMALS_GRADIENT WVOL_ISO_NORMALS_GRADIENT
#define WVOL_NORMALS_ANALYTIC WVOL_ISO_NORMALS_ANALYTIC

typedef struct wvol_iso_params {
    int threads;                /* 0: OpenMP's default; otherwise at most this many */
    wvol_iso_normals normals;   /* default WVOL_ISO_NORMALS_GRADIENT */
    /* For WVOL_ISO_NORMALS_ANALYTIC: gradient of the field at a world position.
     * Called concurrently from several threads. */
    void (*gradient)(void *user, const double xyz[3], double grad[3]);
    void *gradient_user;
    int brick;                  /* coefficient path: cells per brick edge (default 32) */
} wvol_iso_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_iso_params_default(wvol_iso_params *p);

typedef struct wvol_iso_stats {
    int empty;                  /* 1 when the mesh is empty; message says why */
    char message[256];          /* e.g. iso-value outside the data range [min, max] */
    double data_min, data_max;  /* range of the samples (filled when empty) */
    double seconds[4];          /* classify, count, generate, total */
    size_t cells_active;        /* cells the surface passes through */
    /* coefficient path */
    size_t bricks_total, bricks_skipped, bricks_meshed;
    double seconds_bounds, seconds_reconstruct;
    /* from a store opened on a .wvc file: 1 when the bricks to mesh were read from the whole
     * inverse transform of the file decoded whole (made when their own reconstructions would
     * have taken more coefficient positions than the pyramid holds, and the file's budget had
     * room for the pyramid and the file) */
    int whole_inverse;
} wvol_iso_stats;

/* Marching cubes on a dense volume at iso-value `iso` (flying-edges passes:
 * classify x-rows into bit masks, count per row, prefix sums, then write each
 * vertex once per intersected edge and each triangle once, in a deterministic
 * order independent of the thread count). Ambiguous faces follow one fixed rule
 * (positive corners separated), so a surface that does not touch the volume's
 * border comes out closed and manifold. An iso-value that the data never crosses
 * (iso <= min or iso > max) gives an empty mesh, status OK, stats->empty = 1 and
 * a message. NaN/Inf next to the surface gives WVOL_ERR_NONFINITE. p and stats
 * may be NULL. */
WVOL_API wvol_status wvol_iso_extract(wvol_mesh **out, const wvol_volume *v, double iso,
                                      const wvol_iso_params *p, wvol_iso_stats *stats, wvol_error *err);

/* Marching cubes on the reconstruction of wavelet coefficients c (dropped
 * coefficients zeroed, e.g. by wvol_selection_apply), brick by brick: bricks of
 * p->brick^3 cells whose rigorous value bound (from the coefficients alone) does
 * not straddle iso are skipped without reconstruction; the others are rebuilt
 * with wvol_idwt3_brick, meshed, and stitched by global edge ids (no duplicate
 * vertices, no cracks). The mesh equals wvol_iso_extract on wvol_idwt3(c) up to
 * the float rounding of the two reconstructions. stats report bricks skipped. */
WVOL_API wvol_status wvol_iso_extract_coeffs(wvol_mesh **out, const wvol_coeffs *c, double iso,
                                             const wvol_iso_params *p, wvol_iso_stats *stats, wvol_error *err);

/* wvol_iso_extract_coeffs from a store: the bricks whose bound (from the kept coefficients
 * alone) straddles iso are reconstructed from the store's kept coefficients, as the bricked
 * renderer reconstructs its bricks (the dense coefficients are never formed), meshed and
 * stitched. The mesh is wvol_iso_extract_coeffs's on wvol_store_densify(s), exactly: the
 * same vertices, normals and triangles in the same order. Where the bound does not apply
 * (a store without transformed levels) every brick is reconstructed. A store opened on a .wvc
 * file decides its bricks from the file's index first: where those would cost more to
 * reconstruct one by one than the whole inverse transform (a noisy volume, long filters) and
 * the budget has room for the whole pyramid and the file, the file is decoded whole and the
 * bricks are read from its inverse transform (stats->whole_inverse; when the index leaves every
 * brick, wvol_iso_extract on it: the mesh of the file decoded whole); the same mesh as the
 * bricks' up to the float rounding of the two reconstructions. */
WVOL_API wvol_status wvol_iso_extract_store(wvol_mesh **out, const wvol_store *s, double iso,
                                   const wvol_iso_params *p, wvol_iso_stats *stats, wvol_error *err);

/* ---- ray tracing the implicit surface f^ = iso of a store (Kalra-Barr) ---------- */

/* Along a ray, f^ is an exact polynomial of degree <= 9 on each piece of the finest spline
 * lattice, built from the kept basis functions whose support the ray crosses (as the spline
 * integrator does). Pieces are searched front to back: Bernstein coefficients discard
 * intervals whose convex hull excludes iso, intervals are halved until a single sign change
 * of the coefficients guarantees exactly one crossing, which bisection refines.
 * Guarantee: the hit is the first crossing of f^ = iso (a change of the class f^ >= iso)
 * along the ray inside the sample extent [0, n-1] of every transformed axis, at depth within
 * tolerance/2, except that two crossings closer together than tolerance/8 may be skipped
 * (a "graze", counted); see docs/iso.md. Haar's f^ jumps at voxel faces: a jump across iso
 * is a crossing at the face. */
/* Which surface wvol_iso_render_hybrid draws behind the volume. */
typedef enum wvol_iso_surface {
    WVOL_ISO_SURFACE_EXACT = 0, /* f^ = iso, the exact tracer (default) */
    WVOL_ISO_SURFACE_CAST = 1   /* the trilinear interpolant of the store's reconstruction (wvol_iso_cast) */
} wvol_iso_surface;

typedef struct wvol_iso_trace_params {
    double tolerance;   /* depth accuracy in world units; <= 0: 1e-3 of the smallest spacing */
    double chunk;       /* ray segment built at a time, voxels (default 16): a ray stops building
                           at the chunk of its first hit */
    int threads;        /* 0: OpenMP's default */
    double light[3];    /* direction towards the light (world); all 0: a headlight */
    float color[3];     /* albedo */
    float ambient;      /* in [0, 1] */
    wvol_iso_surface surface; /* wvol_iso_render_hybrid only (default EXACT) */
} wvol_iso_trace_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_iso_trace_params_default(wvol_iso_trace_params *p);

typedef struct wvol_iso_hit {
    int hit;            /* 1 when the ray meets f^ = iso inside the extent */
    double t;           /* world distance from the origin along the unit direction (+inf: miss) */
    double pos[3];      /* world position */
    double normal[3];   /* unit -grad f^ (world), pointing towards f^ < iso (0 where grad f^ = 0) */
    double value;       /* f^ at the hit */
    size_t functions;   /* basis-function / ray-chunk pairs added */
    size_t pieces;      /* polynomial pieces built */
    size_t refined;     /* pieces the small functions' bound left undecided, made exact */
    size_t intervals;   /* Bernstein intervals examined */
    int evals;          /* polynomial evaluations (bisection and undecided intervals) */
    int grazes;         /* intervals shorter than the tolerance left without a sign change */
} wvol_iso_hit;

/* The first crossing of f^ = iso along o + t d, t >= 0 (world; d need not be unit; t is then
 * in world units along the unit direction). */
WVOL_API wvol_status wvol_iso_trace_ray(const wvol_store *s, double iso, const double o[3], const double d[3],
                                        const wvol_iso_trace_params *p, wvol_iso_hit *hit, wvol_error *err);

typedef struct wvol_iso_trace_stats {
    size_t rays, hits, functions, pieces, refined, intervals, evals, grazes;
    double seconds, cpu_seconds;
    double seconds_cells;   /* thread seconds spent classifying cells of the grid (lazily, by the
                               rays that reach them: part of the rays' time) */
    size_t cells, cells_undecided; /* cells classified (all levels); finest cells left undecided */
    char message[256];  /* set when nothing is hit (e.g. iso outside the range of f^) */
} wvol_iso_trace_stats;

/* Traces one ray per pixel of cam (the renderer's rays: wvol_camera_ray; orthographic rays
 * are whole lines, perspective ones start at the eye). img (the camera's size) receives the
 * Lambert-shaded albedo (two-sided) with alpha 1 on a hit, 0 elsewhere; depth (w*h floats,
 * +inf on a miss) the ray parameter t of the hit; normals (w*h*3) the unit normals. depth and
 * normals may be NULL. Nothing hit is not an error: stats->message says why. */
WVOL_API wvol_status wvol_iso_raytrace(wvol_image *img, float *depth, float *normals, const wvol_store *s,
                                       const wvol_camera *cam, double iso, const wvol_iso_trace_params *p,
                                       wvol_iso_trace_stats *stats, wvol_error *err);

/* The paper's Fig. 15: the opaque surface f^ = iso composited behind the translucent volume in
 * front of it. Per pixel the surface is traced (wvol_iso_raytrace), the spline integrator runs
 * from the box's entry to the surface's depth (wvol_render_spline_until) with tf and rp, and
 * the shaded surface is added with the remaining transmittance. depth (may be NULL) receives
 * the surface depth. With tp->surface == WVOL_ISO_SURFACE_CAST the surface comes from
 * wvol_iso_cast on the store (tp's threads, light, colour and ambient; its default tolerance
 * and bricks); tstats then reports rays, hits, seconds and cpu_seconds. */
WVOL_API wvol_status wvol_iso_render_hybrid(wvol_image *img, float *depth, const wvol_store *s, const wvol_camera *cam,
                                            const wvol_tf *tf, double iso, const wvol_render_params *rp,
                                            const wvol_iso_trace_params *tp, wvol_iso_trace_stats *tstats,
                                            wvol_render_stats *rstats, wvol_error *err);


/* ---- casting the trilinear interpolant, brick by brick (Parker et al. 1998, Marmitt et al. 2004) */

/* The surface interp(x) = iso of the trilinear interpolant of a volume's samples, or of the
 * samples a store reconstructs (never formed whole: bricks of `brick`^3 cells are rebuilt on
 * demand from the store's kept coefficients, as marching cubes from a store does, the first
 * time a ray reaches one whose rigorous coefficient bound straddles iso). Rays walk the bricks,
 * then groups of 4^3 cells, then cells, front to back, skipping every brick, group and cell
 * whose samples' min/max exclude iso (a trilinear cell lies between its corners' min and max),
 * and find in each remaining cell the exact first crossing of its cubic along the ray: the
 * roots of its derivative split the cell's interval into monotone parts, the first part whose
 * end changes class holds the crossing, which bisection refines to `tolerance`.
 * Guarantee (docs/iso.md): the hit is the first change of the class interp >= iso along the ray
 * inside the sample extent [0, n-1] after the ray's entry (a ray entering inside the surface,
 * where a face cuts it, reports where it leaves it: the mesh's back face), at depth within
 * `tolerance`, up to float64 rounding of the cubic (|interp - iso| below ~1e-12 of the corner
 * magnitudes). Perspective rays start at the eye, orthographic ones are whole lines. */
typedef struct wvol_iso_cast_params {
    int threads;        /* 0: OpenMP's default */
    int brick;          /* cells per brick edge, 4..1024 (default 32) */
    double tolerance;   /* depth accuracy in voxels (default 1e-5) */
    double light[3];    /* direction towards the light (world); all 0: a headlight */
    float color[3];     /* albedo */
    float ambient;      /* in [0, 1] */
    int model_bound;    /* 1: from a store, also bound |f^ - interp| per built brick (stats; costs a
                           query of the functions touching each brick and a halo of samples) */
} wvol_iso_cast_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_iso_cast_params_default(wvol_iso_cast_params *p);

typedef struct wvol_iso_cast_stats {
    size_t rays, hits;
    size_t bricks_total;        /* bricks of the grid */
    size_t bricks_bound;        /* skipped by the coefficient bound alone, never reconstructed */
    size_t bricks_built;        /* reconstructed (or copied from the volume) on demand */
    size_t cells_tested;        /* cells whose cubic was examined */
    size_t bytes;               /* bricks and tables allocated */
    double seconds;             /* the whole call: bounds, bricks and rays */
    double seconds_bounds;      /* of seconds: the store's block view and bounds */
    double seconds_build;       /* thread-seconds spent building bricks (summed over threads) */
    int threads;                /* threads used */
    /* from a store: the bound of |f^ - interp| per built brick (f^ the wavelet model, interp the
     * trilinear interpolant of the reconstruction; the largest of its groups of 4^3 cells'
     * bounds; docs/iso.md): its max and mean over the bricks
     * where it applies, their count, and the bricks whose sample window a face clips (the model
     * reaches across the periodic wrap there: no bound) */
    double fhat_bound_max, fhat_bound_mean;
    size_t fhat_bound_bricks, fhat_bound_faces;
    double cpu_seconds;
    char message[256];          /* set when nothing is hit */
} wvol_iso_cast_stats;

/* Casts one ray per pixel of cam (wvol_camera_ray) against the surface of source (a volume or
 * a store). img receives the Lambert-shaded albedo (two-sided, normal -grad interp) with alpha
 * 1 on a hit; depth (w*h floats, may be NULL) the ray parameter t of the hit (world, +inf on a
 * miss); normals (w*h*3, may be NULL) the unit normals. p and st may be NULL. */
WVOL_API wvol_status wvol_iso_cast(wvol_image *img, float *depth, float *normals, const wvol_render_source *source,
                                   const wvol_camera *cam, double iso, const wvol_iso_cast_params *p,
                                   wvol_iso_cast_stats *st, wvol_error *err);

/* One ray o + t d, t >= 0 (world; d need not be unit; t in world units along the unit
 * direction): hit->hit, t, pos, normal, value filled (the counters left 0). Sets up the
 * source's bricks for this call alone: for many rays use wvol_iso_cast. */
WVOL_API wvol_status wvol_iso_cast_ray(const wvol_render_source *source, double iso, const double o[3],
                                       const double d[3], const wvol_iso_cast_params *p, wvol_iso_hit *hit,
                                       wvol_error *err);

#ifdef __cplusplus
}
#endif
#endif
