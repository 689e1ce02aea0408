/* SPDX-License-Identifier: MIT
 * Wavelet radiosity internals shared by the files of this folder (not installed). */
#ifndef WVOL_RADIOSITY_INTERNAL_H
#define WVOL_RADIOSITY_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include "wvol/radiosity.h"
#include "core/status_internal.h"

enum { RAD_MAXM = 4, RAD_MAXNQ = 6, RAD_MAXNB = RAD_MAXM * RAD_MAXM };

/* A validated patch: bilinear map x(u, v) = o + u a + v b + u v c; for a planar convex quad the
 * area element |x_u x x_v| = j0 + ju u + jv v is affine. */
typedef struct rad_patch {
    wvol_radiosity_quad q;
    double o[3], a[3], b[3], c[3];
    double n[3];      /* unit front normal */
    double j0, ju, jv;
    double area;
    double lo[3], hi[3];
} rad_patch;

struct wvol_radiosity_scene {
    size_t n;
    rad_patch *p;
    double lo[3], hi[3], scale; /* bounds and their diagonal */
};

/* scene.c: geometry of a patch */
void wvol__rad_point(const rad_patch *p, double u, double v, double x[3]);
double wvol__rad_jacobian(const rad_patch *p, double u, double v);
/* 1 when the open segment x..y crosses a patch other than skip1/skip2 (front or back). */
int wvol__rad_occluded(const wvol_radiosity_scene *s, const double x[3], const double y[3], size_t skip1,
                       size_t skip2);
/* Nearest front-facing hit along a ray at t > tmin: patch index and (u, v), or -1. */
long wvol__rad_hit(const wvol_radiosity_scene *s, const double o[3], const double d[3], double tmin, double *u,
                   double *v);
/* Lambert's formula for a convex polygon of nv <= 4 vertices, clipped to x's front half-space. */
double wvol__rad_polygon_ff(const double (*poly)[3], int nv, const double x[3], const double n[3]);
/* Validates quads and builds the scene (scene.c; the OBJ reader calls it). names: NULL or one
 * name per quad for the messages ("face 12 (material red)"). */
wvol_status wvol__rad_scene_build(wvol_radiosity_scene **out, const wvol_radiosity_quad *q, size_t n,
                                  const char *const *labels, wvol_error *err);

/* bases.c: 1D tree-wavelet scaling functions on the unit cell, orthonormal in L2(0, 1). */
typedef struct rad_basis {
    wvol_radiosity_basis kind;
    int m;               /* functions per direction (M) */
    int nb;              /* m * m per node */
    int flat;            /* 1: flatlets (piecewise constant on m boxes); 0: Legendre */
    int nq;              /* kernel sample points per direction on a cell */
    double qx[RAD_MAXNQ], qw[RAD_MAXNQ];     /* on [0, 1], weights sum to 1 */
    double phi[RAD_MAXM][RAD_MAXNQ];         /* phi_a(qx[k]) */
    double mean[RAD_MAXM];                   /* integral of phi_a over [0, 1] */
    double push[2][RAD_MAXM][RAD_MAXM];      /* child c coefficient a from parent coefficient b */
    double resid[RAD_MAXNQ][RAD_MAXNQ];      /* I - weighted LS projection onto degree < M (oracle) */
} rad_basis;

void wvol__rad_basis_init(rad_basis *b, wvol_radiosity_basis kind);
double wvol__rad_phi(const rad_basis *b, int a, double x);
/* The 1D wavelet step of one node: T (2m x 2m, row-major) maps the 2m child scaling coefficients
 * to m parent scaling and m detail (wavelet) coefficients; Tinv is its inverse (T^T for the
 * orthonormal multiwavelets, the dual basis for flatlets). */
void wvol__rad_basis_wavelet(const rad_basis *b, double *t, double *tinv);

/* kernel.c */
typedef struct rad_cell {
    size_t patch;
    int level;
    double u0, v0, h; /* parameter cell [u0, u0 + h] x [v0, v0 + h] */
} rad_cell;

typedef struct rad_counters {
    size_t kernel_evals, closed_form_evals, rays;
} rad_counters;

/* Kernel k(x, y) J_p(s) J_q(t) (with visibility) at the nq^2 x nq^2 sample pairs of two cells:
 * k[(sp * nq2) + tq]; returns the number of nonzero samples. */
size_t wvol__rad_kernel_samples(const wvol_radiosity_scene *s, const rad_basis *b, const rad_cell *p,
                                const rad_cell *q, double *k, rad_counters *cnt);
/* Link coefficients K[A * nb + B] from samples (k as above). */
void wvol__rad_link_quadrature(const rad_basis *b, const rad_cell *p, const rad_cell *q, const double *k,
                               double *kout);
/* Link coefficients with the source integrated in closed form per constant piece (Haar, flatlets),
 * for cells touching or near each other; visibility from the samples' fraction. */
void wvol__rad_link_closed_form(const wvol_radiosity_scene *s, const rad_basis *b, const rad_cell *p,
                                const rad_cell *q, const double *k, double *kout, rad_counters *cnt);
/* Oracle: estimated L1 error (area units) of fitting the sampled kernel by polynomials of degree < M. */
double wvol__rad_oracle(const rad_basis *b, const rad_cell *p, const rad_cell *q, const double *k);
/* 1 when two cells are closer than their size (the kernel's singularity is near). */
int wvol__rad_cells_near(const wvol_radiosity_scene *s, const rad_cell *p, const rad_cell *q);

/* refine.c / solve.c: the solution. Nodes of every patch's quadtree in one array; the four
 * children of a node are consecutive (child = index of the first, or -1 at a leaf). */
typedef struct rad_node {
    size_t patch;
    int level, iu, iv;
    long child;
} rad_node;

typedef struct rad_link {
    size_t recv, src; /* nodes */
    size_t koff;      /* offset of nb * nb coefficients in k */
} rad_link;

struct wvol_radiosity {
    const wvol_radiosity_scene *scene;
    rad_basis basis;
    wvol_radiosity_params par;
    rad_node *nodes;
    size_t nnodes, capnodes;
    double *b;      /* 3 * nb per node: radiosity on the node's scaling functions */
    double *h;      /* 3 * nb per node: irradiance gathered over the node's links (before reflectance) */
    size_t *root;   /* root node of each patch */
    rad_link *links;
    size_t nlinks, caplinks;
    double *k;
    size_t nk, capk;
    rad_counters cnt;
    double samples[RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNQ * RAD_MAXNQ];
};

void wvol__rad_node_cell(const struct wvol_radiosity *r, size_t node, rad_cell *c);
/* Creates the four children of a leaf, their radiosity pushed from the node's. */
wvol_status wvol__rad_split(struct wvol_radiosity *r, size_t node, wvol_error *err);
/* Coefficients of child (cu, cv) from the parent's (push), or accumulated into the parent (pull). */
void wvol__rad_push(const rad_basis *b, int cu, int cv, const double *parent, double *child);
void wvol__rad_pull(const rad_basis *b, int cu, int cv, const double *child, double *parent);
/* Links every pair of patches through ProjectKernel / AskOracle (refine.c). */
wvol_status wvol__rad_refine_all(struct wvol_radiosity *r, wvol_error *err);

#endif
