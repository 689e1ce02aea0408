/* SPDX-License-Identifier: MIT
 * Internals of the transport module: quad frames, the hashed coefficient tree, the 2D rules,
 * the integrand and the oracle (not installed). */
#ifndef WVOL_TRANSPORT_INTERNAL_H
#define WVOL_TRANSPORT_INTERNAL_H

#include <stdint.h>

#include "wvol/transport.h"
#include "core/status_internal.h"

/* ---- quad.c: a parallelogram's frame and the (u, v) <-> world, (k, l) <-> direction maps ---- */
typedef struct wvol__tframe {
    double o[3], eu[3], ev[3];  /* x(u, v) = o + u eu + v ev */
    double n[3], t[3], b[3];    /* orthonormal: t along eu, n the normal, b = n x t */
    double ginv[2][2];          /* inverse Gram matrix of (eu, ev) */
    double area;
} wvol__tframe;

void wvol__tframe_init(wvol__tframe *f, const wvol_transport_quad *q); /* q already checked */
void wvol__tframe_point(const wvol__tframe *f, double u, double v, double x[3]);
/* (u, v) of the world point's projection onto the plane. */
void wvol__tframe_param(const wvol__tframe *f, const double x[3], double uv[2]);
/* Direction of Nusselt (k, l) in the hemisphere of n: 0 when outside the unit disc. */
int wvol__tframe_dir(const wvol__tframe *f, double k, double l, double w[3]);
/* Nusselt (k, l) of a world direction (any length-1 vector; its n side is not checked). */
void wvol__tframe_kl(const wvol__tframe *f, const double w[3], double kl[2]);

static inline double wvol__dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* ---- tree.c: the wavelet coefficient tree ---------------------------------------------------- */
/* A node holds the 16 coefficients (basis selector n = 0..15, bit a set = wavelet in axis a of
 * (u, v, k, l)) x 3 channels of one pure smoothing index. c[0] is meaningful at the root only. */
typedef struct wvol__tnode {
    uint8_t level;
    uint16_t m[4];
    uint16_t child_mask; /* children (m' = 2m + bits) present */
    float c[16][3];
} wvol__tnode;

struct wvol_transport_tree {
    int levels;
    wvol__tnode *nodes;
    size_t count, cap;
    int32_t *hash;  /* open addressing: node index + 1, 0 = empty */
    size_t hash_cap;
};

const wvol__tnode *wvol__tree_find(const wvol_transport_tree *t, int level, const int m[4]);
/* Finds or inserts (zero coefficients); NULL when out of memory. The pointer is valid until the
 * next insertion. */
wvol__tnode *wvol__tree_get(wvol_transport_tree *t, int level, const int m[4]);
/* The 16-point 4D Haar analysis ("pull") and synthesis ("push") of 3 channels: the same
 * orthonormal, self-inverse matrix (1/4 of a Hadamard matrix). Child c = bits (u, v, k, l). */
void wvol__haar16(float out[16][3], const float in[16][3]);

/* ---- rules.c: the 2D rules on a square ------------------------------------------------------- */
typedef double (*wvol__integrand)(void *user, double k, double l);
/* Integral of f over [k0, k0 + h] x [l0, l0 + h]; *evals gets the evaluation count. */
double wvol__rule2d(wvol_transport_quadrature q, int samples, uint64_t seed, wvol__integrand f, void *user, double k0,
                    double l0, double h, size_t *evals);
/* Radical inverse of i in base b. */
double wvol__radical_inverse(uint64_t i, unsigned b);

/* ---- coefficient.c: the reduced integrand G_j A_jk and the oracle ---------------------------- */
typedef struct wvol__tgeom {
    wvol__tframe s, d;
    int coplanar; /* both quads in one plane: nothing travels between them */
} wvol__tgeom;

void wvol__tgeom_init(wvol__tgeom *g, const wvol_transport_quad *src, const wvol_transport_quad *dst);

typedef enum { WVOL__ORACLE_UNKNOWN = 0, WVOL__ORACLE_ZERO = 1, WVOL__ORACLE_FULL = 2 } wvol__oracle;
wvol__oracle wvol__tg_oracle(const wvol__tgeom *g, const wvol_transport_index *j, const wvol_transport_index *k);
/* T_jk by the rule (no oracle); *evals as wvol__rule2d. */
double wvol__tc_eval(const wvol__tgeom *g, const wvol_transport_index *j, const wvol_transport_index *k,
                     const wvol_transport_params *p, size_t *evals);

wvol_status wvol__transport_params_check(const wvol_transport_params *p, wvol_error *err);

#endif
