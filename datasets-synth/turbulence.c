/* SPDX-License-Identifier: MIT
 * A turbulence-like field: a sum of random-phase Fourier modes whose energy spectrum
 * follows Kolmogorov's k^(-5/3) from the box scale down to a few voxels, the field a
 * smooth phantom is not (its wavelet coefficients do not decay fast with the level).
 * Based on: Kraichnan 1970 and Fung, Hunt, Malik & Perkins 1992 (kinematic
 * simulation: random Fourier modes on log-spaced wavenumber shells with the target
 * spectrum). docs/datasets.md states the construction.
 *
 * Cost: cos(k . x + phi) = Re(e^{i phi} e^{i kx x} e^{i ky y} e^{i kz z}); the three
 * per-axis factors are tabulated once per mode and index, so a row (fixed y, z) costs
 * one complex product per mode, and each voxel two multiply-adds per mode over the
 * x table. A slab is as cheap per voxel as the whole volume. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/clones.h"
#include "synth_internal.h"

/* Shells per octave and modes (random directions) per shell: 12 modes per octave of
 * scale, from the box down to PERIOD_MIN voxels (72 modes at 256^3, 108 at 2048^3). */
enum { SHELLS_PER_OCTAVE = 3, MODES_PER_SHELL = 4, MAX_MODES = 1024 };
#define PERIOD_MIN 4.0

typedef struct turb_ctx {
    int modes;
    size_t nx, ny, nz;
    /* per mode m: amplitude-weighted phase factor e^{i phi} A, and the axis tables
     * e^{i k_a u_a(n)}: x as float (the inner loop), y and z as double */
    float *xr, *xi;        /* [m * nx + i] */
    double *yr, *yi;       /* [m * ny + j] */
    double *zr, *zi;       /* [m * nz + k] */
    double *ar, *ai;       /* [m] */
} turb_ctx;

/* The row's factor of mode m: c_m = A e^{i phi} e^{i ky y} e^{i kz z}. */
static inline void row_factor(const turb_ctx *c, int m, size_t j, size_t k, float *cr, float *ci)
{
    double yr = c->yr[(size_t)m * c->ny + j], yi = c->yi[(size_t)m * c->ny + j];
    double zr = c->zr[(size_t)m * c->nz + k], zi = c->zi[(size_t)m * c->nz + k];
    double pr = c->ar[m] * yr - c->ai[m] * yi, pi = c->ar[m] * yi + c->ai[m] * yr;
    *cr = (float)(pr * zr - pi * zi);
    *ci = (float)(pr * zi + pi * zr);
}

/* Four modes per sweep of the row (a quarter of the row's loads and stores), added to
 * each voxel one after the other in mode order: the same operations in the same order
 * as one mode per sweep, so the same bytes. Contraction to FMA is off, so the AVX2 copy
 * (WVOL__CLONES) gives the baseline's bytes too. */
#define MODE_BLOCK 4
WVOL__CLONES WVOL__NO_CONTRACT static void
turb_row(const void *vctx, const synth_grid *g, size_t j, size_t k, float *row, float *lab)
{
    const turb_ctx *c = vctx;
    size_t i, nx = g->nx;
    int m = 0;
    (void)lab;
    for (i = 0; i < nx; i++) row[i] = 0;
    for (; m + MODE_BLOCK <= c->modes; m += MODE_BLOCK) {
        float cr[MODE_BLOCK], ci[MODE_BLOCK];
        const float *restrict xr[MODE_BLOCK], *restrict xi[MODE_BLOCK];
        float *restrict out = row;
        for (int b = 0; b < MODE_BLOCK; b++) {
            row_factor(c, m + b, j, k, &cr[b], &ci[b]);
            xr[b] = c->xr + (size_t)(m + b) * nx, xi[b] = c->xi + (size_t)(m + b) * nx;
        }
        for (i = 0; i < nx; i++) {
            float v = out[i];
            v += cr[0] * xr[0][i] - ci[0] * xi[0][i];
            v += cr[1] * xr[1][i] - ci[1] * xi[1][i];
            v += cr[2] * xr[2][i] - ci[2] * xi[2][i];
            v += cr[3] * xr[3][i] - ci[3] * xi[3][i];
            out[i] = v;
        }
    }
    for (; m < c->modes; m++) {
        float cr, ci;
        const float *restrict xr = c->xr + (size_t)m * nx, *restrict xi = c->xi + (size_t)m * nx;
        float *restrict out = row;
        row_factor(c, m, j, k, &cr, &ci);
        for (i = 0; i < nx; i++) out[i] += cr * xr[i] - ci * xi[i];
    }
}

/* Unit vector uniformly on the sphere (or the circle for a 2D image). */
static void random_direction(wvol_rng *r, int dim, double d[3])
{
    double z = dim == 3 ? 2.0 * wvol_rng_uniform(r) - 1.0 : 0.0, t = 6.283185307179586 * wvol_rng_uniform(r);
    double s = sqrt(1.0 - z * z);
    d[0] = s * cos(t);
    d[1] = s * sin(t);
    d[2] = z;
}

wvol_status wvol__synth_plan_turbulence(synth_plan *pl, const wvol_synth_params *p, wvol_error *err)
{
    turb_ctx *c;
    wvol_rng rng;
    size_t n[3], bytes;
    double kmin, kmax, octaves, sum2 = 0;
    int shells, dim, m;
    unsigned char *mem;
    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "synth turbulence: NULL parameters");
    WVOL_FORWARD(wvol__synth_geometry(&pl->g, p, NULL, "turbulence", err));
    n[0] = pl->g.nx, n[1] = pl->g.ny, n[2] = pl->g.nz;
    dim = n[2] > 1 ? 3 : 2;
    /* normalised units: the largest extent is 2; the finest period is PERIOD_MIN voxels of
     * the largest voxel edge, the coarsest the box */
    kmin = 6.283185307179586 / 2.0;
    kmax = 6.283185307179586 / (PERIOD_MIN * pl->g.voxel_u);
    octaves = kmax > kmin ? log2(kmax / kmin) : 0;
    shells = (int)ceil(octaves * SHELLS_PER_OCTAVE);
    if (shells < 1) shells = 1;
    if (shells * MODES_PER_SHELL > MAX_MODES) shells = MAX_MODES / MODES_PER_SHELL;
    bytes = sizeof *c + (size_t)shells * MODES_PER_SHELL *
                            (2 * n[0] * sizeof(float) + 2 * (n[1] + n[2] + 1) * sizeof(double) + 64);
    WVOL_RETURN_IF(!(c = wvol__synth_plan_ctx(pl, bytes, turb_row)), err, WVOL_ERR_NOMEM,
                   "synth turbulence: no memory for the mode tables (%zu bytes)", bytes);
    c->modes = shells * MODES_PER_SHELL;
    c->nx = n[0], c->ny = n[1], c->nz = n[2];
    mem = (unsigned char *)(c + 1);
    /* doubles first (alignment), then floats */
    c->yr = (double *)mem, mem += (size_t)c->modes * n[1] * sizeof(double);
    c->yi = (double *)mem, mem += (size_t)c->modes * n[1] * sizeof(double);
    c->zr = (double *)mem, mem += (size_t)c->modes * n[2] * sizeof(double);
    c->zi = (double *)mem, mem += (size_t)c->modes * n[2] * sizeof(double);
    c->ar = (double *)mem, mem += (size_t)c->modes * sizeof(double);
    c->ai = (double *)mem, mem += (size_t)c->modes * sizeof(double);
    c->xr = (float *)mem, mem += (size_t)c->modes * n[0] * sizeof(float);
    c->xi = (float *)mem;

    wvol_rng_seed(&rng, p->seed ^ 0x7B2B1E5ull);
    for (m = 0; m < c->modes; m++) {
        int shell = m / MODES_PER_SHELL;
        /* log-spaced shells, the wavenumber jittered within its shell */
        double t = ((double)shell + wvol_rng_uniform(&rng)) / (double)shells;
        double k = kmin * pow(kmax / kmin, t), dk = k * log(kmax / kmin > 1 ? kmax / kmin : 2.0) / shells;
        /* E(k) ~ k^(-5/3): a mode carries E(k) dk / (modes per shell) of energy, amplitude^2 / 2 */
        double amp = sqrt(2.0 * pow(k, -5.0 / 3.0) * dk / MODES_PER_SHELL), phase, d[3];
        random_direction(&rng, dim, d);
        phase = 6.283185307179586 * wvol_rng_uniform(&rng);
        c->ar[m] = amp * cos(phase);
        c->ai[m] = amp * sin(phase);
        sum2 += 0.5 * amp * amp;
        for (int a = 0; a < 3; a++)
            for (size_t q = 0; q < n[a]; q++) {
                double ph = k * d[a] * synth_u(&pl->g, a, q), cr = cos(ph), ci = sin(ph);
                if (a == 0) c->xr[(size_t)m * n[0] + q] = (float)cr, c->xi[(size_t)m * n[0] + q] = (float)ci;
                else if (a == 1) c->yr[(size_t)m * n[1] + q] = cr, c->yi[(size_t)m * n[1] + q] = ci;
                else c->zr[(size_t)m * n[2] + q] = cr, c->zi[(size_t)m * n[2] + q] = ci;
            }
    }
    /* unit variance: the modes are independent cosines, variance sum A^2 / 2 */
    for (m = 0; m < c->modes; m++) {
        c->ar[m] /= sqrt(sum2);
        c->ai[m] /= sqrt(sum2);
    }
    return WVOL_OK;
}

wvol_status wvol_synth_turbulence(wvol_volume **out, const wvol_synth_params *p, wvol_error *err)
{
    return wvol__synth_whole(out, NULL, wvol__synth_plan_turbulence, p, "turbulence", err);
}
