/* SPDX-License-Identifier: MIT
 * The wavelet coefficient tree of Lewis & Fournier 2002, §7.2.2: 4D Haar nodes (the 15 wavelet
 * coefficients of one pure smoothing index, RGB grouped as in §7.2.2.2) hashed on (level, m)
 * with collisions resolved by open addressing; each entry keeps its index for the check. */
#include "transport_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/rng.h"

static uint64_t node_key(int level, const int m[4])
{
    return (uint64_t)level | (uint64_t)m[0] << 4 | (uint64_t)m[1] << 19 | (uint64_t)m[2] << 34 | (uint64_t)m[3] << 49;
}

static int node_is(const wvol__tnode *n, int level, const int m[4])
{
    return n->level == level && n->m[0] == m[0] && n->m[1] == m[1] && n->m[2] == m[2] && n->m[3] == m[3];
}

const wvol__tnode *wvol__tree_find(const wvol_transport_tree *t, int level, const int m[4])
{
    size_t mask = t->hash_cap - 1, h = (size_t)wvol_hash64(node_key(level, m)) & mask;
    for (;;) {
        int32_t e = t->hash[h];
        if (!e) return NULL;
        if (node_is(&t->nodes[e - 1], level, m)) return &t->nodes[e - 1];
        h = (h + 1) & mask;
    }
}

static int rehash(wvol_transport_tree *t, size_t cap)
{
    int32_t *h = calloc(cap, sizeof *h);
    if (!h) return 0;
    free(t->hash);
    t->hash = h;
    t->hash_cap = cap;
    for (size_t i = 0; i < t->count; i++) {
        int m[4] = {t->nodes[i].m[0], t->nodes[i].m[1], t->nodes[i].m[2], t->nodes[i].m[3]};
        size_t s = (size_t)wvol_hash64(node_key(t->nodes[i].level, m)) & (cap - 1);
        while (h[s]) s = (s + 1) & (cap - 1);
        h[s] = (int32_t)(i + 1);
    }
    return 1;
}

wvol__tnode *wvol__tree_get(wvol_transport_tree *t, int level, const int m[4])
{
    const wvol__tnode *f = wvol__tree_find(t, level, m);
    wvol__tnode *n;
    if (f) return (wvol__tnode *)f;
    if (t->count >= INT32_MAX - 1) return NULL;
    if (t->count == t->cap) {
        size_t cap = t->cap ? 2 * t->cap : 64;
        wvol__tnode *nn = realloc(t->nodes, cap * sizeof *nn);
        if (!nn) return NULL;
        t->nodes = nn;
        t->cap = cap;
    }
    if (2 * (t->count + 1) > t->hash_cap && !rehash(t, 2 * t->hash_cap)) return NULL;
    n = &t->nodes[t->count];
    memset(n, 0, sizeof *n);
    n->level = (uint8_t)level;
    for (int a = 0; a < 4; a++) n->m[a] = (uint16_t)m[a];
    {
        size_t s = (size_t)wvol_hash64(node_key(level, m)) & (t->hash_cap - 1);
        while (t->hash[s]) s = (s + 1) & (t->hash_cap - 1);
        t->hash[s] = (int32_t)(t->count + 1);
    }
    t->count++;
    if (level > 0) { /* mark the link from the parent (created on demand: the path stays connected) */
        int pm[4] = {m[0] >> 1, m[1] >> 1, m[2] >> 1, m[3] >> 1};
        int bit = (m[0] & 1) | (m[1] & 1) << 1 | (m[2] & 1) << 2 | (m[3] & 1) << 3;
        size_t self = t->count - 1;
        wvol__tnode *p = wvol__tree_get(t, level - 1, pm);
        if (!p) return NULL;
        p->child_mask |= (uint16_t)(1u << bit);
        return &t->nodes[self];
    }
    return n;
}

void wvol__haar16(float out[16][3], const float in[16][3])
{
    /* separable butterflies over the 4 bits: each stage (a + b, a - b) / sqrt2 */
    float tmp[16][3];
    memcpy(tmp, in, sizeof tmp);
    for (int bit = 1; bit < 16; bit <<= 1)
        for (int i = 0; i < 16; i++)
            if (!(i & bit))
                for (int c = 0; c < 3; c++) {
                    float a = tmp[i][c], b = tmp[i | bit][c];
                    tmp[i][c] = (float)((a + b) * M_SQRT1_2);
                    tmp[i | bit][c] = (float)((a - b) * M_SQRT1_2);
                }
    memcpy(out, tmp, sizeof tmp);
}

size_t wvol_transport_cells_count(int levels)
{
    return levels < 0 || levels > WVOL_TRANSPORT_MAX_LEVELS ? 0 : (size_t)1 << (4 * levels);
}

wvol_status wvol_transport_tree_create(wvol_transport_tree **out, int levels, wvol_error *err)
{
    wvol_transport_tree *t;
    int zero[4] = {0, 0, 0, 0};
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "transport tree: NULL output");
    *out = NULL;
    WVOL_RETURN_IF(levels < 1 || levels > WVOL_TRANSPORT_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "transport tree: levels %d outside 1..%d", levels, WVOL_TRANSPORT_MAX_LEVELS);
    t = calloc(1, sizeof *t);
    if (t) {
        t->levels = levels;
        t->hash_cap = 128;
        t->hash = calloc(t->hash_cap, sizeof *t->hash);
    }
    if (!t || !t->hash || !wvol__tree_get(t, 0, zero)) {
        wvol_transport_tree_destroy(t);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "transport tree: out of memory");
    }
    *out = t;
    return WVOL_OK;
}

void wvol_transport_tree_destroy(wvol_transport_tree *t)
{
    if (!t) return;
    free(t->nodes);
    free(t->hash);
    free(t);
}

int wvol_transport_tree_levels(const wvol_transport_tree *t) { return t ? t->levels : 0; }
size_t wvol_transport_tree_nodes(const wvol_transport_tree *t) { return t ? t->count : 0; }

size_t wvol_transport_tree_coefficients(const wvol_transport_tree *t)
{
    size_t n = 0;
    if (!t) return 0;
    for (size_t i = 0; i < t->count; i++)
        for (int s = i == 0 ? 0 : 1; s < 16; s++)
            for (int c = 0; c < 3; c++) n += t->nodes[i].c[s][c] != 0;
    return n;
}

/* cell index of (m, level) in a dense level array, u fastest */
static size_t cell_at(const int m[4], int level)
{
    size_t n = (size_t)1 << level;
    return (size_t)m[0] + n * ((size_t)m[1] + n * ((size_t)m[2] + n * (size_t)m[3]));
}

static void cell_m(size_t idx, int level, int m[4])
{
    size_t n = (size_t)1 << level;
    for (int a = 0; a < 4; a++) {
        m[a] = (int)(idx % n);
        idx /= n;
    }
}

wvol_status wvol_transport_tree_from_cells(wvol_transport_tree **out, const float *cells, int levels,
                                           double threshold, wvol_error *err)
{
    size_t ncell = wvol_transport_cells_count(levels);
    float *cur = NULL, *par = NULL;
    wvol_transport_tree *t = NULL;
    WVOL_RETURN_IF(!out || !cells, err, WVOL_ERR_ARG, "transport tree: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(!(threshold >= 0) || !isfinite(threshold), err, WVOL_ERR_ARG,
                   "transport tree: threshold %g must be finite and >= 0", threshold);
    WVOL_FORWARD(wvol_transport_tree_create(&t, levels, err));
    for (size_t i = 0; i < 3 * ncell; i++)
        if (!isfinite(cells[i])) {
            wvol_transport_tree_destroy(t);
            return wvol_error_set(err, WVOL_ERR_NONFINITE, "transport tree: cell %zu channel %zu is not finite", i / 3,
                                  i % 3);
        }
    cur = malloc(3 * ncell * sizeof *cur);
    par = malloc(3 * (ncell / 16 + 1) * sizeof *par);
    if (!cur || !par) goto nomem;
    /* cell means -> level-L smoothing coefficients: mean * volume / amplitude = mean / 4^L */
    for (size_t i = 0; i < 3 * ncell; i++) cur[i] = (float)(cells[i] / ldexp(1.0, 2 * levels));
    for (int l = levels - 1; l >= 0; l--) {
        size_t np = (size_t)1 << (4 * l);
        for (size_t pi = 0; pi < np; pi++) {
            int m[4], cm[4];
            float in[16][3], co[16][3];
            int any = 0;
            cell_m(pi, l, m);
            for (int c = 0; c < 16; c++) {
                for (int a = 0; a < 4; a++) cm[a] = 2 * m[a] + (c >> a & 1);
                memcpy(in[c], cur + 3 * cell_at(cm, l + 1), sizeof in[c]);
            }
            wvol__haar16(co, in);
            memcpy(par + 3 * pi, co[0], sizeof co[0]);
            for (int s = 1; s < 16; s++)
                for (int ch = 0; ch < 3; ch++) {
                    if (fabsf(co[s][ch]) <= threshold) co[s][ch] = 0;
                    any |= co[s][ch] != 0;
                }
            if (any || l == 0) {
                wvol__tnode *n = wvol__tree_get(t, l, m);
                if (!n) goto nomem;
                memcpy(n->c[1], co[1], 15 * sizeof co[0]);
                if (l == 0) memcpy(n->c[0], co[0], sizeof co[0]);
            }
        }
        memcpy(cur, par, 3 * np * sizeof *cur);
    }
    free(cur);
    free(par);
    *out = t;
    return WVOL_OK;
nomem:
    free(cur);
    free(par);
    wvol_transport_tree_destroy(t);
    return wvol_error_set(err, WVOL_ERR_NOMEM, "transport tree: out of memory for %zu cells", ncell);
}

wvol_status wvol_transport_tree_to_cells(float *cells, size_t cap, const wvol_transport_tree *t, wvol_error *err)
{
    size_t ncell;
    float *cur, *nxt;
    WVOL_RETURN_IF(!cells || !t, err, WVOL_ERR_ARG, "transport tree: NULL argument");
    ncell = wvol_transport_cells_count(t->levels);
    WVOL_RETURN_IF(cap < 3 * ncell, err, WVOL_ERR_ARG, "transport tree: %zu floats given, %zu needed", cap, 3 * ncell);
    cur = malloc(3 * ncell * sizeof *cur);
    nxt = cells;
    if (!cur) return wvol_error_set(err, WVOL_ERR_NOMEM, "transport tree: out of memory");
    memcpy(cur, t->nodes[0].c[0], 3 * sizeof *cur);
    for (int l = 0; l < t->levels; l++) {
        size_t np = (size_t)1 << (4 * l);
        for (size_t pi = 0; pi < np; pi++) {
            int m[4], cm[4];
            float in[16][3], ch[16][3];
            const wvol__tnode *n;
            cell_m(pi, l, m);
            n = wvol__tree_find(t, l, m);
            if (n) memcpy(in, n->c, sizeof in);
            else memset(in, 0, sizeof in);
            memcpy(in[0], cur + 3 * pi, sizeof in[0]);
            wvol__haar16(ch, in);
            for (int c = 0; c < 16; c++) {
                for (int a = 0; a < 4; a++) cm[a] = 2 * m[a] + (c >> a & 1);
                memcpy(nxt + 3 * cell_at(cm, l + 1), ch[c], sizeof ch[c]);
            }
        }
        memcpy(cur, nxt, 3 * ((size_t)1 << (4 * (l + 1))) * sizeof *cur);
    }
    for (size_t i = 0; i < 3 * ncell; i++) cells[i] = (float)(cur[i] * ldexp(1.0, 2 * t->levels));
    free(cur);
    return WVOL_OK;
}

wvol_status wvol_transport_tree_eval(const wvol_transport_tree *t, const double q[4], float rgb[3], wvol_error *err)
{
    float s[3];
    int m[4] = {0, 0, 0, 0}, l;
    WVOL_RETURN_IF(!t || !q || !rgb, err, WVOL_ERR_ARG, "transport eval: NULL argument");
    for (int a = 0; a < 4; a++)
        WVOL_RETURN_IF(!(q[a] >= 0 && q[a] <= 1), err, WVOL_ERR_ARG, "transport eval: q[%d] = %g outside [0, 1]", a, q[a]);
    memcpy(s, t->nodes[0].c[0], sizeof s);
    for (l = 0; l < t->levels; l++) {
        const wvol__tnode *n = wvol__tree_find(t, l, m);
        float in[16][3], ch[16][3];
        int c = 0, n2 = 1 << (l + 1);
        if (!n) break; /* constant below: the smoothing value stands */
        memcpy(in, n->c, sizeof in);
        memcpy(in[0], s, sizeof s);
        wvol__haar16(ch, in);
        for (int a = 0; a < 4; a++) {
            int cm = (int)(q[a] * n2);
            if (cm >= n2) cm = n2 - 1;
            c |= (cm & 1) << a;
            m[a] = cm;
        }
        memcpy(s, ch[c], sizeof s);
    }
    for (int ch = 0; ch < 3; ch++) rgb[ch] = (float)(s[ch] * ldexp(1.0, 2 * l));
    return WVOL_OK;
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

wvol_status wvol_transport_tree_compress(wvol_transport_tree *t, double keep, size_t *kept, wvol_error *err)
{
    size_t n = 0, total, k, left = 0;
    float *mag, thr;
    WVOL_RETURN_IF(!t, err, WVOL_ERR_ARG, "transport compress: NULL tree");
    WVOL_RETURN_IF(!(keep > 0 && keep <= 1), err, WVOL_ERR_ARG, "transport compress: keep %g outside (0, 1]", keep);
    total = t->count * 15 * 3;
    mag = malloc((total + 1) * sizeof *mag);
    if (!mag) return wvol_error_set(err, WVOL_ERR_NOMEM, "transport compress: out of memory");
    for (size_t i = 0; i < t->count; i++)
        for (int s = 1; s < 16; s++)
            for (int c = 0; c < 3; c++)
                if (t->nodes[i].c[s][c] != 0) mag[n++] = fabsf(t->nodes[i].c[s][c]);
    k = (size_t)ceil(keep * (double)n);
    if (k < n && n > 0) {
        qsort(mag, n, sizeof *mag, cmp_float);
        thr = mag[n - k - 1]; /* drop everything up to and including this magnitude */
        for (size_t i = 0; i < t->count; i++)
            for (int s = 1; s < 16; s++)
                for (int c = 0; c < 3; c++)
                    if (fabsf(t->nodes[i].c[s][c]) <= thr) t->nodes[i].c[s][c] = 0;
    }
    for (size_t i = 0; i < t->count; i++)
        for (int s = i == 0 ? 0 : 1; s < 16; s++)
            for (int c = 0; c < 3; c++) left += t->nodes[i].c[s][c] != 0;
    free(mag);
    if (kept) *kept = left;
    return WVOL_OK;
}

wvol_status wvol_transport_tree_power(double power[3], const wvol_transport_tree *t, const wvol_transport_quad *q,
                                      wvol_error *err)
{
    wvol__tframe f;
    WVOL_RETURN_IF(!power || !t, err, WVOL_ERR_ARG, "transport power: NULL argument");
    WVOL_FORWARD(wvol_transport_quad_check(q, err));
    wvol__tframe_init(&f, q);
    for (int c = 0; c < 3; c++) power[c] = 4.0 * f.area * t->nodes[0].c[0][c];
    return WVOL_OK;
}

/* share of the direction square [k0, k0 + h] x [l0, l0 + h] inside the unit disc: the exact
 * vertical extent at 256 midpoints across (the kinks where the rim meets the edges cost O(1e-5)) */
static double disc_share(double k0, double l0, double h)
{
    enum { NX = 256 };
    double a = 2 * k0 - 1, c = 2 * l0 - 1, d = c + 2 * h, s = 0;
    for (int i = 0; i < NX; i++) {
        double x = a + 2 * h * (i + 0.5) / NX, r = 1 - x * x, y;
        if (r <= 0) continue;
        y = sqrt(r);
        s += fmax(0, fmin(d, y) - fmax(c, -y));
    }
    return s / NX / (2 * h);
}

wvol_status wvol_transport_tree_power_emitted(double power[3], const wvol_transport_tree *t,
                                              const wvol_transport_quad *q, wvol_error *err)
{
    wvol__tframe f;
    size_t nc;
    int n;
    float *cells;
    wvol_status s;
    WVOL_RETURN_IF(!power || !t, err, WVOL_ERR_ARG, "transport power: NULL argument");
    WVOL_FORWARD(wvol_transport_quad_check(q, err));
    wvol__tframe_init(&f, q);
    nc = wvol_transport_cells_count(t->levels);
    n = 1 << t->levels;
    cells = malloc(3 * nc * sizeof *cells);
    WVOL_RETURN_IF(!cells, err, WVOL_ERR_NOMEM, "transport power: out of memory");
    s = wvol_transport_tree_to_cells(cells, 3 * nc, t, err);
    power[0] = power[1] = power[2] = 0;
    for (int D = 0; D < n * n && s == WVOL_OK; D++) {
        double share = disc_share((D % n) / (double)n, (D / n) / (double)n, 1.0 / n), acc[3] = {0, 0, 0};
        for (size_t P = 0; P < (size_t)n * n; P++)
            for (int c = 0; c < 3; c++) acc[c] += cells[3 * (P + (size_t)n * n * D) + c];
        for (int c = 0; c < 3; c++) power[c] += 4.0 * f.area * acc[c] * share / (double)nc;
    }
    free(cells);
    return s;
}
