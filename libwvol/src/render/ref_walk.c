/* SPDX-License-Identifier: MIT
 * The reference integrator's ray walk: one ray's samples at the midpoints of steps of dt,
 * front to back, in runs of full steps, one run per brick crossed (skipped where the
 * brick's contribution rate allows: ray_skip), then the last, shorter step. The runs' sample
 * loops (ref_samples.h) are inlined into a few copies of the run, one per common case
 * (ray_advance_any). */
#include "ref_samples.h"
#include "core/clones.h"

/* The walk's two entry points are multi-versioned (core/clones.h: AVX2 where the CPU has it;
 * the sample loops are inlined into them) with contraction off, so that no clone fuses a
 * multiply and an add: every clone rounds as the baseline does, the same image bit for bit. */
#define RAY_CLONES WVOL__CLONES WVOL__NO_CONTRACT

#include <string.h>

/* The ray's world direction, for shading (a tile's rays are held for the whole walk, so
 * their states are kept small): e times the spacing, the direction to an ulp. */
static inline void ray_dir(const wvol__source *s, const ray_state *st, double d[3])
{
    for (int a = 0; a < 3; a++) d[a] = st->e[a] * s->spacing[a];
}

void wvol__ray_begin(const wvol__source *s, const double o[3], const double d[3], double t0, double t1, double dt,
                     ray_state *st)
{
    memset(st, 0, sizeof *st);
    for (int a = 0; a < 3; a++) {
        st->x0[a] = (o[a] - s->origin[a]) / s->spacing[a];
        st->e[a] = d[a] / s->spacing[a];
    }
    st->t0 = t0, st->t1 = t1, st->t_exit = -INFINITY, st->bid = -1;
    st->r.T = 1.0, st->r.seg = -1, st->r.T_lim = -1.0;
    st->nsteps = (long)ceil((t1 - t0) / dt);
    if (st->nsteps < 1) st->nsteps = 1;
    st->nfull = st->nsteps;
    while (st->nfull > 0 && t0 + (double)st->nfull * dt > t1) st->nfull--; /* steps ending by t1 */
}

/* Enters the brick holding x (sample parameter t; clamped to the grid) when t is at or past
 * the current one's exit, and finds where the ray leaves it: per axis the face it moves
 * towards. */
static inline void ray_enter(const wvol__source *s, ray_state *st, const double x[3], double t)
{
    double te = INFINITY;
    long b[3];
    if (t < st->t_exit) return;
    for (int a = 0; a < 3; a++) {
        double c = s->B_inv > 0 ? (x[a] + 0.5) * s->B_inv : (x[a] + 0.5) / s->B, lo, ta;
        b[a] = c > 0 ? (long)c : 0;
        if (b[a] > (long)s->bn[a] - 1) b[a] = (long)s->bn[a] - 1;
        lo = (double)b[a] * s->B - 0.5;
        if (st->e[a] > 0) ta = (lo + s->B - x[a]) / st->e[a];
        else if (st->e[a] < 0) ta = (lo - x[a]) / st->e[a];
        else continue;
        if (ta < te) te = ta;
    }
    st->bid = b[0] + (long)s->bn[0] * (b[1] + (long)s->bn[1] * b[2]);
    for (int a = 0; a < 3; a++) st->bc[a] = (int32_t)b[a];
    st->t_exit = t + te;
}

/* Whether the ray's next `len` world units, in its current brick, are skipped: the brick's
 * contribution rate (wvol__brick_rate) is 0, or times len it fits in what is left of the
 * ray's skip tolerance, which it then spends (st->skipped). Otherwise returns 0 with *view
 * the brick's (fetched anew each time, a cache lookup, since another ray may have evicted
 * it; a dense source keeps the whole volume's); -1 when the fetch failed. */
static inline __attribute__((always_inline)) int ray_skip(const wvol__source *s, void *tc, ray_state *st,
                                                          double tol, double len, const wvol__view **view)
{
    double rate, allow = tol > st->skipped ? (tol - st->skipped) / len : 0.0;
    if (s->ops == &wvol__dense_ops) { /* its fetch inline (wvol__dense_src): a table read */
        rate = ((const wvol__dense_src *)s->ctx)->rate[st->bid];
    } else {
        st->failed = s->ops->fetch(s, tc, (size_t)st->bid, allow, view, &rate);
        if (st->failed != WVOL_OK) return -1;
    }
    if (rate > allow) return 0;
    if (rate > 0) {
        st->skipped += rate * len;
        st->nskip_tol++;
    }
    st->nskip++;
    return 1;
}

/* The samples of steps *kp .. ke - 1 in one view, front to back. When a run's first and last
 * sample lie strictly inside the view its samples are taken without clamping tests
 * (run_blocked). Returns 1 when the ray terminates (*kp: the step it ended at), else 0 with
 * *kp = ke. */
static inline __attribute__((always_inline)) int take_steps(const wvol__source *s, const wvol__view *view,
                                                            const tf_fast *tfx, const wvol_render_params *p,
                                                            const wvol_render_mode mode, const int shading,
                                                            const int colors, const double *x0, const double *e,
                                                            const double d[3], double t0, double dt, long *kp,
                                                            long ke, ray_acc *r)
{
    if (s->ops->eval) return run(s, view, tfx, p, mode, shading, colors, 0, x0, e, d, t0, dt, kp, ke, r);
#if defined(__SSE2__)
    if (view->local && view->blocked_ok && !shading && !colors && !p->preintegrate)
        /* a brick's view: block_positions_local clamps every position to it, so the samples
         * in a face's outer half voxel need no clamping path of their own */
        return run_blocked(view, tfx, p, mode, x0, e, t0, dt, kp, ke, r);
#endif
    {
        /* the steps whose samples lie strictly inside the view are an interval (x is
         * linear in t); the few outside it, where the ray enters or leaves the volume
         * through a face's outer half voxel, take the clamping path */
        long kin = *kp, kout = ke;
        double x[3], xl[3];
        int a;
        for (a = 0; a < 3; a++) x[a] = x0[a] + (t0 + ((double)kin + 0.5) * dt) * e[a];
        while (kin < kout && !strictly_inside(view, x)) {
            kin++;
            for (a = 0; a < 3; a++) x[a] = x0[a] + (t0 + ((double)kin + 0.5) * dt) * e[a];
        }
        for (a = 0; a < 3; a++) xl[a] = x0[a] + (t0 + ((double)(kout - 1) + 0.5) * dt) * e[a];
        while (kout > kin && !strictly_inside(view, xl)) {
            kout--;
            for (a = 0; a < 3; a++) xl[a] = x0[a] + (t0 + ((double)(kout - 1) + 0.5) * dt) * e[a];
        }
        return run(s, view, tfx, p, mode, shading, colors, 0, x0, e, d, t0, dt, kp, kin, r) ||
               run(s, view, tfx, p, mode, shading, colors, 1, x0, e, d, t0, dt, kp, kout, r) ||
               run(s, view, tfx, p, mode, shading, colors, 0, x0, e, d, t0, dt, kp, ke, r);
    }
}

/* A walk through a brick's sub-cells (wvol__view.sub_zero) along the ray, a 3D DDA: the
 * sub-cell c, per axis the parameter t where the ray leaves it (tmax) and the parameter a
 * sub-cell spans (tdelta). Its t are the ray's, rounded within ~1e-13 relative, and each
 * sub-cell's voxel range reaches half a voxel beyond its cells on every side, so a sample
 * that the walk places in a sub-cell touches only that sub-cell's voxels. */
typedef struct sub_dda {
    long c[3], step[3];
    double tmax[3], tdelta[3];
} sub_dda;

static inline void sub_dda_init(sub_dda *dd, const wvol__view *v, const ray_state *st, double t)
{
    const double S = v->sub_S;
    for (int a = 0; a < 3; a++) {
        const double x = st->x0[a] + t * st->e[a], o = (double)v->sub_org[a] - 0.5;
        const double c = floor(v->sub_S_inv > 0 ? (x - o) * v->sub_S_inv : (x - o) / S);
        /* one division per axis: the faces' parameters are rounded anyway (above) */
        const double inv = 1.0 / st->e[a];
        dd->c[a] = (long)c;
        if (st->e[a] > 0) {
            dd->step[a] = 1;
            dd->tmax[a] = t + (o + (c + 1) * S - x) * inv;
            dd->tdelta[a] = S * inv;
        } else if (st->e[a] < 0) {
            dd->step[a] = -1;
            dd->tmax[a] = t + (o + c * S - x) * inv;
            dd->tdelta[a] = -S * inv;
        } else {
            dd->step[a] = 0;
            dd->tmax[a] = INFINITY;
            dd->tdelta[a] = INFINITY;
        }
    }
}

/* The axis whose sub-cell face the ray meets first. */
static inline int sub_dda_axis(const sub_dda *dd)
{
    return dd->tmax[0] <= dd->tmax[1] ? (dd->tmax[0] <= dd->tmax[2] ? 0 : 2) : (dd->tmax[1] <= dd->tmax[2] ? 1 : 2);
}

/* 1 when the DDA's sub-cell has kappa 0 (outside the brick's sub-cells: 0, conservative). */
static inline int sub_dda_zero(const wvol__view *v, const sub_dda *dd)
{
    const long N = WVOL__SUB_N;
    long bit;
    if ((unsigned long)dd->c[0] >= (unsigned long)N || (unsigned long)dd->c[1] >= (unsigned long)N ||
        (unsigned long)dd->c[2] >= (unsigned long)N)
        return 0;
    bit = dd->c[0] + N * (dd->c[1] + N * dd->c[2]);
    return (int)((v->sub_zero[bit >> 6] >> (bit & 63)) & 1);
}

/* On through the sub-cells of the same kind as the DDA's (zero: its sub_dda_zero) while the
 * ray's parameter stays below t_end: returns the parameter where it enters one of the other
 * kind (the DDA then in it), or INFINITY when none comes before t_end (the DDA then in the
 * last sub-cell entered before it). The walk of sub_dda_axis and sub_dda_zero, its state in
 * registers: out of line, since in the walk's large inlined copies it went through memory. */
static __attribute__((noinline)) double sub_dda_same_until(const wvol__view *v, sub_dda *dd, int zero, double t_end)
{
    const long N = WVOL__SUB_N;
    long c0 = dd->c[0], c1 = dd->c[1], c2 = dd->c[2];
    const long s0 = dd->step[0], s1 = dd->step[1], s2 = dd->step[2];
    double m0 = dd->tmax[0], m1 = dd->tmax[1], m2 = dd->tmax[2];
    const double d0 = dd->tdelta[0], d1 = dd->tdelta[1], d2 = dd->tdelta[2];
    double te;
    for (;;) {
        int z;
        if (m0 <= m1 ? m0 <= m2 : 0) { /* sub_dda_axis: 0 */
            if (!((te = m0) < t_end)) break;
            c0 += s0;
            m0 += d0;
        } else if (m0 <= m1 || !(m1 <= m2)) { /* 2 */
            if (!((te = m2) < t_end)) break;
            c2 += s2;
            m2 += d2;
        } else { /* 1 */
            if (!((te = m1) < t_end)) break;
            c1 += s1;
            m1 += d1;
        }
        if ((unsigned long)c0 >= (unsigned long)N || (unsigned long)c1 >= (unsigned long)N ||
            (unsigned long)c2 >= (unsigned long)N) {
            z = 0;
        } else {
            const long bit = c0 + N * (c1 + N * c2);
            z = (int)((v->sub_zero[bit >> 6] >> (bit & 63)) & 1);
        }
        if (z != zero) goto out;
    }
    te = INFINITY;
out:
    dd->c[0] = c0, dd->c[1] = c1, dd->c[2] = c2;
    dd->tmax[0] = m0, dd->tmax[1] = m1, dd->tmax[2] = m2;
    return te;
}

/* The first step from k on (at most ke) whose sample is at or past parameter te: a guess
 * from dt_inv = 1 / dt, then corrected by the exact test, so the guess's rounding does not
 * matter (the samples' parameters grow with the step, so the answer is unique). The guess
 * is the smallest integer at or above (te - t0) / dt - 1/2, which is the answer but for
 * rounding: the two tests that confirm it do not depend on each other, where a guess one
 * below took a chain of three. */
static inline long first_step_at(double t0, double dt, double dt_inv, long k, long ke, double te)
{
    double q = (te - t0) * dt_inv + 0.5;
    long kk = q > (double)k ? (q < (double)ke ? (long)q : ke) : k;
    while (kk < ke && t0 + ((double)kk + 0.5) * dt < te) kk++;
    while (kk > k && !(t0 + ((double)(kk - 1) + 0.5) * dt < te)) kk--;
    return kk;
}

/* One run: the full steps of the ray in its next brick (all of them for an unbricked
 * source). Returns 1 while full steps remain. When a run's first and last sample lie
 * strictly inside the view its samples are taken without clamping tests (run_blocked). */
static inline __attribute__((always_inline)) int ray_advance(const wvol__source *s, void *tc, const tf_fast *tfx,
                                                             const wvol_render_params *p,
                                                             const wvol_render_mode mode, const int shading,
                                                             const int colors, double dt, ray_state *st)
{
    const wvol__view *view = &s->whole;
    const double t0 = st->t0, *x0 = st->x0, *e = st->e;
    long k = st->k, nfull = st->nfull, ke = nfull; /* this run: steps k .. ke - 1 */
    int a, bricked = s->B > 0, done;
    double x[3], d[3] = {0, 0, 0}, t;
#define T_AT(kk) (t0 + ((double)(kk) + 0.5) * dt)
    if (k >= nfull || st->done || st->failed != WVOL_OK) return 0;
    t = T_AT(k);
    for (a = 0; a < 3; a++) x[a] = x0[a] + t * e[a];
    if (bricked) {
        int skip;
        ray_enter(s, st, x, t);
        /* the first step after k whose sample is at or past the exit */
        if (st->t_exit < T_AT(nfull)) ke = first_step_at(t0, dt, s->dt_inv, k + 1, nfull, st->t_exit);
        skip = ray_skip(s, tc, st, p->skip_tolerance, (double)(ke - k) * dt, &view);
        if (skip < 0) return 0;
        if (skip) {
            if (p->preintegrate) preint_close(tfx, &st->r);
            st->k = ke;
            return ke < nfull;
        }
    }
    if (shading) ray_dir(s, st, d);
    if (view->sub_any) {
        /* the run cut where it enters or leaves sub-cells of kappa 0, whose samples add
         * nothing; the DDA stops only where that changes */
        sub_dda dd;
        done = 0;
        sub_dda_init(&dd, view, st, T_AT(k));
        while (!done && k < ke) {
            const double tk = T_AT(k);
            int zero, ax;
            long kn;
            double te;
            /* the sub-cell holding sample k (the ray may cross thin ones between samples) */
            while (dd.tmax[ax = sub_dda_axis(&dd)] <= tk) {
                dd.c[ax] += dd.step[ax];
                dd.tmax[ax] += dd.tdelta[ax];
            }
            zero = sub_dda_zero(view, &dd);
            te = sub_dda_same_until(view, &dd, zero, T_AT(ke - 1));
            kn = te == INFINITY ? ke : first_step_at(t0, dt, s->dt_inv, k, ke, te);
            if (kn <= k) kn = k + 1;
            if (zero) { /* samples k .. kn - 1 add nothing */
                if (p->preintegrate) preint_close(tfx, &st->r);
                st->nskip++;
                k = kn;
                continue;
            }
            {
                long kz = k;
                done = take_steps(s, view, tfx, p, mode, shading, colors, x0, e, d, t0, dt, &k, kn, &st->r);
                st->nsamp += (size_t)(done ? k - kz + 1 : kn - kz);
            }
        }
    } else {
        long kz = k;
        done = take_steps(s, view, tfx, p, mode, shading, colors, x0, e, d, t0, dt, &k, ke, &st->r);
        st->nsamp += (size_t)(done ? k - kz + 1 : ke - kz);
    }
    st->k = k;
    st->done = done;
#undef T_AT
    return !done && k < nfull;
}

/* Where the ray's last step (shorter than dt, ending at t1) samples: 1 with its position,
 * parameter and length while the ray still has it to take. */
static int ray_last_at(const ray_state *st, double dt, double x[3], double *t, double *h)
{
    double ta;
    if (st->done || st->failed != WVOL_OK || st->nfull >= st->nsteps) return 0;
    ta = st->t0 + (double)st->nfull * dt;
    *h = st->t1 - ta;
    *t = 0.5 * (ta + st->t1);
    for (int a = 0; a < 3; a++) x[a] = st->x0[a] + *t * st->e[a];
    return *h > 0;
}

/* The last step, once; its counters stay in st. */
void wvol__ray_last(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p, double dt,
                    ray_state *st)
{
    double x[3], t, h;
    const wvol__view *view = &s->whole;
    int skip = 0;
    if (!ray_last_at(st, dt, x, &t, &h)) {
        if (p->preintegrate && !st->done && st->failed == WVOL_OK) preint_close(tfx, &st->r); /* the ray's end */
        return;
    }
    st->nsteps = st->nfull; /* taken */
    if (s->B > 0) {
        ray_enter(s, st, x, t);
        skip = ray_skip(s, tc, st, p->skip_tolerance, h, &view);
    }
    if (!skip) {
        double d[3];
        ray_dir(s, st, d);
        st->nsamp++;
        st->done = step(s, view, tfx, p, p->mode, p->shading, p->colors != NULL, 0, x, d, h, &st->r);
    }
    if (p->preintegrate && !st->done && st->failed == WVOL_OK) preint_close(tfx, &st->r); /* the ray's end */
}

/* The ray's pixel. */
void wvol__ray_pixel(const wvol_render_params *p, const ray_state *st, float px[4])
{
    if (p->mode == WVOL_RENDER_MODE_XRAY) {
        px[0] = px[1] = px[2] = (float)st->r.xr;
        px[3] = 1.0f;
    } else {
        for (int a = 0; a < 3; a++) px[a] = (float)st->r.acc[a];
        px[3] = (float)(1.0 - st->r.T);
    }
}

/* The brick holding the ray's next sample (its next full step's, else its last step's),
 * entered (ray_enter); -1 when it has none left. */
RAY_CLONES long wvol__ray_next_brick(const wvol__source *s, ray_state *st, double dt)
{
    double x[3], t, h;
    if (st->done || st->failed != WVOL_OK) return -1;
    if (st->k < st->nfull) {
        t = st->t0 + ((double)st->k + 0.5) * dt;
        for (int a = 0; a < 3; a++) x[a] = st->x0[a] + t * st->e[a];
    } else if (!ray_last_at(st, dt, x, &t, &h)) {
        return -1;
    }
    ray_enter(s, st, x, t);
    return st->bid;
}

/* ray_advance with the common cases' own copies of the loop, the mode, shading and colour
 * tests compiled away (and with them every call in the inner loop: the compositing state
 * stays in registers). */
RAY_CLONES int wvol__ray_advance_any(const wvol__source *s, void *tc, const tf_fast *tfx, const wvol_render_params *p,
                          double dt, ray_state *st)
{
    if (p->mode == WVOL_RENDER_MODE_ABSORPTION && !p->shading && !p->colors)
        return ray_advance(s, tc, tfx, p, WVOL_RENDER_MODE_ABSORPTION, 0, 0, dt, st);
    if (p->mode == WVOL_RENDER_MODE_XRAY && !p->shading) return ray_advance(s, tc, tfx, p, WVOL_RENDER_MODE_XRAY, 0, 0, dt, st);
    return ray_advance(s, tc, tfx, p, p->mode, p->shading, p->colors != NULL, dt, st);
}
