/* SPDX-License-Identifier: MIT
 * A store opened on a .wvc file (wvol_store_open): the grid, basis tables and low-pass
 * cube of a built store, and no nodes: its detail coefficients stay in the file and are
 * decoded chunk by chunk, within the file's memory budget, by the block view that brick
 * reconstructions read (blocks.c), so the bricked renderer and marching cubes work on it
 * unchanged. Queries that walk the octree refuse it (store.c, query.c). */
#include <stdlib.h>
#include <string.h>

#include "codec/wvc_source.h"
#include "store/store_internal.h"

#define DEFAULT_J 4

wvol_status wvol_store_open(wvol_store **out, const char *path, size_t budget, const wvol_store_params *prm,
                            wvol_error *err)
{
    wvol_wvc_file *f = NULL;
    const wvol_wvc_info *I;
    const wvol_filter *filter;
    wvol__layout ly;
    wvol_store *s;
    wvol_status st;
    size_t n[3], nlow;
    int J = prm && prm->spline_J ? prm->spline_J : DEFAULT_J;
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "wvol_store_open: missing argument");
    *out = NULL;
    WVOL_FORWARD(wvol_wvc_open(&f, path, budget, err));
    I = wvol_wvc_file_info(f);
    if ((st = wvol_filter_get(&filter, I->filter, err)) != WVOL_OK ||
        (st = wvol__layout_init_dims(&ly, filter, I->levels, I->px, I->py, I->pz, err)) != WVOL_OK) {
        wvol_wvc_close(f);
        return st;
    }
    s = calloc(1, sizeof *s);
    if (!s) {
        wvol_wvc_close(f);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "store: out of memory");
    }
    s->file = f;
    n[0] = I->nx, n[1] = I->ny, n[2] = I->nz;
    st = wvol__store_shell(s, &ly, filter, n, I->spacing, I->origin, J, err);
    if (st == WVOL_OK) st = wvol__wvc_file_lowpass(f, s->lowpass, err);
    if (st == WVOL_OK) {
        nlow = s->E[0] * s->E[1] * s->E[2];
        for (size_t i = 0; i < nlow; i++) s->root_of[i] = -1;
        s->nodes = calloc(1, sizeof *s->nodes);
        s->values = malloc(sizeof *s->values);
        s->hash = calloc(16, sizeof *s->hash);
        s->hash_mask = 15;
        if (!s->nodes || !s->values || !s->hash) st = wvol_error_set(err, WVOL_ERR_NOMEM, "store: out of memory");
    }
    if (st != WVOL_OK) {
        wvol_store_destroy(s);
        return st;
    }
    *out = s;
    return WVOL_OK;
}

int wvol_store_is_file(const wvol_store *s) { return s && s->file; }

const wvol_wvc_info *wvol_store_file_info(const wvol_store *s) { return s && s->file ? wvol_wvc_file_info(s->file) : NULL; }

wvol_status wvol_store_file_stats(const wvol_store *s, wvol_wvc_cache_stats *st, wvol_error *err)
{
    WVOL_RETURN_IF(!s || !st, err, WVOL_ERR_ARG, "wvol_store_file_stats: missing argument");
    WVOL_RETURN_IF(!s->file, err, WVOL_ERR_ARG, "store: not opened on a file");
    wvol_wvc_file_stats(s->file, st);
    return wvol__wvc_file_error(s->file, err);
}

wvol_status wvol__store_file_error(const wvol_store *s, wvol_error *err)
{
    return s && s->file ? wvol__wvc_file_error(s->file, err) : WVOL_OK;
}
