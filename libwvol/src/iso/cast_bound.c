/* SPDX-License-Identifier: MIT
 * The link between the caster's surface and the wavelet model's: a bound, per brick, of
 * |f^(x) - interp(x)| for x in the brick, where f^ is the store's spline model and interp the
 * trilinear interpolant of the samples the store reconstructs (c0, the level-0 scaling
 * coefficients). With g the model of the true (cascade) phi, g(x) = sum_p c0[p] Phi(x - p + s)
 * exactly (two-scale relation), and g_s the same with the spline phi:
 *
 *   f^ - interp = (f^ - g) + (g - g_s) + (g_s - interp)
 *
 *   |f^ - g|       <= sum_j |c_j| norm_j (prod_a (V_a + e_a) - prod_a V_a)   (the functions touching
 *                     the brick; V the spline's max |phi| or |psi| per axis, e its error)
 *   |g - g_s|      <= max|c0| ((A + (L-1) e_phi)^3 - A^3)
 *   g_s - interp   =  sum_p r[p] (Phi_s - Lambda)(x - p) + a0 (S(x) - 1)
 *                     + sum_a g_a (u_a (P S - 1) + P (s S - m))
 *                  with c0[p] = a0 + g . (p - pbar) + r[p] the least-squares plane over the window
 *                  of samples whose phi or hat reaches x, u = x - pbar, S = s(x_a + s) the spline's
 *                  partition of unity along the axis, m its first moment, P the other axes' S:
 *   |g_s - interp| <= max|r| D (A^2 + A + 1) + |a0| max|S^3 - 1| + sum_a |g_a| (max|u_a| max|S^3 - 1|
 *                     + max P max|s S - m|)
 *
 * (trilinear interpolation reproduces the plane exactly; the spline phi reproduces it up to the
 * ranges of S and m), evaluated per group of 4^3 cells (a window of a few samples, where the
 * plane follows the data closely) and maximised over the brick's groups. Lambda is the
 * trilinear hat, A >= max_x sum_p |phi_s(x - p + s)| and
 * D >= max_x sum_p |phi_s(x - p + s) - hat(x - p)| (1D, from 4096 points per unit plus a
 * Lipschitz margin), S = prod of the spline's partition of unity (its range from the summed
 * pieces' Bernstein hulls). The products are bounded by telescoping (|abc - a'b'c'| <=
 * |a-a'||b||c| + |a'||b-b'||c| + |a'||b'||c-c'|, summed over p factor by factor). e is the
 * spline's error against the cascade at J + 2 (the basis tables' measured error, the store's
 * convention for its own bounds); the rest is rigorous up to a relative pad of 1e-5 of the
 * samples' magnitude for the float32 reconstruction. */
#include <math.h>
#include <string.h>

#include "iso_internal.h"

#define SAMPLES_PER_UNIT 4096

void wvol__fhat_link_init(wvol__fhat_link *k, const wvol_store *s)
{
    const wvol_basis *b = wvol_store_basis(s);
    wvol_store_info info;
    wvol__iso_boxk bk;
    double V[2], e[2], h = 1.0 / SAMPLES_PER_UNIT, margin, s3lo, s3hi;
    int a, i, p, band, L;
    memset(k, 0, sizeof *k);
    wvol_store_get_info(s, &info);
    if (!b || !info.transformed[0] || !info.transformed[1] || !info.transformed[2] || info.levels < 1) return;
    L = b->length;
    V[0] = b->vmax[WVOL_BASIS_PHI], V[1] = b->vmax[WVOL_BASIS_PSI];
    e[0] = b->exact ? 0.0 : b->spline_error_phi, e[1] = b->exact ? 0.0 : b->spline_error_psi;
    /* the window of samples p reaching x in [c0, c1]: phi(x - p + s) with support (0, L - 1),
     * and the hat over [c0, c1] */
    k->below = (int)ceil((double)(L - 1) - b->center);
    k->above = (int)ceil(b->center);
    if (k->below < 0) k->below = 0;
    if (k->above < 1) k->above = 1;
    /* D and A: per x, the sums over p; each term moves by at most (max|phi'| + 1) h / 2 within
     * half a sample step (Haar's box is constant between its jumps, which fall on the samples'
     * midpoints' boundaries: its terms move only with the hat) */
    margin = 0.5 * h * ((b->exact ? 0.0 : b->dmax[WVOL_BASIS_PHI]) + 1.0);
    for (i = 0; i < SAMPLES_PER_UNIT; i++) {
        double x = (i + 0.5) * h, sd = 0, sa = 0;
        int np = 0;
        for (p = -L - 2; p <= L + 2; p++) {
            double ph = wvol_basis_value(b, WVOL_BASIS_PHI, x - p + b->center), hat = 1.0 - fabs(x - p);
            if (hat < 0) hat = 0;
            if (ph == 0.0 && hat == 0.0 && fabs(x - p + b->center) > L && fabs(x - p) > 1.5) continue;
            sd += fabs(ph - hat);
            sa += fabs(ph);
            np++;
        }
        sd += np * margin;
        sa += np * margin;
        if (sd > k->D) k->D = sd;
        if (sa > k->A) k->A = sa;
    }
    wvol__iso_boxk_init(&bk, s);
    s3lo = bk.s1[0] * bk.s1[0] * bk.s1[0];
    s3hi = bk.s1[1] * bk.s1[1] * bk.s1[1];
    k->smax = bk.s1[0] > 0 ? fmax(fabs(s3lo - 1.0), fabs(s3hi - 1.0)) : INFINITY;
    k->lin = fmax(bk.s1[0] * bk.s1[0], bk.s1[1] * bk.s1[1]) *
             fmax(fmax(fabs(b->center * bk.s1[0] - bk.m1[1]), fabs(b->center * bk.s1[0] - bk.m1[0])),
                  fmax(fabs(b->center * bk.s1[1] - bk.m1[1]), fabs(b->center * bk.s1[1] - bk.m1[0])));
    wvol__iso_boxk_free(&bk);
    k->K = k->D * (k->A * k->A + k->A + 1.0);
    {
        double sig = (L - 1) * e[0];
        k->e0 = (k->A + sig) * (k->A + sig) * (k->A + sig) - k->A * k->A * k->A;
    }
    for (band = 0; band < 8; band++) {
        double pe = 1.0, pv = 1.0;
        for (a = 0; a < 3; a++) {
            int w = (band >> a) & 1;
            pe *= V[w] + e[w];
            pv *= V[w];
        }
        k->F[band] = pe - pv;
    }
    k->ok = isfinite(k->smax) && isfinite(k->K);
}

/* The plane-fit part over one group's window [w0, w1] (stored-box indices) for x in the
 * group's box [x0, x1] (the same indices). */
static double group_bound(const wvol__fhat_link *k, const float *s, const size_t md[3], const long w0[3],
                          const long w1[3], const long x0[3], const long x1[3])
{
    double pbar[3], den[3], g[3] = {0, 0, 0}, a0 = 0, r = 0, mag = 0, e;
    long i, j, l, cnt = 1;
    int a;
    for (a = 0; a < 3; a++) {
        long n = w1[a] - w0[a] + 1;
        pbar[a] = 0.5 * (double)(w0[a] + w1[a]);
        den[a] = (double)(n * n - 1) * (double)n / 12.0; /* sum of (p - pbar)^2 over the axis */
        cnt *= n;
    }
    for (l = w0[2]; l <= w1[2]; l++)
        for (j = w0[1]; j <= w1[1]; j++)
            for (i = w0[0]; i <= w1[0]; i++) {
                double v = s[(size_t)i + md[0] * ((size_t)j + md[1] * (size_t)l)];
                a0 += v;
                g[0] += (i - pbar[0]) * v, g[1] += (j - pbar[1]) * v, g[2] += (l - pbar[2]) * v;
                if (fabs(v) > mag) mag = fabs(v);
            }
    a0 /= (double)cnt;
    for (a = 0; a < 3; a++) g[a] = den[a] > 0 ? g[a] / (den[a] * (double)cnt / (double)(w1[a] - w0[a] + 1)) : 0.0;
    for (l = w0[2]; l <= w1[2]; l++)
        for (j = w0[1]; j <= w1[1]; j++)
            for (i = w0[0]; i <= w1[0]; i++) {
                double v = s[(size_t)i + md[0] * ((size_t)j + md[1] * (size_t)l)];
                double q = v - a0 - g[0] * (i - pbar[0]) - g[1] * (j - pbar[1]) - g[2] * (l - pbar[2]);
                if (fabs(q) > r) r = fabs(q);
            }
    e = r * k->K + fabs(a0) * k->smax + mag * k->e0;
    for (a = 0; a < 3; a++) {
        double u = fmax(fabs((double)x0[a] - pbar[a]), fabs((double)x1[a] - pbar[a]));
        e += fabs(g[a]) * (u * k->smax + k->lin);
    }
    /* float32 samples and the float64 sums above: a relative pad */
    return e + 1e-5 * mag * (1.0 + k->K);
}

double wvol__fhat_link_bound(const wvol__fhat_link *k, const float *s, const size_t md[3], const size_t core[3],
                             const size_t cells[3], int group, const wvol_store_hit *hits, size_t nh)
{
    double lev = 0.0, worst = 0.0;
    size_t i, gn[3];
    long gi[3];
    int a;
    if (!k->ok) return INFINITY;
    for (i = 0; i < nh; i++) lev += fabs((double)hits[i].value) * hits[i].norm * k->F[hits[i].band];
    for (a = 0; a < 3; a++) gn[a] = (cells[a] + (size_t)group - 1) / (size_t)group;
    for (gi[2] = 0; gi[2] < (long)gn[2]; gi[2]++)
        for (gi[1] = 0; gi[1] < (long)gn[1]; gi[1]++)
            for (gi[0] = 0; gi[0] < (long)gn[0]; gi[0]++) {
                long x0[3], x1[3], w0[3], w1[3];
                double e;
                for (a = 0; a < 3; a++) {
                    x0[a] = (long)core[a] + gi[a] * group;
                    x1[a] = x0[a] + group < (long)(core[a] + cells[a]) ? x0[a] + group : (long)(core[a] + cells[a]);
                    w0[a] = x0[a] - k->below;
                    w1[a] = x1[a] + k->above;
                    if (w0[a] < 0 || w1[a] >= (long)md[a]) return INFINITY; /* the window is not stored */
                }
                e = group_bound(k, s, md, w0, w1, x0, x1);
                if (e > worst) worst = e;
            }
    return lev + worst;
}
