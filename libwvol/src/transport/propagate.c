/* SPDX-License-Identifier: MIT
 * Oracle-driven propagation of a source coefficient tree to a destination tree (Lewis & Fournier
 * 2002, §7.2.4, Figs. 10-11): wct_transport descends the source tree, pushing its wavelet nodes
 * to finer pure smoothing coefficients; below the stored nodes, tc_propagate descends the
 * destination tree where the oracle cannot decide, integrates T_jk at the finest level, and pulls
 * the products b_j T_jk back into destination wavelet nodes. */
#include "transport_internal.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
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

/* a node without wavelets (a constant root) is a leaf: its support is sent whole */
static int has_wavelets(const wvol__tnode *n)
{
    for (int s = 1; s < 16; s++)
        if (n->c[s][0] != 0 || n->c[s][1] != 0 || n->c[s][2] != 0) return 1;
    return 0;
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
    if (n && !has_wavelets(n)) n = NULL;
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

typedef struct work_item {
    wvol_transport_index js;
    float b[3];
} work_item;

/* the source's pure smoothing coefficients two levels down (fewer where its tree stops): the
 * independent pieces of work that threads share */
static work_item *expand(const wvol_transport_tree *src, size_t *count)
{
    work_item *items = malloc(sizeof *items), *next;
    size_t n = 1;
    if (!items) return NULL;
    items[0].js = (wvol_transport_index){0, {0, 0, 0, 0}};
    memcpy(items[0].b, src->nodes[0].c[0], sizeof items[0].b);
    for (int depth = 0; depth < 2; depth++) {
        size_t m = 0;
        next = malloc(16 * n * sizeof *next);
        if (!next) {
            free(items);
            return NULL;
        }
        for (size_t i = 0; i < n; i++) {
            const wvol__tnode *nd = items[i].js.level < src->levels
                                        ? wvol__tree_find(src, items[i].js.level, items[i].js.m)
                                        : NULL;
            float in[16][3], ch[16][3];
            if (!nd || !has_wavelets(nd)) {
                next[m++] = items[i];
                continue;
            }
            memcpy(in, nd->c, sizeof in);
            memcpy(in[0], items[i].b, sizeof in[0]);
            wvol__haar16(ch, in);
            for (int b = 0; b < 16; b++) {
                next[m].js.level = items[i].js.level + 1;
                for (int a = 0; a < 4; a++) next[m].js.m[a] = 2 * items[i].js.m[a] + (b >> a & 1);
                memcpy(next[m].b, ch[b], sizeof ch[b]);
                m++;
            }
        }
        free(items);
        items = next;
        n = m;
    }
    *count = n;
    return items;
}

wvol_status wvol_transport_run(wvol_transport_tree **out, const wvol_transport_tree *src,
                               const wvol_transport_quad *src_quad, const wvol_transport_quad *dst_quad,
                               const wvol_transport_params *p, wvol_transport_stats *stats, wvol_error *err)
{
    prop_ctx *ctx;
    work_item *items;
    size_t nitems = 0;
    int nt, failed = 0;
    double t0 = wvol__now();
    WVOL_RETURN_IF(!out || !src, err, WVOL_ERR_ARG, "transport: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol_transport_quad_check(src_quad, err));
    WVOL_FORWARD(wvol_transport_quad_check(dst_quad, err));
    WVOL_FORWARD(wvol__transport_params_check(p, err));
    WVOL_FORWARD(wvol__threads_check(p->threads, "transport", err));
    items = expand(src, &nitems);
    WVOL_RETURN_IF(!items, err, WVOL_ERR_NOMEM, "transport: out of memory");
    nt = wvol__threads(p->threads);
    if (nt > (int)nitems) nt = (int)nitems;
    if (nt < 1) nt = 1;
    ctx = calloc((size_t)nt, sizeof *ctx);
    if (!ctx) {
        free(items);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "transport: out of memory");
    }
    for (int t = 0; t < nt; t++) {
        wvol__tgeom_init(&ctx[t].g, src_quad, dst_quad);
        ctx[t].p = p;
        ctx[t].src = src;
        if (wvol_transport_tree_create(&ctx[t].dst, p->levels, NULL) != WVOL_OK) failed = 1;
    }
    /* item i always goes to thread i % nt, and the trees merge in thread order: the same
     * count of threads gives the same bits */
    if (!failed) {
#pragma omp parallel for num_threads(nt) schedule(static, 1)
        for (long i = 0; i < (long)nitems; i++) {
            prop_ctx *c = &ctx[omp_get_thread_num()];
            wct_transport(c, &items[i].js, items[i].b);
        }
    }
    for (int t = 0; t < nt; t++) failed |= ctx[t].failed;
    for (int t = 1; t < nt && !failed; t++) {
        const wvol_transport_tree *o = ctx[t].dst;
        for (size_t i = 0; i < o->count && !failed; i++) {
            const wvol__tnode *sn = &o->nodes[i];
            int m[4] = {sn->m[0], sn->m[1], sn->m[2], sn->m[3]};
            wvol__tnode *dn = wvol__tree_get(ctx[0].dst, sn->level, m);
            if (!dn) {
                failed = 1;
                break;
            }
            for (int s = 0; s < 16; s++)
                for (int k = 0; k < 3; k++) dn->c[s][k] += sn->c[s][k];
        }
        ctx[0].st.evaluated += ctx[t].st.evaluated;
        ctx[0].st.oracle_zero += ctx[t].st.oracle_zero;
        ctx[0].st.oracle_exact += ctx[t].st.oracle_exact;
        ctx[0].st.samples += ctx[t].st.samples;
    }
    for (int t = 1; t < nt; t++) wvol_transport_tree_destroy(ctx[t].dst);
    free(items);
    if (failed) {
        wvol_transport_tree_destroy(ctx[0].dst);
        free(ctx);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "transport: out of memory for the destination tree");
    }
    for (size_t i = 0; i < ctx[0].dst->count; i++)
        for (int s = 0; s < 16; s++)
            for (int k = 0; k < 3; k++)
                if (!isfinite(ctx[0].dst->nodes[i].c[s][k])) {
                    wvol_transport_tree_destroy(ctx[0].dst);
                    free(ctx);
                    return wvol_error_set(err, WVOL_ERR_INTERNAL, "transport: non-finite destination coefficient");
                }
    ctx[0].st.seconds = wvol__now() - t0;
    if (stats) *stats = ctx[0].st;
    *out = ctx[0].dst;
    free(ctx);
    return WVOL_OK;
}
