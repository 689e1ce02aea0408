/* SPDX-License-Identifier: MIT
 * The link between the caster's surface and the wavelet model's: a bound, per group of 4^3 cells
 * of a brick, of |f^(x) - interp(x)|, f^ the store's spline model and interp the trilinear
 * interpolant of the samples c0 the store reconstructs. With g_s(x) = sum_p c0[p] Phi_s(x - p + s)
 * (the samples expanded in the level-0 spline phi):
 *
 *   f^ - interp = (f^ - g_s) + (g_s - interp)
 *
 * f^ - g_s. A kept function j (level m, band, support box from lo) is prod_a A_a(x_a - lo_a) in f^,
 * A = 2^{-m/2} theta_s(xi / 2^m) (theta the spline phi or psi), and prod_a B_a in g_s, B(xi) =
 * sum_i r[i] phi_s(xi - i) with r the filter bank's level-m 1D synthesis response (its samples are
 * the filter bank's, so the same coefficient gives sum_p R_j(p) Phi_s(x - p + s)). For the true phi
 * A = B (the two-scale relation); the splines differ by their tables' defect, so f^ - g_s =
 * sum_j c_j (prod A - prod B) with
 *   - details: the functions whose support meets the group, each |c_j| F[m][band],
 *     F = sup |prod A - prod B| <= d0 VA1 VA2 + VB0 d1 VA2 + VB0 VB1 d2 (telescoped; d = sup |A - B|,
 *     VA, VB the sups of |A|, |B| per axis and factor): a sum over the functions at the group,
 *     not over the brick;
 *   - the level-M low-pass band, whose coefficients carry the data's level, fitted by a plane over
 *     the positions k reaching the group, a_k = a0 + g . (k - kbar) + q_k: with u = y - kbar,
 *     y = (x + s) / 2^M and per axis (normalised by 2^{M/2}) S_A = sum_k A_k, M_A = sum_k (y - k) A_k
 *     and the same for B,
 *       |sum_k a_k (prod A - prod B)_k| <= norm (|a0| c_u + sum_a |g_a| (|u_a| c_u + c_m) + max|q| c_res),
 *     c_u = max |prod S_A - prod S_B|, c_m = max |M_A S_A^2 - M_B S_B^2|, c_res = DS AS^2 + BS DS AS +
 *     BS^2 DS with DS, AS, BS the sups of sum_k |A_k - B_k|, |A_k|, |B_k|.
 * g_s - interp = sum_p r[p] (Phi_s - Lambda)(x - p) + a0 (S(x) - 1) + sum_a g_a (u_a (P S - 1) + P (s S - m))
 * with c0[p] = a0 + g . (p - pbar) + r[p] the least-squares plane over the window of samples whose
 * phi or hat reaches the group (trilinear interpolation reproduces it exactly, the spline phi up to
 * the ranges of its partition of unity S and first moment m, P the other axes' S):
 *   |g_s - interp| <= max|r| D (A^2 + A + 1) + |a0| max|S^3 - 1| + sum_a |g_a| (max|u_a| max|S^3 - 1|
 *                     + max P max|s S - m|),
 * A >= max_x sum_p |phi_s(x - p + s)|, D >= max_x sum_p |phi_s(x - p + s) - hat(x - p)|.
 *
 * The 1D sups are taken on grids (4096 points per unit, fewer for long filters) plus a Lipschitz
 * margin from the tables' derivative bounds, the ranges of S and m are the Bernstein hulls of the
 * summed pieces (wvol__iso_boxk); a relative pad of 1e-5 of the samples' magnitude covers their
 * float32 rounding. No spline-against-cascade error enters: f^ is the spline model and the samples
 * are the filter bank's. Where a face clips a group's sample window there is no bound (+inf):
 * g_s reaches across the periodic wrap there (docs/iso.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "iso_internal.h"

#define SAMPLES_PER_UNIT 4096

/* The level-m synthesis response of one coefficient (which: 0 low-pass, 1 high-pass along the
 * axis): r_1 = h or g, r_l = (upsampled r_{l-1}) * h. Length (L - 1)(2^m - 1) + 1. */
static double *response(const wvol_filter *f, int m, int which, size_t *len)
{
    size_t L = (size_t)f->length, n = L, l, i, j;
    double *r = malloc(n * sizeof *r), *q;
    if (!r) return NULL;
    memcpy(r, which ? f->g : f->h, L * sizeof *r);
    for (l = 2; l <= (size_t)m; l++) {
        size_t nn = 2 * n + L - 2;
        q = calloc(nn, sizeof *q);
        if (!q) {
            free(r);
            return NULL;
        }
        for (i = 0; i < n; i++)
            for (j = 0; j < L; j++) q[2 * i + j] += r[i] * f->h[j];
        free(r);
        r = q;
        n = nn;
    }
    *len = n;
    return r;
}

/* One factor along an axis, in the function's local coordinate xi = x - lo: A, its spline form in
 * f^, and B, its two-scale expansion in the level-0 spline phi (g_s's form). */
typedef struct factor {
    const wvol_basis *b;
    const double *r;
    size_t len;
    int m, which;
    double amp, lip, vab; /* 2^{-m/2}; Lipschitz constant of A plus that of B; sup|A| + sup|B| */
} factor;

static double fA(const factor *f, double xi)
{
    return f->amp * wvol_basis_value(f->b, f->which, xi * ldexp(1.0, -f->m));
}

static double fB(const factor *f, double xi)
{
    double v = 0.0;
    long i, i0 = (long)floor(xi) - f->b->length, i1 = (long)ceil(xi);
    if (i0 < 0) i0 = 0;
    if (i1 >= (long)f->len) i1 = (long)f->len - 1;
    for (i = i0; i <= i1; i++) v += f->r[i] * wvol_basis_value(f->b, WVOL_BASIS_PHI, xi - (double)i);
    return v;
}

static int factor_init(factor *f, const wvol_basis *b, int m, int which)
{
    size_t i;
    double sr = 0.0;
    f->b = b, f->m = m, f->which = which;
    f->amp = 1.0 / sqrt(ldexp(1.0, m));
    f->r = response(b->filter, m, which, &f->len);
    if (!f->r) return 0;
    for (i = 0; i < f->len; i++) sr += fabs(f->r[i]);
    f->vab = f->amp * b->vmax[which] + sr * b->vmax[WVOL_BASIS_PHI];
    /* Haar (exact): both are piecewise constant, jumps on the integers the grids avoid */
    f->lip = b->exact ? 0.0 : f->amp * b->dmax[which] * ldexp(1.0, -m) + sr * b->dmax[WVOL_BASIS_PHI];
    return 1;
}

/* Points per voxel for the 1D sups: fine (spv), but bounded in total work for long filters. */
static double grid_step(const wvol_basis *b, int m, double spv)
{
    double work = ldexp(1.0, m) * b->length * (double)b->length;
    if (spv * work > 3e7) spv = fmax(64.0, 3e7 / work);
    return 1.0 / spv;
}

/* sups over xi of |A - B|, |A|, |B| on the support [0, 2^m (L - 1)] (between grid points each
 * moves by at most lip h / 2) */
static void factor_sups(const factor *f, double *d, double *va, double *vb)
{
    double h = grid_step(f->b, f->m, 4096.0), x1 = ldexp((double)f->b->support, f->m), margin;
    long i, n = (long)ceil(x1 / h);
    *d = *va = *vb = 0.0;
    for (i = 0; i < n; i++) {
        double xi = (i + 0.5) * h, A = fA(f, xi), B = fB(f, xi);
        *d = fmax(*d, fabs(A - B));
        *va = fmax(*va, fabs(A));
        *vb = fmax(*vb, fabs(B));
    }
    margin = 0.5 * h * f->lip;
    *d += margin, *va += margin, *vb += margin;
}

/* The level-M low-pass band's sums over its positions k (normalised by 2^{M/2}): ranges of
 * S_A = sum_k A_k, S_B, M_A = sum_k (y - k) A_k, M_B, and the sups of sum_k |A_k - B_k|, |A_k|,
 * |B_k|, over one period of x. */
static void lowpass_consts(wvol__fhat_link *k, const factor *f)
{
    const wvol_basis *b = f->b;
    double P = k->scale, h = grid_step(b, k->M, 65536.0), sup = ldexp((double)b->support, k->M), nrm = sqrt(P);
    double sa[2] = {INFINITY, -INFINITY}, sb[2] = {INFINITY, -INFINITY}, ma[2] = {INFINITY, -INFINITY},
           mb[2] = {INFINITY, -INFINITY}, ds = 0, as = 0, bs = 0, marg, mmarg, la, lb, ml, mh, bl, bh;
    long i, n = (long)ceil(P / h), kk, nk = 0;
    for (i = 0; i < n; i++) {
        double x = (i + 0.5) * h, y = (x + k->shift) / P, SA = 0, SB = 0, MA = 0, MB = 0, sd = 0, s1 = 0, s2 = 0;
        long cnt = 0;
        for (kk = (long)floor((x + k->shift - sup) / P); kk <= (long)ceil((x + k->shift) / P); kk++) {
            double xi = x + k->shift - P * (double)kk, A, B;
            if (xi < 0.0 || xi > sup) continue;
            A = fA(f, xi), B = fB(f, xi);
            SA += A, SB += B, MA += (y - (double)kk) * A, MB += (y - (double)kk) * B;
            sd += fabs(A - B), s1 += fabs(A), s2 += fabs(B);
            cnt++;
        }
        if (cnt > nk) nk = cnt;
        sa[0] = fmin(sa[0], SA), sa[1] = fmax(sa[1], SA), sb[0] = fmin(sb[0], SB), sb[1] = fmax(sb[1], SB);
        ma[0] = fmin(ma[0], MA), ma[1] = fmax(ma[1], MA), mb[0] = fmin(mb[0], MB), mb[1] = fmax(mb[1], MB);
        ds = fmax(ds, sd), as = fmax(as, s1), bs = fmax(bs, s2);
    }
    /* margins: each term moves by lip h / 2; (y - k) A_k also through y - k (|y - k| <= L - 1) */
    marg = nk * 0.5 * h * f->lip;
    mmarg = nk * 0.5 * h * (b->support * f->lip + f->vab / P);
    sa[0] -= marg, sa[1] += marg, sb[0] -= marg, sb[1] += marg;
    ma[0] -= mmarg, ma[1] += mmarg, mb[0] -= mmarg, mb[1] += mmarg;
    ds += marg, as += marg, bs += marg;
    for (i = 0; i < 2; i++) sa[i] *= nrm, sb[i] *= nrm, ma[i] *= nrm, mb[i] *= nrm;
    ds *= nrm, as *= nrm, bs *= nrm;
    k->c_res = ds * as * as + bs * ds * as + bs * bs * ds;
    if (!(sa[0] > 0 && sb[0] > 0)) {
        k->c_u = INFINITY;
        return;
    }
    /* prod S_A - prod S_B, and M_A S_A^2 - M_B S_B^2, as intervals */
    k->c_u = fmax(fabs(sa[1] * sa[1] * sa[1] - sb[0] * sb[0] * sb[0]), fabs(sa[0] * sa[0] * sa[0] - sb[1] * sb[1] * sb[1]));
    la = sa[0] * sa[0], lb = sa[1] * sa[1];
    ml = fmin(ma[0] * la, fmin(ma[0] * lb, fmin(ma[1] * la, ma[1] * lb)));
    mh = fmax(ma[0] * la, fmax(ma[0] * lb, fmax(ma[1] * la, ma[1] * lb)));
    la = sb[0] * sb[0], lb = sb[1] * sb[1];
    bl = fmin(mb[0] * la, fmin(mb[0] * lb, fmin(mb[1] * la, mb[1] * lb)));
    bh = fmax(mb[0] * la, fmax(mb[0] * lb, fmax(mb[1] * la, mb[1] * lb)));
    k->c_m = fmax(fabs(mh - bl), fabs(ml - bh));
}

/* Ranges, over x, of the level-0 spline phi's sums S = sum_p phi_s(x - p + s), M1 = sum_p (x - p)
 * phi_s(..), M2 = sum_p (x - p)^2 phi_s(..) (period 1), and of Q = M2 - tau, tau = frac(x)(1 - frac(x))
 * the hats' second moment; on a fine grid plus each term's Lipschitz margin. */
static int level0_sums(wvol__fhat_link *k, const wvol_basis *b)
{
    int L = b->length;
    double n = fmax(4096.0, fmin(65536.0, 65536.0 * 8.0 / L)), h = 1.0 / n, dm = b->exact ? 0.0 : b->dmax[WVOL_BASIS_PHI],
           vm = b->vmax[WVOL_BASIS_PHI], r[4][2], lip[4];
    long i;
    int q, p, np = 0;
    for (q = 0; q < 4; q++) r[q][0] = INFINITY, r[q][1] = -INFINITY;
    for (i = 0; i < (long)n; i++) {
        double x = (i + 0.5) * h, v[4] = {0, 0, 0, 0};
        int cnt = 0;
        for (p = -L - 2; p <= L + 2; p++) {
            double ph = wvol_basis_value(b, WVOL_BASIS_PHI, x - p + b->center), w = x - p;
            if (ph == 0.0) continue;
            v[0] += ph, v[1] += w * ph, v[2] += w * w * ph;
            cnt++;
        }
        v[3] = v[2] - x * (1.0 - x);
        if (cnt > np) np = cnt;
        for (q = 0; q < 4; q++) r[q][0] = fmin(r[q][0], v[q]), r[q][1] = fmax(r[q][1], v[q]);
    }
    /* per term: phi_s moves by dm, (x - p) phi_s by L dm + vm, (x - p)^2 phi_s by L^2 dm + 2 L vm
     * (|x - p| <= L where phi_s is not 0); tau by 1. Haar's boxes jump on the grid's midpoints'
     * complement: between grid points they are constant */
    lip[0] = np * dm, lip[1] = np * (L * dm + vm), lip[2] = np * (L * L * dm + 2.0 * L * vm), lip[3] = lip[2] + 1.0;
    for (q = 0; q < 4; q++) r[q][0] -= 0.5 * h * lip[q], r[q][1] += 0.5 * h * lip[q];
    k->S[0] = r[0][0], k->S[1] = r[0][1];
    k->m1 = fmax(fabs(r[1][0]), fabs(r[1][1]));
    k->m2 = fmax(fabs(r[2][0]), fabs(r[2][1]));
    k->qmax = fmax(fabs(r[3][0]), fabs(r[3][1]));
    k->smax = fmax(fabs(k->S[1] * k->S[1] * k->S[1] - 1.0), fabs(k->S[0] * k->S[0] * k->S[0] - 1.0));
    k->pmax = fmax(k->S[1] * k->S[1], k->S[0] * k->S[0]);
    k->p1 = fmax(fabs(k->S[1] * k->S[1] - 1.0), fabs(k->S[0] * k->S[0] - 1.0));
    if (!(k->S[0] > 0)) k->smax = INFINITY;
    return 1;
}

void wvol__fhat_link_init(wvol__fhat_link *k, const wvol_store *s)
{
    const wvol_basis *b = wvol_store_basis(s);
    wvol_store_info info;
    factor fac[WVOL_SELECT_MAX_LEVELS + 1][2];
    double d[WVOL_SELECT_MAX_LEVELS + 1][2], va[WVOL_SELECT_MAX_LEVELS + 1][2], vb[WVOL_SELECT_MAX_LEVELS + 1][2];
    double h = 1.0 / SAMPLES_PER_UNIT, margin;
    int m, w, band, M, ok = 1, i, p, L;
    memset(k, 0, sizeof *k);
    memset(fac, 0, sizeof fac);
    wvol_store_get_info(s, &info);
    if (!b || !b->filter || !info.transformed[0] || !info.transformed[1] || !info.transformed[2] || info.levels < 1 ||
        info.levels > WVOL_SELECT_MAX_LEVELS)
        return;
    M = k->M = info.levels;
    L = k->L = b->length;
    k->shift = b->center;
    k->scale = ldexp(1.0, M);
    k->norm = pow(k->scale, -1.5);
    /* g_s - interp: the window of samples p reaching x in [c0, c1] (phi(x - p + s) with support
     * (0, L - 1), and the hat over [c0, c1]); D and A, per x the sums over p, each term moving by
     * at most (max|phi'| + 1) h / 2 within half a step (Haar's box moves only with the hat) */
    k->below = (int)ceil((double)(L - 1) - b->center);
    k->above = (int)ceil(b->center);
    if (k->below < 0) k->below = 0;
    if (k->above < 1) k->above = 1;
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
        k->D = fmax(k->D, sd + np * margin);
        k->A = fmax(k->A, sa + np * margin);
    }
    ok = level0_sums(k, b);
    k->K = k->D * (k->A * k->A + k->A + 1.0);
    /* f^ - g_s: per level and factor, the spline function against its two-scale expansion */
    for (m = 1; m <= M && ok; m++)
        for (w = 0; w < 2 && ok; w++) {
            ok = factor_init(&fac[m][w], b, m, w);
            if (ok) factor_sups(&fac[m][w], &d[m][w], &va[m][w], &vb[m][w]);
        }
    if (ok) {
        for (m = 1; m <= M; m++)
            for (band = 1; band < 8; band++) {
                int w0 = band & 1, w1 = (band >> 1) & 1, w2 = (band >> 2) & 1;
                k->F[m][band] = d[m][w0] * va[m][w1] * va[m][w2] + vb[m][w0] * d[m][w1] * va[m][w2] +
                                vb[m][w0] * vb[m][w1] * d[m][w2];
            }
        lowpass_consts(k, &fac[M][0]);
    }
    for (m = 1; m <= M; m++)
        for (w = 0; w < 2; w++) free((void *)fac[m][w].r);
    k->ok = ok && isfinite(k->smax) && isfinite(k->K) && isfinite(k->qmax) && isfinite(k->c_res) && isfinite(k->c_u) && isfinite(k->c_m);
}

/* g_s - interp over one group's window [w0, w1] (stored-box indices) for x in the group's box
 * [x0, x1] (the same indices): the samples fitted by a quadric, c0[p] = a0 + g . u + sum_a q_a u_a^2
 * + sum_{a<b} h_ab u_a u_b + r[p], u = p - pbar (least squares; on the window's box the centred
 * monomials 1, u_a, u_a^2 - mean, u_a u_b are orthogonal, so each coefficient is one projection).
 * With v = x - pbar and per axis S, M1, M2 the spline's sums and tau the hats' second moment
 * (P the other two axes' S product):
 *   sum_p u_a (Phi_s - Lambda)     = v_a (S_a P - 1) - M1_a P
 *   sum_p u_a^2 (Phi_s - Lambda)   = v_a^2 (S_a P - 1) - 2 v_a M1_a P + (M2_a P - tau_a)
 *   sum_p u_a u_b (Phi_s - Lambda) = (v_a S_a - M1_a)(v_b S_b - M1_b) S_c - v_a v_b
 * and the residual adds at most max|r| D (A^2 + A + 1). M2 - tau is the one part that does not
 * vanish for a good spline: the trilinear interpolant's own error on a curved field. */
static double sample_part(const wvol__fhat_link *k, const float *s, const size_t md[3], const long w0[3],
                          const long w1[3], const long x0[3], const long x1[3], double *mag)
{
    double pbar[3], cm[3], n1[3], n2[3], g[3] = {0, 0, 0}, q[3] = {0, 0, 0}, hx[3] = {0, 0, 0}, a0 = 0, r = 0, e,
           V[3], cnt = 1;
    long i[3], n;
    int a;
    *mag = 0.0;
    for (a = 0; a < 3; a++) {
        n = w1[a] - w0[a] + 1;
        pbar[a] = 0.5 * (double)(w0[a] + w1[a]);
        n1[a] = (double)(n * n - 1) * (double)n / 12.0; /* sum of u^2 along the axis */
        cm[a] = n1[a] / (double)n;                      /* mean of u^2 */
        n2[a] = 0.0;                                    /* sum of (u^2 - cm)^2 */
        for (i[0] = w0[a]; i[0] <= w1[a]; i[0]++) {
            double u = (double)i[0] - pbar[a];
            n2[a] += (u * u - cm[a]) * (u * u - cm[a]);
        }
        cnt *= (double)n;
        V[a] = fmax(fabs((double)x0[a] - pbar[a]), fabs((double)x1[a] - pbar[a]));
    }
    for (i[2] = w0[2]; i[2] <= w1[2]; i[2]++)
        for (i[1] = w0[1]; i[1] <= w1[1]; i[1]++)
            for (i[0] = w0[0]; i[0] <= w1[0]; i[0]++) {
                double v = s[(size_t)i[0] + md[0] * ((size_t)i[1] + md[1] * (size_t)i[2])], u[3];
                for (a = 0; a < 3; a++) u[a] = (double)i[a] - pbar[a];
                a0 += v;
                for (a = 0; a < 3; a++) g[a] += u[a] * v, q[a] += (u[a] * u[a] - cm[a]) * v;
                hx[0] += u[1] * u[2] * v, hx[1] += u[0] * u[2] * v, hx[2] += u[0] * u[1] * v;
                if (fabs(v) > *mag) *mag = fabs(v);
            }
    a0 /= cnt;
    for (a = 0; a < 3; a++) {
        double other = cnt / (double)(w1[a] - w0[a] + 1); /* points per value of u_a */
        g[a] = n1[a] > 0 ? g[a] / (n1[a] * other) : 0.0;
        q[a] = n2[a] > 0 ? q[a] / (n2[a] * other) : 0.0;
    }
    for (a = 0; a < 3; a++) { /* u_b u_c, b, c the other two axes */
        int b = (a + 1) % 3, c = (a + 2) % 3;
        double den = n1[b] * n1[c] * (double)(w1[a] - w0[a] + 1);
        hx[a] = den > 0 ? hx[a] / den : 0.0;
    }
    for (a = 0; a < 3; a++) a0 -= q[a] * cm[a]; /* back to the plain monomials */
    for (i[2] = w0[2]; i[2] <= w1[2]; i[2]++)
        for (i[1] = w0[1]; i[1] <= w1[1]; i[1]++)
            for (i[0] = w0[0]; i[0] <= w1[0]; i[0]++) {
                double v = s[(size_t)i[0] + md[0] * ((size_t)i[1] + md[1] * (size_t)i[2])], u[3];
                for (a = 0; a < 3; a++) u[a] = (double)i[a] - pbar[a];
                v -= a0 + hx[0] * u[1] * u[2] + hx[1] * u[0] * u[2] + hx[2] * u[0] * u[1];
                for (a = 0; a < 3; a++) v -= g[a] * u[a] + q[a] * u[a] * u[a];
                if (fabs(v) > r) r = fabs(v);
            }
    e = r * k->K + fabs(a0) * k->smax;
    for (a = 0; a < 3; a++) {
        int b = (a + 1) % 3, c = (a + 2) % 3;
        e += fabs(g[a]) * (V[a] * k->smax + k->m1 * k->pmax);
        e += fabs(q[a]) * (V[a] * V[a] * k->smax + 2.0 * V[a] * k->m1 * k->pmax + k->qmax + k->m2 * k->p1);
        e += fabs(hx[a]) * (V[b] * V[c] * k->smax + (V[b] + V[c]) * k->m1 * k->pmax + k->m1 * k->m1 * k->S[1]);
    }
    return e;
}

/* Index range [*k0, *k1] of the level-M positions whose support meets [x0, x1] (widened: extra
 * positions add nothing, their functions are 0 there). */
static void reach(const wvol__fhat_link *k, double x0, double x1, long *k0, long *k1)
{
    *k0 = (long)ceil((x0 + k->shift) / k->scale - (k->L - 1) - 1e-9);
    *k1 = (long)floor((x1 + k->shift) / k->scale + 1e-9);
}

double wvol__fhat_link_bound(const wvol__fhat_link *k, const float *s, const size_t md[3], const size_t core[3],
                             const size_t c0[3], const size_t cells[3], int group, const wvol_store_hit *hits,
                             size_t nh, double *out)
{
    size_t gn[3], ng, i;
    long kb0[3], kb1[3], kn[3], gi[3];
    double *low, worst = 0.0;
    int a;
    if (!k->ok) return INFINITY;
    for (a = 0; a < 3; a++) {
        gn[a] = (cells[a] + (size_t)group - 1) / (size_t)group;
        reach(k, (double)c0[a], (double)(c0[a] + cells[a]), &kb0[a], &kb1[a]);
        kn[a] = kb1[a] - kb0[a] + 1;
        if ((long)core[a] < k->below || core[a] + cells[a] + (size_t)k->above >= md[a])
            return INFINITY; /* the samples' window is not stored (a face clipped it) */
    }
    ng = gn[0] * gn[1] * gn[2];
    low = calloc((size_t)(kn[0] * kn[1] * kn[2]), sizeof *low);
    if (!low) return INFINITY;
    memset(out, 0, ng * sizeof *out);
    for (i = 0; i < nh; i++) {
        const wvol_store_hit *h = &hits[i];
        long lo[3], hi[3], x, y, z;
        if (h->band == 0) { /* the low-pass band: its position's value */
            long kk[3];
            for (a = 0; a < 3; a++) {
                kk[a] = lround((h->lo[a] + k->shift) / k->scale) - kb0[a];
                if (kk[a] < 0 || kk[a] >= kn[a]) break;
            }
            if (a == 3) low[kk[0] + kn[0] * (kk[1] + kn[1] * kk[2])] = h->value;
            continue;
        }
        for (a = 0; a < 3; a++) { /* the groups its support box meets */
            double g0 = (h->lo[a] - (double)c0[a]) / group, g1 = (h->hi[a] - (double)c0[a]) / group;
            lo[a] = g0 <= 0 ? 0 : (long)ceil(g0) - 1;
            hi[a] = g1 >= (double)gn[a] ? (long)gn[a] - 1 : (long)floor(g1);
            if (lo[a] > hi[a]) break;
        }
        if (a < 3) continue;
        {
            double v = fabs((double)h->value) * k->F[h->level][h->band];
            for (z = lo[2]; z <= hi[2]; z++)
                for (y = lo[1]; y <= hi[1]; y++)
                    for (x = lo[0]; x <= hi[0]; x++) out[(size_t)x + gn[0] * ((size_t)y + gn[1] * (size_t)z)] += v;
        }
    }
    for (gi[2] = 0; gi[2] < (long)gn[2]; gi[2]++)
        for (gi[1] = 0; gi[1] < (long)gn[1]; gi[1]++)
            for (gi[0] = 0; gi[0] < (long)gn[0]; gi[0]++) {
                double x0[3], x1[3], kbar[3], den[3], g[3] = {0, 0, 0}, a0 = 0, q = 0, e, cnt = 1, mag;
                long w0[3], w1[3], p[3], sx0[3], sx1[3], sw0[3], sw1[3];
                size_t gidx = (size_t)gi[0] + gn[0] * ((size_t)gi[1] + gn[1] * (size_t)gi[2]);
                for (a = 0; a < 3; a++) {
                    long n;
                    x0[a] = (double)(c0[a] + (size_t)gi[a] * (size_t)group);
                    x1[a] = fmin(x0[a] + group, (double)(c0[a] + cells[a]));
                    reach(k, x0[a], x1[a], &w0[a], &w1[a]);
                    n = w1[a] - w0[a] + 1;
                    kbar[a] = 0.5 * (double)(w0[a] + w1[a]);
                    den[a] = (double)(n * n - 1) * (double)n / 12.0; /* sum of (k - kbar)^2 along the axis */
                    cnt *= (double)n;
                    /* the same box and its samples' window in stored-box indices */
                    sx0[a] = (long)core[a] + gi[a] * group;
                    sx1[a] = sx0[a] + (long)(x1[a] - x0[a]);
                    sw0[a] = sx0[a] - k->below;
                    sw1[a] = sx1[a] + k->above;
                }
                /* f^ - g_s, low-pass: the least-squares plane over the window (a box: the axes separate) */
                for (p[2] = w0[2]; p[2] <= w1[2]; p[2]++)
                    for (p[1] = w0[1]; p[1] <= w1[1]; p[1]++)
                        for (p[0] = w0[0]; p[0] <= w1[0]; p[0]++) {
                            double v = low[(p[0] - kb0[0]) + kn[0] * ((p[1] - kb0[1]) + kn[1] * (p[2] - kb0[2]))];
                            a0 += v;
                            for (a = 0; a < 3; a++) g[a] += ((double)p[a] - kbar[a]) * v;
                        }
                a0 /= cnt;
                for (a = 0; a < 3; a++) g[a] = den[a] > 0 ? g[a] / (den[a] * cnt / (double)(w1[a] - w0[a] + 1)) : 0.0;
                for (p[2] = w0[2]; p[2] <= w1[2]; p[2]++)
                    for (p[1] = w0[1]; p[1] <= w1[1]; p[1]++)
                        for (p[0] = w0[0]; p[0] <= w1[0]; p[0]++) {
                            double v = low[(p[0] - kb0[0]) + kn[0] * ((p[1] - kb0[1]) + kn[1] * (p[2] - kb0[2]))];
                            for (a = 0; a < 3; a++) v -= g[a] * ((double)p[a] - kbar[a]);
                            q = fmax(q, fabs(v - a0));
                        }
                e = fabs(a0) * k->c_u + q * k->c_res;
                for (a = 0; a < 3; a++) {
                    double u = fmax(fabs((x0[a] + k->shift) / k->scale - kbar[a]), fabs((x1[a] + k->shift) / k->scale - kbar[a]));
                    e += fabs(g[a]) * (u * k->c_u + k->c_m);
                }
                /* + the details, + g_s - interp from the samples */
                            e = k->norm * e + out[gidx] + sample_part(k, s, md, sw0, sw1, sx0, sx1, &mag);
                /* the float64 sums (relative) and the float32 samples (of their magnitude) */
                e = e * (1.0 + 1e-9) + 1e-5 * mag * (1.0 + k->K);
                out[gidx] = e;
                if (e > worst) worst = e;
            }
    free(low);
    return worst;
}
