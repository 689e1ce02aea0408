/* SPDX-License-Identifier: MIT */
/* A store's coarser level as a dense volume (the grid of wvol_idwt3_level), and the energy
 * of the detail levels that dropping to it leaves out: what the screen-size level of detail
 * of the renderer and marching cubes' --level read (docs/render.md, "Level of detail").
 * A built store gathers its coefficients of the levels above L into a pyramid of M - L
 * levels on the coarse grid and inverts that; a file-backed store reads the level's whole
 * grid through wvol_wvc_read_region, which decodes only the chunks of the levels above L. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "store/store_internal.h"
#include "wavelet/wavelet_bricks.h"
#include "wvol/wvc.h"

static wvol_status check_level(const wvol_store *s, int level, wvol_error *err)
{
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "store level: store is NULL");
    WVOL_RETURN_IF(level < 0 || level > s->ly.levels, err, WVOL_ERR_ARG,
                   "store level: level %d outside 0..%d (the store's levels)", level, s->ly.levels);
    return WVOL_OK;
}

wvol_status wvol_store_level_energy(const wvol_store *s, int level, double *energy, wvol_error *err)
{
    double e = 0.0;
    WVOL_RETURN_IF(!energy, err, WVOL_ERR_ARG, "store level: energy is NULL");
    *energy = 0.0;
    WVOL_FORWARD(check_level(s, level, err));
    if (s->file) {
        /* the encoder's sum c^2 per band (of the coefficients before quantisation) */
        const wvol_wvc_info *I = wvol_wvc_file_info(s->file);
        for (int i = 0; i < I->nsections; i++)
            if (I->sections[i].band != 0 && I->sections[i].level <= level) e += I->sections[i].energy;
    } else {
        for (size_t n = 0; n < s->nnodes; n++) {
            const wvol__node *nd = s->nodes + n;
            int bands = 0;
            for (unsigned m = nd->band_mask; m; m &= m - 1) bands++;
            if (wvol__key_level(nd->key) > level) continue;
            for (int b = 0; b < bands; b++) {
                double v = s->values[nd->coef_first + (uint32_t)b];
                e += v * v;
            }
        }
    }
    *energy = e;
    return WVOL_OK;
}

/* Values scaled as wvol_idwt3_level scales them (2^{-L/2} per transformed axis), spacing
 * 2^L times, origin on the level-L scaling functions' centres, the first in the first cell. */
static void coarse_geometry(wvol_volume *v, const wvol_store *s, int level)
{
    for (int a = 0; a < 3; a++) {
        v->spacing[a] = s->spacing[a] * (s->ly.tr[a] ? ldexp(1.0, level) : 1.0);
        v->origin[a] = s->origin[a] + (s->ly.tr[a] ? s->spacing[a] * wvol_level_offset(s->filter, level) : 0.0);
    }
}

static wvol_status built_level(wvol_volume **out, const wvol_store *s, int level, wvol_error *err)
{
    size_t n[3] = {s->nx, s->ny, s->nz}, e[3];
    double scale = 1.0;
    wvol_coeffs *c = NULL;
    wvol_volume *v = NULL;
    wvol_store_iter it = {0, 0};
    wvol_store_coeff k;
    wvol_status st;
    for (int a = 0; a < 3; a++) {
        size_t q = (size_t)1 << level;
        e[a] = s->ly.tr[a] ? (n[a] + q - 1) / q : 1;
        if (s->ly.tr[a]) scale *= pow(2.0, -0.5 * level);
    }
    if (level == s->ly.levels) {
        /* the low-pass cube itself, cropped to the cells that touch the grid */
        const size_t E[3] = {s->E[0], s->E[1], s->E[2]};
        WVOL_FORWARD(wvol_volume_create(&v, e[0], e[1], e[2], err));
        wvol__level_crop(v->data, e, s->lowpass, E, E[0], E[0] * E[1], s->filter, level, scale);
    } else {
        /* levels L+1..M become levels 1..M-L of a pyramid on the coarse grid, whose padded
         * size is P / 2^L (P is a multiple of 2^M); inverted whole, then cropped */
        wvol_volume *whole = NULL;
        size_t P[3];
        for (int a = 0; a < 3; a++) P[a] = s->ly.tr[a] ? s->ly.P[a] >> level : 1;
        WVOL_FORWARD(wvol_coeffs_create(&c, s->filter, s->ly.levels - level, P[0], P[1], P[2], err));
        if (c->px != (s->ly.tr[0] ? s->ly.P[0] >> level : 1) || c->py != (s->ly.tr[1] ? s->ly.P[1] >> level : 1) ||
            c->pz != (s->ly.tr[2] ? s->ly.P[2] >> level : 1)) {
            wvol_coeffs_destroy(c);
            return wvol_error_set(err, WVOL_ERR_INTERNAL, "store level: coarse padded size differs");
        }
        while (wvol_store_next(s, &it, &k)) {
            size_t i;
            if (k.level <= level) continue;
            i = wvol_coeffs_index(c, k.level - level, k.band, k.p, k.q, k.r);
            if (i != (size_t)-1) c->data[i] = (float)(scale * k.value);
        }
        st = wvol_idwt3(&whole, c, err);
        wvol_coeffs_destroy(c);
        if (st == WVOL_OK) st = wvol_volume_create(&v, e[0], e[1], e[2], err);
        if (st == WVOL_OK) wvol__level_crop(v->data, e, whole->data, P, P[0], P[0] * P[1], s->filter, level, 1.0);
        wvol_volume_destroy(whole);
        if (st != WVOL_OK) return st;
    }
    coarse_geometry(v, s, level);
    *out = v;
    return WVOL_OK;
}

/* A file-backed store's level: the level's grid read slab by slab along z (each slab's chunks
 * decoded on demand through the file's cache, within its budget), so that the reconstruction's
 * scratch follows a slab, not the whole grid: the peak is the output, the cache and one slab's
 * work. */
#define LEVEL_SLAB_VOXELS ((size_t)1 << 24)

static wvol_status file_level(wvol_volume **out, const wvol_store *s, int level, wvol_error *err)
{
    const wvol_wvc_info *I = wvol_wvc_file_info(s->file);
    size_t hi[3], n[3] = {I->nx, I->ny, I->nz}, plane, depth;
    wvol_volume *v = NULL;
    wvol_status st = WVOL_OK;
    for (int a = 0; a < 3; a++) hi[a] = n[a] > 1 ? (n[a] + ((size_t)1 << level) - 1) >> level : 1;
    plane = hi[0] * hi[1];
    depth = plane < LEVEL_SLAB_VOXELS ? LEVEL_SLAB_VOXELS / plane : 1;
    WVOL_FORWARD(wvol_volume_create(&v, hi[0], hi[1], hi[2], err));
    for (size_t z0 = 0; z0 < hi[2] && st == WVOL_OK; z0 += depth) {
        size_t lo3[3] = {0, 0, z0}, hi3[3] = {hi[0], hi[1], z0 + depth < hi[2] ? z0 + depth : hi[2]};
        wvol_volume *slab = NULL;
        /* the file's cache is meant to change under const use (it has its own lock) */
        st = wvol_wvc_read_region(&slab, (wvol_wvc_file *)s->file, lo3, hi3, level, err);
        if (st == WVOL_OK) st = wvol__store_file_error(s, err);
        if (st == WVOL_OK) {
            memcpy(v->data + plane * z0, slab->data, plane * (hi3[2] - z0) * sizeof *v->data);
            if (z0 == 0) {
                /* the first slab starts at the grid's first sample: its geometry is the grid's */
                memcpy(v->spacing, slab->spacing, sizeof v->spacing);
                memcpy(v->origin, slab->origin, sizeof v->origin);
            }
        }
        wvol_volume_destroy(slab);
    }
    if (st != WVOL_OK) {
        wvol_volume_destroy(v);
        return st;
    }
    *out = v;
    return WVOL_OK;
}

wvol_status wvol_store_level_volume(wvol_volume **out, const wvol_store *s, int level, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "store level: out is NULL");
    *out = NULL;
    WVOL_FORWARD(check_level(s, level, err));
    if (s->file) return file_level(out, s, level, err);
    return built_level(out, s, level, err);
}
