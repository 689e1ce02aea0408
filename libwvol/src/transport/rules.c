/* SPDX-License-Identifier: MIT
 * The 2D integration rules Lewis & Fournier 2002 compare (§7.1.4.2): trapezoidal, Romberg with
 * linear / quadratic / cubic Richardson extrapolation, Monte Carlo plain and stratified, Halton
 * and Hammersley. Based on: Zwillinger, Handbook of Integration (1992); Keller 1996 (QMC). */
#include "transport_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/rng.h"

double wvol__radical_inverse(uint64_t i, unsigned b)
{
    double inv = 1.0 / b, f = inv, r = 0;
    while (i) {
        r += f * (double)(i % b);
        i /= b;
        f *= inv;
    }
    return r;
}

static int isqrt_floor(int n)
{
    int r = (int)sqrt((double)n);
    while ((r + 1) * (r + 1) <= n) r++;
    while (r * r > n) r--;
    return r;
}

/* trapezoid sum on an (n + 1)^2 grid taking every `step`-th node of the stored fine grid */
static double trap_from_grid(const double *v, int fine, int step, double h)
{
    int n = (fine - 1) / step;
    double s = 0, d = h / n;
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            double w = (i == 0 || i == n ? 0.5 : 1.0) * (j == 0 || j == n ? 0.5 : 1.0);
            s += w * v[(size_t)j * step * fine + (size_t)i * step];
        }
    return s * d * d;
}

double wvol__rule2d(wvol_transport_quadrature q, int samples, uint64_t seed, wvol__integrand f, void *user, double k0,
                    double l0, double h, size_t *evals)
{
    double s = 0;
    size_t e = 0;
    if (samples < 1) samples = 1;
    switch (q) {
    case WVOL_TRANSPORT_QUADRATURE_TRAPEZOID: {
        int n = isqrt_floor(samples);
        if (n < 2) { /* one sample: the midpoint */
            s = f(user, k0 + 0.5 * h, l0 + 0.5 * h) * h * h;
            e = 1;
            break;
        }
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                double w = (i == 0 || i == n - 1 ? 0.5 : 1.0) * (j == 0 || j == n - 1 ? 0.5 : 1.0);
                s += w * f(user, k0 + h * i / (n - 1), l0 + h * j / (n - 1));
            }
        s *= (h / (n - 1)) * (h / (n - 1));
        e = (size_t)n * n;
        break;
    }
    case WVOL_TRANSPORT_QUADRATURE_ROMBERG1:
    case WVOL_TRANSPORT_QUADRATURE_ROMBERG2:
    case WVOL_TRANSPORT_QUADRATURE_ROMBERG3: {
        int order = (int)q, M = 0, fine;
        double R[16][4], *v;
        while (((1 << (M + 1)) + 1) * ((1 << (M + 1)) + 1) <= samples && M < 12) M++;
        fine = (1 << M) + 1;
        v = malloc((size_t)fine * fine * sizeof *v);
        if (!v) return NAN;
        for (int j = 0; j < fine; j++)
            for (int i = 0; i < fine; i++)
                v[(size_t)j * fine + i] = f(user, k0 + h * i / (fine - 1), l0 + h * j / (fine - 1));
        e = (size_t)fine * fine;
        for (int m = 0; m <= M; m++) {
            R[m][0] = trap_from_grid(v, fine, 1 << (M - m), h);
            for (int r = 1; r <= order && r <= m; r++)
                R[m][r] = R[m][r - 1] + (R[m][r - 1] - R[m - 1][r - 1]) / (pow(4.0, r) - 1);
        }
        s = R[M][order < M ? order : M];
        free(v);
        break;
    }
    case WVOL_TRANSPORT_QUADRATURE_MONTE_CARLO: {
        wvol_rng r;
        wvol_rng_seed(&r, seed);
        for (int i = 0; i < samples; i++) {
            double a = wvol_rng_uniform(&r), b = wvol_rng_uniform(&r);
            s += f(user, k0 + a * h, l0 + b * h);
        }
        s *= h * h / samples;
        e = (size_t)samples;
        break;
    }
    case WVOL_TRANSPORT_QUADRATURE_STRATIFIED: {
        int n = isqrt_floor(samples);
        wvol_rng r;
        wvol_rng_seed(&r, seed);
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                double a = (i + wvol_rng_uniform(&r)) / n, b = (j + wvol_rng_uniform(&r)) / n;
                s += f(user, k0 + a * h, l0 + b * h);
            }
        e = (size_t)n * n;
        s *= h * h / (double)e;
        break;
    }
    case WVOL_TRANSPORT_QUADRATURE_HALTON:
        for (int i = 0; i < samples; i++)
            s += f(user, k0 + wvol__radical_inverse((uint64_t)i + 1, 2) * h,
                   l0 + wvol__radical_inverse((uint64_t)i + 1, 3) * h);
        s *= h * h / samples;
        e = (size_t)samples;
        break;
    case WVOL_TRANSPORT_QUADRATURE_HAMMERSLEY:
        for (int i = 0; i < samples; i++)
            s += f(user, k0 + (i + 0.5) / samples * h, l0 + wvol__radical_inverse((uint64_t)i, 2) * h);
        s *= h * h / samples;
        e = (size_t)samples;
        break;
    default:
        return NAN;
    }
    if (evals) *evals += e;
    return s;
}

static const char *const quad_names[WVOL_TRANSPORT_QUADRATURE_COUNT] = {
    "trapezoid", "romberg1", "romberg2", "romberg3", "monte-carlo", "stratified", "halton", "hammersley"};

const char *wvol_transport_quadrature_name(wvol_transport_quadrature q)
{
    return (unsigned)q < WVOL_TRANSPORT_QUADRATURE_COUNT ? quad_names[q] : NULL;
}

int wvol_transport_quadrature_find(const char *name)
{
    if (!name) return -1;
    for (int i = 0; i < WVOL_TRANSPORT_QUADRATURE_COUNT; i++)
        if (!strcmp(name, quad_names[i])) return i;
    return -1;
}
