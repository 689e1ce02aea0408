/* SPDX-License-Identifier: MIT */
/* Geometry of the Mallat (pyramid) layout as the store sees it: band extents,
 * indices, and the row segments that let the selection passes stream over the
 * coefficient array in index order. */
#include <stdlib.h>
#include <string.h>

#include "store/store_internal.h"

wvol_status wvol__layout_init(wvol__layout *ly, const wvol_coeffs *c, wvol_error *err)
{
    WVOL_RETURN_IF(!c || !c->data || !c->filter, err, WVOL_ERR_ARG, "coefficients are NULL or have no filter");
    return wvol__layout_init_dims(ly, c->filter, c->levels, c->px, c->py, c->pz, err);
}

wvol_status wvol__layout_init_dims(wvol__layout *ly, const wvol_filter *filter, int levels, size_t px, size_t py,
                                   size_t pz, wvol_error *err)
{
    size_t n;
    WVOL_RETURN_IF(!filter, err, WVOL_ERR_ARG, "coefficients have no filter");
    WVOL_RETURN_IF(levels < 1 || levels > WVOL_SELECT_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "coefficients: levels = %d (1..%d)", levels, WVOL_SELECT_MAX_LEVELS);
    WVOL_RETURN_IF(filter->length < 2, err, WVOL_ERR_ARG, "coefficients: filter '%s' has %d taps", filter->name,
                   filter->length);
    memset(ly, 0, sizeof *ly);
    ly->levels = levels;
    ly->L = filter->length;
    ly->s = filter->center;
    ly->P[0] = px, ly->P[1] = py, ly->P[2] = pz;
    for (int a = 0; a < 3; a++) {
        size_t P = ly->P[a];
        ly->tr[a] = P > 1;
        WVOL_RETURN_IF(P == 0 || (P > 1 && (P % ((size_t)1 << levels)) != 0), err, WVOL_ERR_DIMS,
                       "coefficients: padded size %zu on axis %d is not a multiple of 2^%d", P, a, levels);
    }
    WVOL_RETURN_IF(!ly->tr[0] && !ly->tr[1] && !ly->tr[2], err, WVOL_ERR_DIMS,
                   "coefficients: no transformed axis (1 x 1 x 1)");
    WVOL_RETURN_IF(!wvol_size_mul3(ly->P[0], ly->P[1], ly->P[2], sizeof(float), &n), err, WVOL_ERR_DIMS,
                   "coefficients: %zu x %zu x %zu overflows", ly->P[0], ly->P[1], ly->P[2]);
    ly->N = n / sizeof(float);
    return WVOL_OK;
}

wvol_status wvol__segplan_init(wvol__segplan *sp, const wvol__layout *ly, wvol_error *err)
{
    int M = ly->levels;
    memset(sp, 0, sizeof *sp);
    sp->ly = *ly;
    for (int a = 0; a < 3; a++) {
        size_t P = ly->P[a], E = wvol__ext(ly, a, M);
        sp->h[a] = malloc(P);
        if (!sp->h[a]) {
            wvol__segplan_free(sp);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "selection: out of memory");
        }
        memset(sp->h[a], M + 1, P);
        if (!ly->tr[a]) continue;
        for (int m = M; m >= 1; m--) /* high half of level m: [E 2^(M-m), E 2^(M-m+1)) */
            memset(sp->h[a] + (E << (M - m)), m, E << (M - m));
    }
    if (!ly->tr[0]) {
        sp->nxseg = 1;
        sp->xs[0] = 0, sp->xs[1] = 1;
        sp->xh[0] = M + 1;
    } else {
        size_t E = wvol__ext(ly, 0, M);
        sp->nxseg = M + 1;
        sp->xs[0] = 0, sp->xs[1] = E;
        sp->xh[0] = M + 1;
        for (int m = M, s = 1; m >= 1; m--, s++) {
            sp->xs[s + 1] = E << (M - m + 1);
            sp->xh[s] = m;
        }
    }
    return WVOL_OK;
}

void wvol__segplan_free(wvol__segplan *sp)
{
    for (int a = 0; a < 3; a++) free(sp->h[a]), sp->h[a] = NULL;
}

int wvol__segplan_row(const wvol__segplan *sp, size_t j, size_t k, wvol__seg *segs)
{
    const wvol__layout *ly = &sp->ly;
    int M = ly->levels, hy = sp->h[1][j], hz = sp->h[2][k];
    for (int s = 0; s < sp->nxseg; s++) {
        int hx = sp->xh[s], m = hx < hy ? hx : hy;
        wvol__seg *g = segs + s;
        if (hz < m) m = hz;
        g->x0 = sp->xs[s], g->x1 = sp->xs[s + 1];
        if (m > M) {
            g->level = 0, g->band = 0;
            g->p0 = g->x0, g->q = j, g->r = k;
            continue;
        }
        g->level = m;
        g->band = (hx == m) | ((hy == m) << 1) | ((hz == m) << 2);
        g->p0 = g->x0 - ((g->band & 1) ? wvol__ext(ly, 0, m) : 0);
        g->q = j - ((g->band & 2) ? wvol__ext(ly, 1, m) : 0);
        g->r = k - ((g->band & 4) ? wvol__ext(ly, 2, m) : 0);
    }
    return sp->nxseg;
}
