/* SPDX-License-Identifier: MIT */
/* The sparse octree of kept coefficients: building it from a selection, the
 * hash of nodes, lookup, iteration, per-subtree bounds, densify.
 * Based on: Lewis & Fournier, wavelet radiative transfer, section 7.2.2 (the
 * wavelet coefficient tree: hashed nodes keyed by wavelet index, integer
 * indices instead of pointers, child and basis-selector bit masks). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "store/store_internal.h"
#include "store/store_build.h"
#include "codec/wvc_source.h"
#include "core/alloc.h"
#include "core/finite.h"

#define DEFAULT_J 4

void wvol_store_params_default(wvol_store_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->spline_J = DEFAULT_J;
}

static inline uint64_t hash64(uint64_t k)
{
    k ^= k >> 31;
    k *= 0x9E3779B97F4A7C15ull;
    k ^= k >> 29;
    return k;
}

static size_t hash_find(const wvol_store *s, uint64_t key)
{
    size_t i = (size_t)hash64(key) & s->hash_mask;
    for (;;) {
        uint32_t v = s->hash[i];
        if (!v) return (size_t)-1;
        if (s->nodes[v - 1].key == key) return v - 1;
        i = (i + 1) & s->hash_mask;
    }
}

/* Rounds a non-negative bound up to a float that is >= it. */
static float up_float(double d)
{
    float f = (float)d;
    if ((double)f < d) f = nextafterf(f, INFINITY);
    return f;
}

/* Bits set in a node's 8-bit band mask, in a few operations (baseline x86-64 has no
 * population count instruction: __builtin_popcount is a library call there). */
static inline int popc(unsigned x)
{
    x = x - ((x >> 1) & 0x55u);
    x = (x & 0x33u) + ((x >> 2) & 0x33u);
    return (int)((x + (x >> 4)) & 0x0fu);
}

/* ---- per-(level, band) function bounds -------------------------------------------------- */

static void function_bounds(wvol_store *s)
{
    const wvol__layout *ly = &s->ly;
    for (int m = 1; m <= ly->levels; m++) {
        double F[3][2], D[3][2]; /* per axis: [phi/psi] max of the factor and of its x-derivative */
        s->norm[m] = sqrt(ldexp(1.0, -m * wvol__dims(ly)));
        for (int a = 0; a < 3; a++) {
            if (!ly->tr[a]) {
                F[a][0] = F[a][1] = 1.0;
                D[a][0] = D[a][1] = 0.0;
                continue;
            }
            /* the period P / 2^m in local units, in pieces: copies overlap when it is
               shorter than the support */
            size_t T = (ly->P[a] >> m) * (size_t)s->rg.per_unit;
            F[a][0] = wvol__ranges_periodic_max(&s->rg, WVOL__PHI, T);
            F[a][1] = wvol__ranges_periodic_max(&s->rg, WVOL__PSI, T);
            D[a][0] = wvol__ranges_periodic_max(&s->rg, WVOL__DPHI, T) * ldexp(1.0, -m);
            D[a][1] = wvol__ranges_periodic_max(&s->rg, WVOL__DPSI, T) * ldexp(1.0, -m);
        }
        for (int l = 0; l < 8; l++) {
            int b0 = l & 1, b1 = (l >> 1) & 1, b2 = (l >> 2) & 1;
            double nm = s->norm[m];
            s->fvmax[m][l] = nm * F[0][b0] * F[1][b1] * F[2][b2] * (1.0 + 1e-12);
            s->fgmax[m][l][0] = nm * D[0][b0] * F[1][b1] * F[2][b2] * (1.0 + 1e-12);
            s->fgmax[m][l][1] = nm * F[0][b0] * D[1][b1] * F[2][b2] * (1.0 + 1e-12);
            s->fgmax[m][l][2] = nm * F[0][b0] * F[1][b1] * D[2][b2] * (1.0 + 1e-12);
        }
    }
}

void wvol_store_function_bounds(const wvol_store *s, int level, int band, double *vmax, double gmax[3])
{
    int ok = s && level >= 1 && level <= s->ly.levels && band >= 0 && band < 8;
    if (vmax) *vmax = ok ? s->fvmax[level][band] : 0.0;
    if (gmax)
        for (int a = 0; a < 3; a++) gmax[a] = ok ? s->fgmax[level][band][a] : 0.0;
}

/* ---- build ---------------------------------------------------------------------------------- */

typedef struct bitset {
    uint64_t *w;
    size_t n;
} bitset;

static inline void bs_set(bitset *b, size_t i) { b->w[i >> 6] |= (uint64_t)1 << (i & 63); }
static inline int bs_get(const bitset *b, size_t i) { return (int)((b->w[i >> 6] >> (i & 63)) & 1); }

static void store_free_parts(wvol_store *s)
{
    wvol__store_view_free(s);
    if (s->view_lock_ok) pthread_mutex_destroy(&s->view_lock);
    wvol_basis_destroy(s->basis);
    wvol__ranges_free(&s->rg);
    free(s->lowpass), free(s->root_of), free(s->nodes), free(s->values), free(s->hash);
    wvol_wvc_close(s->file);
}

wvol_status wvol__store_shell(wvol_store *s, const wvol__layout *ly, const wvol_filter *filter, const size_t n[3],
                              const double spacing[3], const double origin[3], int J, int majorant,
                              wvol_error *err)
{
    size_t nlow;
    WVOL_RETURN_IF(pthread_mutex_init(&s->view_lock, NULL) != 0, err, WVOL_ERR_NOMEM, "store: no lock for its view");
    s->view_lock_ok = 1;
    s->ly = *ly;
    s->filter = filter;
    s->nx = n[0], s->ny = n[1], s->nz = n[2];
    memcpy(s->spacing, spacing, sizeof s->spacing);
    memcpy(s->origin, origin, sizeof s->origin);
    for (int a = 0; a < 3; a++) s->E[a] = wvol__ext(ly, a, ly->levels);
    for (int m = 0; m <= WVOL_SELECT_MAX_LEVELS; m++) s->pow2[m] = ldexp(1.0, m), s->ipow2[m] = ldexp(1.0, -m);
    WVOL_FORWARD((majorant ? wvol_basis_create_majorant : wvol_basis_create)(&s->basis, filter, J, err));
    WVOL_FORWARD(wvol__ranges_build(&s->rg, s->basis, err));
    function_bounds(s);
    nlow = s->E[0] * s->E[1] * s->E[2];
    s->lowpass = malloc(nlow * sizeof *s->lowpass);
    s->root_of = malloc(nlow * sizeof *s->root_of);
    WVOL_RETURN_IF(!s->lowpass || !s->root_of, err, WVOL_ERR_NOMEM, "store: out of memory");
    return WVOL_OK;
}

void wvol_store_destroy(wvol_store *s)
{
    if (!s) return;
    store_free_parts(s);
    free(s);
}

/* Marks in pres (positions of level m) every position with a kept detail coefficient. */
static void mark_level(const wvol__layout *ly, const uint64_t *sel, int m, bitset *pres)
{
    size_t e0 = wvol__ext(ly, 0, m), e1 = wvol__ext(ly, 1, m), e2 = wvol__ext(ly, 2, m);
    for (int l = 1; l < 8; l++) {
        if (!wvol__band_ok(ly, l)) continue;
        for (size_t r = 0; r < e2; r++)
            for (size_t q = 0; q < e1; q++) {
                size_t start = wvol__index(ly, m, l, 0, q, r), end = start + e0, i = start;
                size_t prow = e0 * (q + e1 * r);
                while (i < end) {
                    size_t wi = i >> 6, lim = (wi + 1) << 6;
                    uint64_t w = sel[wi] >> (i & 63);
                    if (lim > end) {
                        size_t nb = end - i;
                        if (nb < 64) w &= ((uint64_t)1 << nb) - 1;
                    }
                    while (w) {
                        int t = __builtin_ctzll(w);
                        bs_set(pres, prow + (i - start) + (size_t)t);
                        w &= w - 1;
                    }
                    i = lim;
                }
            }
    }
}

/* The value a store keeps for a coefficient: |c| in a majorant store. */
static inline float stored(const wvol_store_params *prm, float c) { return prm && prm->majorant ? fabsf(c) : c; }

wvol_status wvol_store_build(wvol_store **out, const wvol_coeffs *c, const wvol_selection *sel,
                             const wvol_store_params *prm, wvol_error *err)
{
    wvol__layout ly;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_store_build: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__layout_init(&ly, c, err));
    WVOL_FORWARD(wvol_check_finite(c->data, c->px, c->py, c->pz, "store: coefficients", err));
    return wvol__store_build_tested(out, c, sel, prm, err);
}

wvol_status wvol__store_build_tested(wvol_store **out, const wvol_coeffs *c, const wvol_selection *sel,
                                     const wvol_store_params *prm, wvol_error *err)
{
    wvol_store *s;
    wvol_selection *own = NULL;
    const uint64_t *kept;
    bitset pres[WVOL_SELECT_MAX_LEVELS + 2];
    size_t lvl_start[WVOL_SELECT_MAX_LEVELS + 2], total = 0, nlow;
    wvol__layout ly;
    wvol_status st = WVOL_OK;
    int J = prm && prm->spline_J ? prm->spline_J : DEFAULT_J, M;

    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_store_build: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__layout_init(&ly, c, err));
    WVOL_FORWARD(wvol__geometry_check(c->spacing, c->origin, err));
    M = ly.levels;
    for (int a = 0; a < 3; a++)
        WVOL_RETURN_IF(ly.tr[a] && (ly.P[a] >> 1) > WVOL__POS_MAX, err, WVOL_ERR_DIMS,
                       "store: padded size %zu on axis %d exceeds %zu", ly.P[a], a, WVOL__POS_MAX * 2);
    if (sel) {
        WVOL_RETURN_IF(sel->ly.N != ly.N || sel->ly.levels != ly.levels || sel->ly.P[0] != ly.P[0] ||
                           sel->ly.P[1] != ly.P[1] || sel->ly.P[2] != ly.P[2],
                       err, WVOL_ERR_DIMS, "store: the selection does not match the coefficients' layout");
    } else {
        WVOL_FORWARD(wvol__selection_nonzero(&own, c, err));
        sel = own;
    }
    WVOL_RETURN_IF(sel->kept > 0xfffffff0u, err, WVOL_ERR_DIMS, "store: %zu kept coefficients (at most 2^32 - 16)",
                   sel->kept);
    kept = sel->bits;

    s = calloc(1, sizeof *s);
    if (!s) {
        wvol_selection_destroy(own);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "store: out of memory");
    }
    memset(pres, 0, sizeof pres);
    {
        const size_t n[3] = {c->nx, c->ny, c->nz};
        if ((st = wvol__store_shell(s, &ly, c->filter, n, c->spacing, c->origin, J, prm && prm->majorant, err)) !=
            WVOL_OK)
            goto fail;
    }

    /* the dense low-pass cube */
    nlow = s->E[0] * s->E[1] * s->E[2];
    for (size_t r = 0; r < s->E[2]; r++)
        for (size_t q = 0; q < s->E[1]; q++)
            for (size_t p = 0; p < s->E[0]; p++)
                s->lowpass[p + s->E[0] * (q + s->E[1] * r)] = stored(prm, c->data[wvol__index(&ly, M, 0, p, q, r)]);

    /* node presence per level: own kept coefficients, then propagated to ancestors */
    for (int m = 1; m <= M; m++) {
        pres[m].n = wvol__ext(&ly, 0, m) * wvol__ext(&ly, 1, m) * wvol__ext(&ly, 2, m);
        pres[m].w = wvol__calloc_large((pres[m].n + 63) / 64, sizeof(uint64_t));
        if (!pres[m].w) goto nomem;
        mark_level(&ly, kept, m, pres + m);
    }
    for (int m = 1; m < M; m++) {
        size_t e0 = wvol__ext(&ly, 0, m), e1 = wvol__ext(&ly, 1, m);
        size_t f0 = wvol__ext(&ly, 0, m + 1), f1 = wvol__ext(&ly, 1, m + 1);
        for (size_t wi = 0; wi < (pres[m].n + 63) / 64; wi++)
            for (uint64_t w = pres[m].w[wi]; w; w &= w - 1) {
                size_t i = (wi << 6) + (size_t)__builtin_ctzll(w), p = i % e0, q = (i / e0) % e1, r = i / e0 / e1;
                bs_set(pres + m + 1, (p >> 1) + f0 * ((q >> 1) + f1 * (r >> 1)));
            }
    }
    for (int m = 1; m <= M; m++)
        for (size_t wi = 0; wi < (pres[m].n + 63) / 64; wi++) total += (size_t)__builtin_popcountll(pres[m].w[wi]);
    if (total > 0xfffffff0u) {
        st = wvol_error_set(err, WVOL_ERR_DIMS, "store: %zu nodes (at most 2^32 - 16)", total);
        goto fail;
    }
    /* the store's arrays in huge pages (core/alloc.h): they are megabytes, which in 4 KiB pages
     * are faulted in one page at a time as they are filled */
    s->nodes = wvol__calloc_large(total ? total : 1, sizeof *s->nodes);
    s->nvalues = sel->kept - nlow;
    s->values = wvol__malloc_large((s->nvalues ? s->nvalues : 1) * sizeof *s->values);
    if (!s->nodes || !s->values) goto nomem;

    /* nodes breadth first: roots in raster order, then each node's children together */
    for (size_t i = 0; i < nlow; i++) {
        s->root_of[i] = -1;
        if (bs_get(pres + M, i)) {
            size_t p = i % s->E[0], q = (i / s->E[0]) % s->E[1], r = i / s->E[0] / s->E[1];
            s->root_of[i] = (int32_t)s->nnodes;
            s->nodes[s->nnodes++].key = wvol__key(M, p, q, r);
        }
    }
    s->nroots = s->nnodes;
    lvl_start[M] = 0;
    for (int m = M; m >= 2; m--) {
        size_t e0 = wvol__ext(&ly, 0, m - 1), e1 = wvol__ext(&ly, 1, m - 1), end = s->nnodes;
        lvl_start[m - 1] = end;
        for (size_t ni = lvl_start[m]; ni < end; ni++) {
            wvol__node *nd = s->nodes + ni;
            size_t pos[3];
            wvol__key_pos(nd->key, pos);
            nd->child_first = (uint32_t)s->nnodes;
            for (int ci = 0; ci < 8; ci++) {
                size_t cp = 2 * pos[0] + (ci & 1), cq = 2 * pos[1] + ((ci >> 1) & 1), cr = 2 * pos[2] + ((ci >> 2) & 1);
                if (!wvol__band_ok(&ly, ci)) continue; /* no split along an untransformed axis */
                if (!bs_get(pres + m - 1, cp + e0 * (cq + e1 * cr))) continue;
                nd->child_mask |= (uint8_t)(1u << ci);
                s->nodes[s->nnodes++].key = wvol__key(m - 1, cp, cq, cr);
            }
        }
    }
    if (s->nnodes != total) {
        st = wvol_error_set(err, WVOL_ERR_INTERNAL, "store: %zu nodes made, %zu expected", s->nnodes, total);
        goto fail;
    }

    /* coefficients, band order within each node; then bounds from the leaves up */
    {
        size_t nv = 0;
        for (size_t ni = 0; ni < s->nnodes; ni++) {
            wvol__node *nd = s->nodes + ni;
            int m = wvol__key_level(nd->key);
            size_t pos[3];
            wvol__key_pos(nd->key, pos);
            nd->coef_first = (uint32_t)nv;
            for (int l = 1; l < 8; l++) {
                size_t idx;
                if (!wvol__band_ok(&ly, l)) continue;
                idx = wvol__index(&ly, m, l, pos[0], pos[1], pos[2]);
                if (!((kept[idx >> 6] >> (idx & 63)) & 1)) continue;
                if (nv >= s->nvalues) {
                    st = wvol_error_set(err, WVOL_ERR_INTERNAL, "store: more kept coefficients than counted");
                    goto fail;
                }
                nd->band_mask |= (uint8_t)(1u << (l - 1));
                s->values[nv++] = stored(prm, c->data[idx]);
            }
        }
        if (nv != s->nvalues) {
            st = wvol_error_set(err, WVOL_ERR_INTERNAL, "store: %zu coefficients placed, %zu kept", nv, s->nvalues);
            goto fail;
        }
    }

    /* the hash of nodes: open addressing, linear probing, load <= 1/2 */
    {
        size_t slots = 16;
        while (slots < 2 * s->nnodes) slots <<= 1;
        s->hash = wvol__calloc_large(slots, sizeof *s->hash);
        if (!s->hash) goto nomem;
        s->hash_mask = slots - 1;
        for (size_t ni = 0; ni < s->nnodes; ni++) {
            size_t i = (size_t)hash64(s->nodes[ni].key) & s->hash_mask;
            while (s->hash[i]) i = (i + 1) & s->hash_mask;
            s->hash[i] = (uint32_t)(ni + 1);
        }
    }
    for (int m = 1; m <= M; m++) free(pres[m].w);
    wvol_selection_destroy(own);
    *out = s;
    return WVOL_OK;
nomem:
    st = wvol_error_set(err, WVOL_ERR_NOMEM, "store: out of memory");
fail:
    for (int m = 1; m <= M; m++) free(pres[m].w);
    wvol_selection_destroy(own);
    wvol_store_destroy(s);
    return st;
}

/* ---- inspection ---------------------------------------------------------------------------- */

const wvol_basis *wvol_store_basis(const wvol_store *s) { return s ? s->basis : NULL; }
const float *wvol_store_lowpass(const wvol_store *s) { return s ? s->lowpass : NULL; }
size_t wvol_store_node_count(const wvol_store *s) { return s ? s->nnodes : 0; }

void wvol_store_get_info(const wvol_store *s, wvol_store_info *info)
{
    size_t nlow;
    if (!info) return;
    memset(info, 0, sizeof *info);
    if (!s) return;
    nlow = s->E[0] * s->E[1] * s->E[2];
    info->filter = s->filter;
    info->levels = s->ly.levels;
    info->nx = s->nx, info->ny = s->ny, info->nz = s->nz;
    info->px = s->ly.P[0], info->py = s->ly.P[1], info->pz = s->ly.P[2];
    for (int a = 0; a < 3; a++) {
        info->spacing[a] = s->spacing[a], info->origin[a] = s->origin[a];
        info->transformed[a] = s->ly.tr[a];
        info->lowpass[a] = s->E[a];
    }
    info->kept_lowpass = nlow;
    info->kept = nlow + s->nvalues;
    info->nodes = s->nnodes;
    info->roots = s->nroots;
    info->hash_slots = s->hash_mask + 1;
    info->bytes = sizeof *s + nlow * (sizeof *s->lowpass + sizeof *s->root_of) + s->nnodes * sizeof *s->nodes +
                  s->nvalues * sizeof *s->values + info->hash_slots * sizeof *s->hash;
    info->bytes_per_coeff = info->kept ? (double)info->bytes / (double)info->kept : 0.0;
    info->basis_bytes = (size_t)s->basis->pieces * 26 * sizeof(double) +
                        (size_t)s->rg.n * 2 * 2 * WVOL__KINDS * sizeof(double);
}

/* A node's subtree bounds: sum over the subtree of |c| max|w| (vb) and of |c| max|dw/dx_a|
 * (gb), each child's sum rounded up to float before it is added. Computed on request from
 * the subtree (no algorithm of the library needs them, so the nodes do not carry them:
 * 16 bytes less per node, a third of the store). */
static void node_bounds(const wvol_store *s, const wvol__node *nd, float *vbound, float gbound[3])
{
    int m = wvol__key_level(nd->key), j = 0;
    double vb = 0.0, gb[3] = {0.0, 0.0, 0.0};
    for (int l = 1; l < 8; l++) {
        if (!((nd->band_mask >> (l - 1)) & 1)) continue;
        double a = fabs((double)s->values[nd->coef_first + (uint32_t)j++]);
        vb += a * s->fvmax[m][l];
        for (int x = 0; x < 3; x++) gb[x] += a * s->fgmax[m][l][x];
    }
    for (int ci = 0, k = 0; ci < 8; ci++) {
        float cv, cg[3];
        if (!((nd->child_mask >> ci) & 1)) continue;
        node_bounds(s, s->nodes + nd->child_first + k++, &cv, cg); /* depth <= levels */
        vb += cv;
        for (int x = 0; x < 3; x++) gb[x] += cg[x];
    }
    *vbound = up_float(vb);
    for (int x = 0; x < 3; x++) gbound[x] = up_float(gb[x]);
}

void wvol_store_node_get(const wvol_store *s, size_t i, wvol_store_node *out)
{
    float vb, gb[3];
    const wvol__node *nd;
    size_t pos[3];
    int m;
    if (!out) return;
    memset(out, 0, sizeof *out);
    if (!s || i >= s->nnodes) return;
    nd = s->nodes + i;
    m = wvol__key_level(nd->key);
    wvol__key_pos(nd->key, pos);
    out->level = m;
    out->p = (uint32_t)pos[0], out->q = (uint32_t)pos[1], out->r = (uint32_t)pos[2];
    out->band_mask = nd->band_mask;
    out->child_mask = nd->child_mask;
    out->values = s->values + nd->coef_first;
    out->child_first = nd->child_first;
    for (int a = 0; a < 3; a++) {
        if (s->ly.tr[a]) {
            out->lo[a] = ldexp((double)pos[a], m) - s->ly.s;
            out->hi[a] = out->lo[a] + ldexp((double)(s->ly.L - 1), m);
        } else {
            out->lo[a] = -INFINITY, out->hi[a] = INFINITY;
        }
    }
    node_bounds(s, nd, &vb, gb);
    out->vbound = vb;
    for (int a = 0; a < 3; a++) out->gbound[a] = gb[a];
}

int wvol_store_lookup(const wvol_store *s, int level, int band, size_t p, size_t q, size_t r, float *value)
{
    size_t ni;
    const wvol__node *nd;
    if (!s || level < 1 || level > s->ly.levels || band < 0 || band > 7 || !wvol__band_ok(&s->ly, band)) return 0;
    if (p >= wvol__ext(&s->ly, 0, level) || q >= wvol__ext(&s->ly, 1, level) || r >= wvol__ext(&s->ly, 2, level))
        return 0;
    if (band == 0) {
        if (level != s->ly.levels) return 0;
        if (value) *value = s->lowpass[p + s->E[0] * (q + s->E[1] * r)];
        return 1;
    }
    ni = hash_find(s, wvol__key(level, p, q, r));
    if (ni == (size_t)-1) return 0;
    nd = s->nodes + ni;
    if (!((nd->band_mask >> (band - 1)) & 1)) return 0;
    if (value) *value = s->values[nd->coef_first + (uint32_t)popc(nd->band_mask & ((1u << (band - 1)) - 1))];
    return 1;
}

int wvol_store_next(const wvol_store *s, wvol_store_iter *it, wvol_store_coeff *c)
{
    size_t nlow;
    if (!s || !it) return 0;
    nlow = s->E[0] * s->E[1] * s->E[2];
    if (it->node == 0) {
        if (it->k < nlow) {
            size_t i = it->k++;
            if (c) {
                c->value = s->lowpass[i];
                c->level = (uint8_t)s->ly.levels, c->band = 0;
                c->p = (uint32_t)(i % s->E[0]);
                c->q = (uint32_t)((i / s->E[0]) % s->E[1]);
                c->r = (uint32_t)(i / s->E[0] / s->E[1]);
            }
            return 1;
        }
        it->node = 1, it->k = 0;
    }
    while (it->node - 1 < s->nnodes) {
        const wvol__node *nd = s->nodes + (it->node - 1);
        /* an iterator not advanced by this function may hold any k: past the bands, none left */
        unsigned rest = it->k < 8 ? nd->band_mask & ~((1u << it->k) - 1u) : 0u;
        if (rest) {
            int bit = __builtin_ctz(rest);
            if (c) {
                size_t pos[3];
                wvol__key_pos(nd->key, pos);
                c->value = s->values[nd->coef_first + (uint32_t)popc(nd->band_mask & ((1u << bit) - 1u))];
                c->level = (uint8_t)wvol__key_level(nd->key), c->band = (uint8_t)(bit + 1);
                c->p = (uint32_t)pos[0], c->q = (uint32_t)pos[1], c->r = (uint32_t)pos[2];
            }
            it->k = (size_t)bit + 1;
            return 1;
        }
        it->node++, it->k = 0;
    }
    return 0;
}

wvol_status wvol_store_densify(const wvol_store *s, wvol_coeffs **out, wvol_error *err)
{
    wvol_coeffs *c;
    wvol_store_iter it = {0, 0};
    wvol_store_coeff e;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_store_densify: out is NULL");
    *out = NULL;
    if (s && s->file) {
        /* every chunk, decoded whole (what densify means; the budget bounds only the cache) */
        wvol_coeffs *d = NULL;
        WVOL_FORWARD(wvol_wvc_read(&d, wvol__wvc_file_path(s->file), NULL, NULL, err));
        *out = d;
        return WVOL_OK;
    }
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "wvol_store_densify: store is NULL");
    WVOL_FORWARD(wvol_coeffs_create(&c, s->filter, s->ly.levels, s->nx, s->ny, s->nz, err));
    if (c->px != s->ly.P[0] || c->py != s->ly.P[1] || c->pz != s->ly.P[2]) {
        wvol_coeffs_destroy(c);
        return wvol_error_set(err, WVOL_ERR_INTERNAL, "store: padded sizes differ from the transform's");
    }
    memcpy(c->spacing, s->spacing, sizeof c->spacing);
    memcpy(c->origin, s->origin, sizeof c->origin);
    while (wvol_store_next(s, &it, &e)) c->data[wvol__index(&s->ly, e.level, e.band, e.p, e.q, e.r)] = e.value;
    *out = c;
    return WVOL_OK;
}

void wvol_store_world_to_voxel(const wvol_store *s, const double world[3], double voxel[3])
{
    if (!voxel) return;
    for (int a = 0; a < 3; a++) voxel[a] = s && world ? (world[a] - s->origin[a]) / s->spacing[a] : 0.0;
}

void wvol_store_voxel_to_world(const wvol_store *s, const double voxel[3], double world[3])
{
    if (!world) return;
    for (int a = 0; a < 3; a++) world[a] = s && voxel ? s->origin[a] + voxel[a] * s->spacing[a] : 0.0;
}

void wvol_store_dir_to_voxel(const wvol_store *s, const double dworld[3], double dvoxel[3])
{
    if (!dvoxel) return;
    for (int a = 0; a < 3; a++) dvoxel[a] = s && dworld ? dworld[a] / s->spacing[a] : 0.0;
}
