/* SPDX-License-Identifier: MIT
 * Texture mosaics for wavelet-feature segmentation, after the test images of
 * Gross et al. (Fig. 12: "Sine1" gratings of different spectral ranges and
 * orientations, "Sine2" of different spectral ranges, random dots).
 *
 * Regions: a Voronoi partition of `count` seeded sites, taken after a smooth
 * sinusoidal warp of space, so the boundaries are curved. Textures are defined in
 * voxel (index) units so that each one falls into known wavelet levels. */
#include <math.h>
#include <string.h>
#include <strings.h>

#include "synth_internal.h"

enum { MAX_REGIONS = 16 };
enum { TEX_GRATING = 0, TEX_DOTS = 1 };

typedef struct region {
    double site[3];   /* normalised */
    int kind;         /* TEX_GRATING or TEX_DOTS */
    double dir[3];    /* grating: unit direction (index space) */
    double period;    /* grating: voxels per cycle */
    double phase;
    double radius;    /* dots: radius in voxels */
    double cell;      /* dots: one dot at most per cell of this size (voxels) */
    double prob;      /* dots: chance that a cell has a dot */
    uint64_t seed;
} region;

typedef struct tex_ctx {
    int n, dim;
    region r[MAX_REGIONS];
    double warp_amp, warp_w[3][3], warp_phase[3];
} tex_ctx;

static int tex_label(const tex_ctx *c, const double u[3])
{
    double w[3], best = INFINITY;
    int a, b, n, label = 0;
    for (a = 0; a < 3; a++) {
        double t = c->warp_phase[a];
        for (b = 0; b < 3; b++) t += c->warp_w[a][b] * u[b];
        w[a] = u[a] + (a < c->dim ? c->warp_amp * sin(t) : 0.0);
    }
    for (n = 0; n < c->n; n++) {
        double d = 0;
        for (a = 0; a < c->dim; a++) d += (w[a] - c->r[n].site[a]) * (w[a] - c->r[n].site[a]);
        if (d < best) {
            best = d;
            label = n;
        }
    }
    return label;
}

static double dots_value(const region *r, int dim, const double x[3])
{
    long cell[3], o[3];
    double best = 0;
    int a;
    for (a = 0; a < 3; a++) cell[a] = (long)floor(x[a] / r->cell);
    for (o[2] = (dim == 3 ? -1 : 0); o[2] <= (dim == 3 ? 1 : 0); o[2]++)
        for (o[1] = -1; o[1] <= 1; o[1]++)
            for (o[0] = -1; o[0] <= 1; o[0]++) {
                long q[3];
                uint64_t key;
                double d2 = 0, cov;
                for (a = 0; a < 3; a++) q[a] = cell[a] + o[a];
                key = ((uint64_t)q[0] * 73856093u) ^ ((uint64_t)q[1] * 19349663u) ^
                      ((uint64_t)q[2] * 83492791u);
                key = wvol_hash64(key ^ wvol_hash64((uint64_t)q[0] + ((uint64_t)q[1] << 21) +
                                                    ((uint64_t)q[2] << 42)));
                if (synth_hash_unit(r->seed, key, 0) >= r->prob) continue;
                for (a = 0; a < dim; a++) {
                    double c = ((double)q[a] + synth_hash_unit(r->seed, key, (uint64_t)a + 1)) * r->cell;
                    d2 += (x[a] - c) * (x[a] - c);
                }
                cov = synth_clamp(r->radius + 0.5 - sqrt(d2), 0.0, 1.0);
                if (cov > best) best = cov;
            }
    return best;
}

static void tex_row(const void *vctx, const synth_grid *g, size_t j, size_t k, float *row, float *lab)
{
    const tex_ctx *c = vctx;
    double u[3], x[3];
    size_t i;
    u[1] = synth_u(g, 1, j);
    u[2] = c->dim == 3 ? synth_u(g, 2, k) : 0.0;
    x[1] = (double)j;
    x[2] = (double)k;
    for (i = 0; i < g->nx; i++) {
        const region *r;
        int l;
        double v;
        u[0] = synth_u(g, 0, i);
        x[0] = (double)i;
        l = tex_label(c, u);
        r = &c->r[l];
        if (r->kind == TEX_GRATING) {
            double t = r->dir[0] * x[0] + r->dir[1] * x[1] + r->dir[2] * x[2];
            v = 0.5 + 0.5 * sin(6.283185307179586 * t / r->period + r->phase);
        } else {
            v = dots_value(r, c->dim, x);
        }
        row[i] = (float)v;
        if (lab) lab[i] = (float)l;
    }
}

/* n well-spread unit directions: angles over a half-turn in 2D, a Fibonacci
 * half-sphere in 3D (a direction and its opposite make the same grating). */
static void spread_direction(int idx, int n, int dim, double jitter, double d[3])
{
    if (dim == 2) {
        double th = 3.14159265358979323846 * ((double)idx + 0.5 + jitter) / (double)n;
        d[0] = cos(th);
        d[1] = sin(th);
        d[2] = 0;
    } else {
        double zc = 1.0 - ((double)idx + 0.5) / (double)n; /* (0, 1]: upper half-sphere */
        double rad = sqrt(1.0 - zc * zc);
        double ph = 2.399963229728653 * (double)idx + jitter;
        d[0] = rad * cos(ph);
        d[1] = rad * sin(ph);
        d[2] = zc;
    }
}

wvol_status wvol__synth_plan_textures(synth_plan *pl, const wvol_synth_params *p, wvol_error *err)
{
    static const double periods[8] = {4.0, 11.0, 6.0, 17.0, 5.0, 8.0, 13.0, 24.0};
    tex_ctx *c;
    wvol_rng rng;
    const char *variant;
    int n, a, b, mode; /* 0 gratings, 1 frequencies, 2 dots, 3 mixed */
    double rmin, common_dir[3];

    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "synth textures: NULL parameters");
    variant = p->variant && *p->variant ? p->variant : "gratings";
    if (strcasecmp(variant, "gratings") == 0) mode = 0;
    else if (strcasecmp(variant, "frequencies") == 0) mode = 1;
    else if (strcasecmp(variant, "dots") == 0) mode = 2;
    else if (strcasecmp(variant, "mixed") == 0) mode = 3;
    else
        return wvol_error_set(err, WVOL_ERR_ARG,
                              "synth textures: unknown variant '%s' (known: gratings, frequencies, "
                              "dots, mixed)", variant);
    n = p->count == 0 ? 4 : p->count;
    WVOL_RETURN_IF(n < 2 || n > MAX_REGIONS, err, WVOL_ERR_ARG,
                   "synth textures: count %d must be from 2 to %d regions", p->count, MAX_REGIONS);
    WVOL_FORWARD(wvol__synth_geometry(&pl->g, p, NULL, "textures", err));
    WVOL_RETURN_IF(!(c = wvol__synth_plan_ctx(pl, sizeof *c, tex_row)), err, WVOL_ERR_NOMEM,
                   "synth textures: out of memory");
    pl->has_labels = 1;
    c->n = n;
    c->dim = pl->g.nz > 1 ? 3 : 2;
    wvol_rng_seed(&rng, p->seed ^ 0x7E47u);

    /* Sites: rejection sampling with a minimum distance that relaxes if crowded. */
    rmin = 0.9 * pow(pow(1.7, c->dim) / c->n, 1.0 / c->dim);
    for (n = 0; n < c->n; n++) {
        int tries = 0;
        for (;;) {
            int ok = 1, m;
            for (a = 0; a < 3; a++) c->r[n].site[a] = a < c->dim ? -0.85 + 1.7 * wvol_rng_uniform(&rng) : 0;
            for (m = 0; m < n && ok; m++) {
                double d2 = 0;
                for (a = 0; a < c->dim; a++)
                    d2 += (c->r[n].site[a] - c->r[m].site[a]) * (c->r[n].site[a] - c->r[m].site[a]);
                ok = d2 >= rmin * rmin;
            }
            if (ok) break;
            if (++tries % 50 == 0) rmin *= 0.9;
        }
    }
    /* Warp: amplitude x frequency < 1 keeps it one-to-one, so no region vanishes. */
    c->warp_amp = 0.15;
    for (a = 0; a < 3; a++) {
        double th = 6.283185307179586 * wvol_rng_uniform(&rng), f = 3.0 + 2.0 * wvol_rng_uniform(&rng);
        double d[3];
        spread_direction(a, 3, 3, wvol_rng_uniform(&rng), d);
        for (b = 0; b < 3; b++) c->warp_w[a][b] = f * (b < c->dim ? d[b] : 0);
        c->warp_phase[a] = th;
    }
    spread_direction(0, 1, c->dim, 2.0 * wvol_rng_uniform(&rng) - 1.0, common_dir);

    for (n = 0; n < c->n; n++) {
        region *r = &c->r[n];
        int dots = mode == 2 || (mode == 3 && n % 2 == 1);
        int idx = mode == 3 ? n / 2 : n, cnt = mode == 3 ? (c->n + 1) / 2 : c->n;
        r->seed = wvol_hash64(p->seed + 0x51DEull * (uint64_t)(n + 1));
        r->phase = 6.283185307179586 * wvol_rng_uniform(&rng);
        if (dots) {
            int nd = mode == 3 ? c->n / 2 : c->n;
            double t = nd > 1 ? (double)idx / (double)(nd - 1) : 0.0;
            r->kind = TEX_DOTS;
            r->radius = 1.0 + 3.0 * t;
            r->cell = 3.0 * r->radius + 1.5;
            r->prob = 0.55 + 0.1 * wvol_rng_uniform(&rng);
        } else {
            r->kind = TEX_GRATING;
            if (mode == 1) {
                memcpy(r->dir, common_dir, sizeof r->dir);
                r->period = 3.0 * pow(32.0 / 3.0, (double)n / (double)(c->n - 1));
            } else {
                spread_direction(idx, cnt, c->dim, 0.1 * (wvol_rng_uniform(&rng) - 0.5), r->dir);
                r->period = periods[idx % 8] * (1.0 + 0.05 * (double)(idx / 8));
            }
        }
    }
    return WVOL_OK;
}

wvol_status wvol_synth_textures(wvol_volume **out, wvol_volume **labels, const wvol_synth_params *p,
                                wvol_error *err)
{
    return wvol__synth_whole(out, labels, wvol__synth_plan_textures, p, "textures", err);
}
