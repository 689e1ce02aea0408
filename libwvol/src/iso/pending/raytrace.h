/* Ray tracer API, parked until the store implementation (libwvol/src/store/store.c,
 * query.c) and the basis splines land in main: then these declarations move into
 * wvol/iso.h, raytrace.c into libwvol/src/iso/ and test_iso_trace.c into tests/c/.
 * Built and tested meanwhile in a scratch tree with the store and basis branches. */
#ifndef WVOL_ISO_PENDING_RAYTRACE_H
#define WVOL_ISO_PENDING_RAYTRACE_H
#include "wvol/iso.h"
#include "wvol/store.h"

/* ---- ray tracing the implicit surface f^ = iso of a store (Kalra-Barr) ---------- */

typedef struct wvol_iso_trace_params {
    double tolerance;   /* depth accuracy in world units; <= 0: 1e-3 of the smallest spacing */
    double step;        /* coarse segment length in voxels (default 4) */
    int threads;        /* 0: OpenMP's default */
    double light[3];    /* direction towards the light (world); all 0: a headlight */
    float color[3];     /* albedo */
    float ambient;      /* in [0, 1] */
} wvol_iso_trace_params;

void wvol_iso_trace_params_default(wvol_iso_trace_params *p);

typedef struct wvol_iso_hit {
    int hit;            /* 1 when the ray meets f^ = iso inside the volume's extent */
    double t;           /* world distance from the origin along the unit direction (+inf: miss) */
    double pos[3];      /* world position */
    double normal[3];   /* unit -grad f^ (world), pointing towards f^ < iso */
    double value;       /* f^ at the hit */
    int evals, bounds;  /* point evaluations and box bounds used */
    int grazes;         /* intervals shorter than tolerance/16 left unresolved (no sign change) */
} wvol_iso_hit;

/* The first crossing of f^ = iso along o + t d (world; d need not be unit),
 * within the volume's sample extent [0, n-1] per axis: no crossing is missed
 * except pairs closer together than tolerance/16; the depth is within tolerance/2. */
wvol_status wvol_iso_trace_ray(const wvol_store *s, double iso, const double o[3], const double d[3],
                               const wvol_iso_trace_params *p, wvol_iso_hit *hit, wvol_error *err);

/* A camera: the world ray through pixel position (px, py) (pixel centres at +0.5). */
typedef void (*wvol_iso_ray_fn)(void *user, double px, double py, double origin[3], double dir[3]);

typedef struct wvol_iso_trace_stats {
    size_t rays, hits, evals, bounds, grazes;
    double seconds;
    char message[256];  /* set when nothing is hit (e.g. iso outside the range of f^) */
} wvol_iso_trace_stats;

/* Traces width x height rays. rgb (w*h*3, Lambert-shaded albedo, 0 on a miss),
 * depth (w*h, +inf on a miss) and normals (w*h*3) may each be NULL. */
wvol_status wvol_iso_raytrace(float *rgb, float *depth, float *normals, int width, int height,
                              wvol_iso_ray_fn camera, void *camera_user, const wvol_store *s, double iso,
                              const wvol_iso_trace_params *p, wvol_iso_trace_stats *stats, wvol_error *err);

#endif
