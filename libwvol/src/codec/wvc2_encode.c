/* SPDX-License-Identifier: MIT
 * wvol_wvc_encode's version-2 path: a dense pyramid handed to the slab writer level by
 * level, coarsest first, so that in-memory and streamed compression share one chunk
 * coder and write the same bytes for the same coefficients, step and dead zones. */
#include <string.h>

#include "wvc2_internal.h"
#include "wvc2_writer.h"

wvol_status wvol__wvc2_encode_dense(void **out, size_t *out_size, const wvol_coeffs *c, const wvol_wvc_params *p,
                                    double step, const double *zero_edge, wvol_wvc_report *rep, wvol_error *err)
{
    wvc2_header h;
    wvc2_writer *w = NULL;
    wvc_layout L;
    size_t n = strlen(c->filter->name);
    wvol__wvc2_header_default(&h);
    memcpy(h.filter, c->filter->name, n < sizeof h.filter - 1 ? n : sizeof h.filter - 1);
    h.levels = c->levels;
    h.nx = c->nx, h.ny = c->ny, h.nz = c->nz;
    h.px = c->px, h.py = c->py, h.pz = c->pz;
    memcpy(h.spacing, c->spacing, sizeof h.spacing);
    memcpy(h.origin, c->origin, sizeof h.origin);
    h.value_min = p->value_min;
    h.value_max = p->value_max;
    h.step = step;
    h.rounding = p->rounding;
    h.zero_edge = zero_edge;
    h.dropped_energy = p->dropped_energy;
    h.tile = p->tile;
    h.tile_z = p->tile_z;
    h.coder = p->coder;
    h.zstd_level = p->zstd_level;
    WVOL_FORWARD(wvol__wvc2_writer_open_mem(&w, &h, err));
    wvol__wvc_layout(&L, c->px, c->py, c->pz, c->levels);
    for (int m = c->levels; m >= 1; m--) {
        wvc2_planes pl;
        size_t ez = c->pz > 1 ? c->pz >> m : 1;
        wvol_status st;
        memset(&pl, 0, sizeof pl);
        for (int s = 0; s < L.nsec; s++) {
            const wvc_band *b = &L.sec[s];
            if (b->level != m || !b->count) continue;
            pl.band[b->band] = c->data + wvc_index(L.p, b, 0, 0, 0);
            pl.sy[b->band] = c->px;
            pl.sz[b->band] = c->px * c->py;
        }
        st = wvol__wvc2_writer_put(w, m, 0, ez, &pl, err);
        if (st != WVOL_OK) {
            wvol__wvc2_writer_abort(w);
            return st;
        }
    }
    return wvol__wvc2_writer_close(w, out, out_size, rep, err);
}
