/* SPDX-License-Identifier: MIT
 * Oracle-driven propagation of a source coefficient tree to a destination tree (Lewis & Fournier
 * 2002, §7.2.4, Figs. 10-11): wct_transport descends the source tree, pushing its wavelet nodes
 * to finer pure smoothing coefficients; below the stored nodes, tc_propagate descends the
 * destination tree where the oracle cannot decide, integrates T_jk at the finest level, and pulls
 * the products b_j T_jk back into destination wavelet nodes. */
#include "transport_internal.h"

#include <math.h>
#include <string.h>

#include "core/clock.h"

typedef struct prop_ctx {
    wvol__tgeom g;
    const wvol_transport_params *p;
    const wvol_transport_tree *src;
    wvol_transport_tree *dst;
    wvol_transport_stats st;
    int failed;
} prop_ctx;

static double tc_propagate(prop_ctx *c, const wvol_transport_index *js, const float bs[3],
                           const wvol_transport_index *kd)
{
    double tc[16], sum = 0;
    float wn[16][3], co[16][3];
    wvol__tnode *node;
    if (c->p->use_oracle) {
        wvol__oracle o = wvol__tg_oracle(&c->g, js, kd);
        if (o == WVOL__ORACLE_ZERO) {
            c->st.oracle_zero++;
            return 0;
        }
        if (o == WVOL__ORACLE_FULL) { /* constant over kd's hypercube: no wavelet below it */
            c->st.oracle_exact++;
            return ldexp(1.0, 2 * (js->level - kd->level));
        }
    }
    if (kd->level == c->p->levels) {
        c->st.evaluated++;
        return wvol__tc_eval(&c->g, js, kd, c->p, &c->st.samples);
    }
    for (int ch = 0; ch < 16; ch++) {
        wvol_transport_index kc = {kd->level + 1, {0, 0, 0, 0}};
        for (int a = 0; a < 4; a++) kc.m[a] = 2 * kd->m[a] + (ch >> a & 1);
        tc[ch] = tc_propagate(c, js, bs, &kc);
        sum += tc[ch];
    }
    if (sum == 0) return 0;
    for (int ch = 0; ch < 16; ch++)
        for (int k = 0; k < 3; k++) wn[ch][k] = (float)(bs[k] * tc[ch]);
    wvol__haar16(co, wn);
    node = wvol__tree_get(c->dst, kd->level, kd->m);
    if (!node) {
        c->failed = 1;
        return 0;
    }
    for (int s = 1; s < 16; s++) /* the smoothing part goes up through the return value */
        for (int k = 0; k < 3; k++) node->c[s][k] += co[s][k];
    return sum * 0.25; /* the pull of tc: T at kd's level */
}

static void wct_transport(prop_ctx *c, const wvol_transport_index *js, const float bs0[3])
{
    const wvol_transport_index top = {0, {0, 0, 0, 0}};
    const wvol__tnode *n;
    if (bs0[0] == 0 && bs0[1] == 0 && bs0[2] == 0 && js->level > 0) {
        /* nothing to send unless wavelets below add some */
        n = wvol__tree_find(c->src, js->level, js->m);
        if (!n) return;
    }
    if (c->failed) return;
    if (c->p->use_oracle && wvol__tg_oracle(&c->g, js, &top) == WVOL__ORACLE_ZERO) {
        c->st.oracle_zero++;
        return;
    }
    n = js->level < c->src->levels ? wvol__tree_find(c->src, js->level, js->m) : NULL;
    if (n) { /* a node without wavelets (a constant root) is a leaf: its support goes whole */
        int any = 0;
        for (int s = 1; s < 16; s++) any |= n->c[s][0] != 0 || n->c[s][1] != 0 || n->c[s][2] != 0;
        if (!any) n = NULL;
    }
    if (n) {
        float in[16][3], ch[16][3];
        memcpy(in, n->c, sizeof in);
        memcpy(in[0], bs0, sizeof in[0]);
        wvol__haar16(ch, in);
        for (int b = 0; b < 16; b++) {
            wvol_transport_index jc = {js->level + 1, {0, 0, 0, 0}};
            for (int a = 0; a < 4; a++) jc.m[a] = 2 * js->m[a] + (b >> a & 1);
            wct_transport(c, &jc, ch[b]);
        }
    } else {
        double T = tc_propagate(c, js, bs0, &top);
        wvol__tnode *root = &c->dst->nodes[0];
        for (int k = 0; k < 3; k++) root->c[0][k] += (float)(bs0[k] * T);
    }
}

wvol_status wvol_transport_run(wvol_transport_tree **out, const wvol_transport_tree *src,
                               const wvol_transport_quad *src_quad, const wvol_transport_quad *dst_quad,
                               const wvol_transport_params *p, wvol_transport_stats *stats, wvol_error *err)
{
    prop_ctx c;
    const wvol_transport_index root = {0, {0, 0, 0, 0}};
    double t0 = wvol__now();
    WVOL_RETURN_IF(!out || !src, err, WVOL_ERR_ARG, "transport: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol_transport_quad_check(src_quad, err));
    WVOL_FORWARD(wvol_transport_quad_check(dst_quad, err));
    WVOL_FORWARD(wvol__transport_params_check(p, err));
    memset(&c, 0, sizeof c);
    wvol__tgeom_init(&c.g, src_quad, dst_quad);
    c.p = p;
    c.src = src;
    WVOL_FORWARD(wvol_transport_tree_create(&c.dst, p->levels, err));
    wct_transport(&c, &root, src->nodes[0].c[0]);
    if (c.failed) {
        wvol_transport_tree_destroy(c.dst);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "transport: out of memory for the destination tree");
    }
    for (size_t i = 0; i < c.dst->count; i++)
        for (int s = 0; s < 16; s++)
            for (int k = 0; k < 3; k++)
                if (!isfinite(c.dst->nodes[i].c[s][k])) {
                    wvol_transport_tree_destroy(c.dst);
                    return wvol_error_set(err, WVOL_ERR_INTERNAL, "transport: non-finite destination coefficient");
                }
    c.st.seconds = wvol__now() - t0;
    if (stats) *stats = c.st;
    *out = c.dst;
    return WVOL_OK;
}
