/* SPDX-License-Identifier: MIT
 * A tighter rigorous range of f^ on a small cell (wvol__iso_box_range_tensor): the coarsest
 * level's functions summed exactly as tensor-product Bernstein forms on the cell's patches of
 * that level's lattice, the finer levels' functions as intervals (trace_cells.c's factor
 * ranges). The interval range of wvol__iso_box_range_list cannot see the cancellation between
 * the coarsest level's functions (the low-pass band and its details dominate a 2-voxel cell's
 * interval width on the skull); their sum is one cubic per axis on every lattice patch, so its
 * Bernstein hull on each patch is a range of their sum itself.
 * Based on: DESIGN.md section 9; docs/iso.md; Farouki & Rajan 1987 (Bernstein form ranges). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "iso_internal.h"

/* the coarsest level's lattice patches a cell may have per axis (a 2-voxel cell on the
 * half-voxel lattice of level 3 at J = 4 has 5): more and the cell is left to the interval range */
#define TT_P WVOL__TT_P
/* distinct translates a cell's level-M functions may have per axis (more: no tensor range) */
#define TT_SPAN WVOL__TT_SPAN

static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

/* The cubic c(u) (u in [0, h] on its piece) restricted to [u0, u1] as Bernstein coefficients
 * in t in [0, 1], u = u0 + (u1 - u0) t. */
static void restrict_bernstein(const double c[4], double u0, double u1, double bz[4])
{
    double a[4];
    wvol_poly3_affine(a, c, u1 - u0, u0);
    wvol_poly3_bernstein(bz, a);
}

typedef struct axis_split {
    int P;              /* sub-intervals of the cell's side: the cell's [lo, hi] cut at the lattice */
    double e[TT_P + 1]; /* their edges */
    int64_t j0;         /* the translates' offset for the factor cache */
    int pc;             /* the sub-interval holding the cell's centre */
} axis_split;

/* The factor of a level-M function (translate j, which) on every sub-interval of its axis, as
 * Bernstein coefficients (zero where the sub-interval misses the support): each sub-interval lies
 * in one piece (the piece holding its midpoint; a computed lattice edge may be off the true knot
 * by rounding, which the Lipschitz term of the pad covers). */
static void factor_bz(const wvol__iso_boxk *k, const axis_split *s, double flo, double sc, int which, double *out)
{
    int p;
    for (p = 0; p < s->P; p++) {
        double u0 = (s->e[p] - flo) * sc, u1 = (s->e[p + 1] - flo) * sc, um = 0.5 * (u0 + u1), *bz = out + 4 * p;
        long i;
        if (!(um >= 0.0) || um >= k->support) {
            bz[0] = bz[1] = bz[2] = bz[3] = 0.0;
            continue;
        }
        i = (long)(um * k->per_unit);
        if (i >= k->pieces) i = k->pieces - 1;
        u0 = dmin(dmax(u0 - (double)i * k->h, 0.0), k->h);
        u1 = dmin(dmax(u1 - (double)i * k->h, 0.0), k->h);
        restrict_bernstein(wvol_basis_coeffs(k->basis, which, WVOL_BASIS_VALUE, (int)i), u0, u1, bz);
    }
}

/* The Bernstein cubic bz at t in [0, 1]. */
static inline double bern_eval(const double bz[4], double t)
{
    double r = 1.0 - t;
    return r * r * r * bz[0] + 3.0 * t * r * (r * bz[1] + t * bz[2]) + t * t * t * bz[3];
}

static inline int key_of(const wvol__iso_boxk *k, const wvol_store_hit *h, const axis_split *sp, int a, double sc)
{
    int64_t j = (int64_t)floor((h->lo[a] + k->shift) * sc + 0.5) - sp[a].j0;
    return j < 0 || j >= TT_SPAN ? -1 : (int)j * 2 + ((h->band >> a) & 1);
}

WVOL__CLONES int wvol__iso_box_class_tensor(const wvol__iso_boxk *k, wvol__tensor_ws *w, const wvol_store_hit *hits,
                                            size_t n, const double lo[3], const double hi[3], const double fine[2],
                                            double iso)
{
    const int M = k->levels;
    const double d = ldexp(k->h, M), sc = k->inv_size[M]; /* lattice spacing (voxels) */
    axis_split sp[3];
    size_t i, nm = 0;
    double mid = fine[0], dev = fine[1], mag = 0, lip = 0, pt = 0, tmin = INFINITY, tmax = -INFINITY, pc[3], tc[3], pad;
    int a, kx, ky, nkx = 0, xs[2 * TT_SPAN];
    if (!k->basis || !k->prange || M < 1 || M > WVOL__TT_LEVELS) return -1;
    for (a = 0; a < 3; a++) {
        axis_split *s = &sp[a];
        double x;
        int64_t nl;
        if (!k->transformed[a]) return -1;
        s->P = 0;
        s->e[0] = lo[a];
        nl = (int64_t)floor((lo[a] + k->shift) / d) + 1; /* the first knot past lo */
        for (x = (double)nl * d - k->shift; x < hi[a]; x = (double)(++nl) * d - k->shift) {
            if (x <= s->e[s->P]) continue;
            if (s->P + 1 >= TT_P) return -1;
            s->e[++s->P] = x;
        }
        s->e[++s->P] = hi[a];
        s->j0 = (int64_t)floor((lo[a] + k->shift) * sc - k->support) - 1;
        /* the cell's centre: its sub-interval and local parameter (the pre-test's point) */
        pc[a] = 0.5 * (lo[a] + hi[a]);
        for (s->pc = 0; s->pc + 1 < s->P && s->e[s->pc + 1] <= pc[a]; s->pc++) {}
        tc[a] = s->e[s->pc + 1] > s->e[s->pc] ? (pc[a] - s->e[s->pc]) / (s->e[s->pc + 1] - s->e[s->pc]) : 0.0;
    }
    /* the factors per (axis, translate, which), the level-M functions bucketed by their x and
     * y keys (translate, which); the level-M part of f^ at the cell's centre */
    memset(w->have, 0, sizeof w->have);
    memset(w->cnt, 0, sizeof w->cnt);
    for (i = 0; i < n; i++) {
        const wvol_store_hit *h = &hits[i];
        int key[3];
        double v = (double)h->value * h->norm;
        if (h->level != M) continue;
        for (a = 0; a < 3; a++) {
            key[a] = key_of(k, h, sp, a, sc);
            if (key[a] < 0) return -1;
            if (!w->have[a][key[a]]) {
                factor_bz(k, &sp[a], h->lo[a], sc, (h->band >> a) & 1, w->f[a][key[a]]);
                w->fc[a][key[a]] = bern_eval(w->f[a][key[a]] + 4 * sp[a].pc, tc[a]);
                w->have[a][key[a]] = 1;
            }
            v *= w->fc[a][key[a]];
        }
        pt += v;
        w->cnt[key[0]][key[1]]++;
        nm++;
    }
    /* a value of f^ in the cell within the finer levels' half-width of iso: the range cannot
     * exclude iso (the test only skips work; it never decides a cell) */
    if (fabs(pt + mid - iso) <= dev) return -1;
    /* prefix sums: the level-M functions in (x key, y key) order */
    {
        size_t acc = 0;
        for (kx = 0; kx < 2 * TT_SPAN; kx++)
            for (ky = 0; ky < 2 * TT_SPAN; ky++) {
                size_t c = w->cnt[kx][ky];
                w->cnt[kx][ky] = acc;
                acc += c;
            }
    }
    if (nm > w->cap) {
        uint32_t *o = realloc(w->order, nm * sizeof *o);
        if (!o) return -1;
        w->order = o;
        w->cap = nm;
    }
    for (i = 0; i < n; i++) {
        const wvol_store_hit *h = &hits[i];
        if (h->level != M) continue;
        w->order[w->cnt[key_of(k, h, sp, 0, sc)][key_of(k, h, sp, 1, sc)]++] = (uint32_t)i;
    }
    /* T[p q r][a b c] = sum_f c_f norm_f X_f[p][a] Y_f[q][b] Z_f[r][c], factorised: per (x, y) key
     * the Z factors summed, per x key W[q b][r c] = sum_y Y[q][b] Zs[r][c], then per x
     * sub-interval p the rows T[p a] = sum_x X[p][a] W, whose hull grows slab by slab */
    {
        const int Px = sp[0].P, Py = sp[1].P, Pz = sp[2].P, nzc = 4 * Pz, nw = 4 * Py * nzc;
        size_t at = 0;
        for (kx = 0; kx < 2 * TT_SPAN; kx++) {
            double *wk = w->w + (size_t)nkx * (size_t)nw;
            int anyx = 0;
            for (ky = 0; ky < 2 * TT_SPAN; ky++) {
                size_t end = w->cnt[kx][ky]; /* after the fill: the group's end */
                double zs[4 * TT_P];
                int q, r;
                if (at == end) continue;
                if (!anyx) memset(wk, 0, sizeof(double) * (size_t)nw), anyx = 1;
                memset(zs, 0, sizeof zs);
                for (; at < end; at++) {
                    const wvol_store_hit *h = &hits[w->order[at]];
                    double c = (double)h->value * h->norm;
                    const double *z = w->f[2][key_of(k, h, sp, 2, sc)];
                    for (r = 0; r < nzc; r++) zs[r] += c * z[r];
                    mag += fabs(c) * k->bmax3[h->band];
                    lip += fabs(c) * k->lip3[h->band];
                }
                /* W[q b][r c] += Y[q][b] Zs[r c] */
                for (q = 0; q < 4 * Py; q++) {
                    double y = w->f[1][ky][q];
                    double *row = wk + (size_t)q * nzc;
                    if (y == 0.0) continue;
                    for (r = 0; r < nzc; r++) row[r] += y * zs[r];
                }
            }
            if (anyx) xs[nkx++] = kx;
        }
        /* Rounding: every tensor coefficient is a sum of nm terms c norm X Y Z, each a product of
         * four factors, the factors restrictions of a cubic (tens of operations deep): its error is
         * below (nm + 64) 2^-52 mag, mag = sum |c| norm prod_a max|Bernstein coefficient|; a lattice
         * edge computed off its knot by rounding (< 1e-12 of a unit) moves a factor by less than its
         * Lipschitz constant times that (lip = sum |c| norm sum_a dmax_a prod_{b != a} vmax_b). Both
         * are padded at least a thousandfold; the intervals carry their own padding. */
        pad = (1e-9 + 1e-14 * (double)nm) * (mag + lip);
        for (int p = 0; p < Px; p++) {
            for (int c4 = 0; c4 < 4; c4++) {
                double *row = w->t;
                int j, q;
                for (q = 0; q < nw; q++) row[q] = 0.0;
                for (j = 0; j < nkx; j++) {
                    double x = w->f[0][xs[j]][4 * p + c4];
                    const double *wk = w->w + (size_t)j * (size_t)nw;
                    if (x == 0.0) continue;
                    for (q = 0; q < nw; q++) row[q] += x * wk[q];
                }
                for (q = 0; q < nw; q++) {
                    tmin = dmin(tmin, row[q]);
                    tmax = dmax(tmax, row[q]);
                }
            }
            /* the hull only grows: once it reaches iso from both sides the cell stays undecided */
            if (tmin + mid - dev - pad - 1e-9 * fabs(tmin) <= iso && tmax + mid + dev + pad + 1e-9 * fabs(tmax) >= iso)
                return -1;
        }
    }
    if (!nm) tmin = tmax = 0.0;
    tmin += mid - dev - pad - 1e-9 * fabs(tmin);
    tmax += mid + dev + pad + 1e-9 * fabs(tmax);
    return tmin > iso ? 1 : tmax < iso ? 0 : -1;
}
