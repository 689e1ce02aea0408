/* SPDX-License-Identifier: MIT
 * Trilinear views of voxels (render_internal.h, wvol__view), and the reference integrator's
 * dense source: a whole volume seen through one view, with a min/max brick grid for
 * empty-space skipping. */
#include "reference_internal.h"

#include <stdlib.h>
#include <string.h>

double wvol__trilinear_slow(const wvol__view *w, const double x[3])
{
    size_t i0[3], i1[3];
    double wt[3];
    int a;
    for (a = 0; a < 3; a++) {
        double xa = x[a], f;
        long lo = w->lo[a], hi = w->hi[a];
        if (hi == lo || !(xa > (double)lo)) { /* also NaN */
            i0[a] = i1[a] = (size_t)(lo - w->off[a]);
            wt[a] = 0;
            continue;
        }
        if (xa >= (double)hi) {
            i0[a] = i1[a] = (size_t)(hi - w->off[a]);
            wt[a] = 0;
            continue;
        }
        f = floor(xa);
        i0[a] = (size_t)((long)f - w->off[a]);
        i1[a] = i0[a] + 1;
        wt[a] = xa - f;
    }
    {
        const float *d = w->data;
        size_t sy = w->sy, sz = w->sz;
        size_t b00 = i0[1] * sy + i0[2] * sz, b10 = i1[1] * sy + i0[2] * sz, b01 = i0[1] * sy + i1[2] * sz,
               b11 = i1[1] * sy + i1[2] * sz;
        double c00 = d[b00 + i0[0]] + wt[0] * (d[b00 + i1[0]] - d[b00 + i0[0]]);
        double c10 = d[b10 + i0[0]] + wt[0] * (d[b10 + i1[0]] - d[b10 + i0[0]]);
        double c01 = d[b01 + i0[0]] + wt[0] * (d[b01 + i1[0]] - d[b01 + i0[0]]);
        double c11 = d[b11 + i0[0]] + wt[0] * (d[b11 + i1[0]] - d[b11 + i0[0]]);
        double c0 = c00 + wt[1] * (c10 - c00), c1 = c01 + wt[1] * (c11 - c01);
        return c0 + wt[2] * (c1 - c0);
    }
}

void wvol__view_finish(wvol__view *w)
{
    for (int a = 0; a < 3; a++) {
        w->flo[a] = (double)w->lo[a];
        w->fhi[a] = (double)w->hi[a];
    }
    /* run_blocked's voxel offsets and coordinates are 32-bit */
    w->blocked_ok = (double)w->sz * (double)(w->hi[2] - w->off[2] + 1) < 2147483647.0 && w->hi[0] < INT32_MAX &&
                    w->hi[1] < INT32_MAX && w->hi[2] < INT32_MAX;
    w->local = 0;
    w->sub_any = 0;
    w->sub_S = 0;
    w->grad = NULL;
}

/* ---- the dense source --------------------------------------------------------------------- */

/* Each brick's contribution rate (wvol__brick_rate), 0 where its samples cannot contribute.
 * Each brick covers the voxel cells [b*B - 1/2, (b+1)*B - 1/2) and its min/max is taken
 * over voxels b*B-1 .. (b+1)*B, every voxel a trilinear sample inside the brick can touch. */
/* noinline: alone, its loops keep their bounds in registers */
static __attribute__((noinline)) wvol_status build_bricks(wvol__source *s, const wvol_tf *tf, wvol_render_mode mode,
                                                          wvol_error *err)
{
    wvol__dense_src *ds = s->ctx;
    const wvol_volume *v = ds->v;
    size_t bi, bj, bk, nb;
    int a, B = s->B;
    for (a = 0; a < 3; a++) s->bn[a] = (s->n[a] + (size_t)B - 1) / (size_t)B;
    nb = s->bn[0] * s->bn[1] * s->bn[2];
    ds->rate = malloc(nb * sizeof *ds->rate);
    WVOL_RETURN_IF(!ds->rate, err, WVOL_ERR_NOMEM, "render: out of memory for %zu bricks", nb);
    for (bk = 0; bk < s->bn[2]; bk++)
        for (bj = 0; bj < s->bn[1]; bj++)
            for (bi = 0; bi < s->bn[0]; bi++) {
                size_t lo[3], hi[3], b[3] = {bi, bj, bk}, i, j, k;
                double mn = INFINITY, mx = -INFINITY;
                for (a = 0; a < 3; a++) {
                    lo[a] = b[a] * (size_t)B;
                    lo[a] = lo[a] > 0 ? lo[a] - 1 : 0;
                    hi[a] = (b[a] + 1) * (size_t)B + 1;
                    if (hi[a] > s->n[a]) hi[a] = s->n[a];
                }
                for (k = lo[2]; k < hi[2]; k++)
                    for (j = lo[1]; j < hi[1]; j++) {
                        const float *row = v->data + v->nx * (j + v->ny * k);
                        for (i = lo[0]; i < hi[0]; i++) {
                            if (row[i] < mn) mn = row[i];
                            if (row[i] > mx) mx = row[i];
                        }
                    }
                ds->rate[bi + s->bn[0] * (bj + s->bn[1] * bk)] = wvol__brick_rate(tf, mode, mn, mx);
            }
    return WVOL_OK;
}

/* The min/max grid of bricks of side s->B (params->reference.brick; 0: none). */
static wvol_status dense_prepare(wvol__source *s, const wvol_tf *tf_world, const wvol_render_params *p,
                                 wvol_error *err)
{
    return s->B > 0 ? build_bricks(s, tf_world, p->mode, err) : WVOL_OK;
}

/* Every brick's view is the whole volume's; its rate is the table's. */
static wvol_status dense_fetch(const wvol__source *s, void *tctx, size_t brick, double allow, const wvol__view **view,
                               double *rate)
{
    const wvol__dense_src *ds = s->ctx;
    (void)tctx, (void)allow;
    *view = &s->whole;
    *rate = ds->rate[brick];
    return WVOL_OK;
}

const wvol__source_ops wvol__dense_ops = {.prepare = dense_prepare, .fetch = dense_fetch};

wvol_status wvol_render_reference(wvol_image *img, const wvol_volume *v, const wvol_camera *cam, const wvol_tf *tf,
                                  const wvol_render_params *params, wvol_render_stats *stats, wvol_error *err)
{
    wvol__source s;
    wvol__dense_src ds = {v, NULL};
    wvol_render_params p;
    wvol_status st;
    int a;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "render: no volume");
    wvol__params(&p, params);
    memset(&s, 0, sizeof s);
    s.ops = &wvol__dense_ops;
    s.ctx = &ds;
    s.B = p.reference.brick > 0 ? p.reference.brick : 0;
    s.n[0] = v->nx;
    s.n[1] = v->ny;
    s.n[2] = v->nz;
    s.whole.data = v->data;
    s.whole.sy = v->nx;
    s.whole.sz = v->nx * v->ny;
    for (a = 0; a < 3; a++) s.whole.hi[a] = (long)s.n[a] - 1;
    wvol__view_finish(&s.whole);
    for (a = 0; a < 3; a++) {
        s.spacing[a] = v->spacing[a];
        s.origin[a] = v->origin[a];
    }
    st = wvol__render_sampled(img, &s, cam, tf, params, stats, err);
    free(ds.rate);
    return st;
}

