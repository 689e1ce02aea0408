/* SPDX-License-Identifier: MIT */
/* Triangle meshes: allocation, area, enclosed volume, bounds and the
 * combinatorial checks (watertight, manifold edges and vertices, orientation,
 * Euler characteristic, components) that the tests rely on. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/status_internal.h"
#include "wvol/iso.h"

wvol_status wvol_mesh_create(wvol_mesh **out, size_t nverts, size_t ntris, int with_normals, wvol_error *err)
{
    wvol_mesh *m;
    size_t vb, tb;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "mesh: output pointer is NULL");
    *out = NULL;
    if (!wvol_size_mul3(nverts, 3, 1, sizeof(float), &vb) || !wvol_size_mul3(ntris, 3, 1, sizeof(uint32_t), &tb))
        return wvol_error_set(err, WVOL_ERR_NOMEM, "mesh of %zu vertices, %zu triangles is too large", nverts,
                              ntris);
    m = calloc(1, sizeof *m);
    if (!m) return wvol_error_set(err, WVOL_ERR_NOMEM, "mesh: out of memory");
    m->nverts = nverts;
    m->ntris = ntris;
    /* a 2.7 M triangle mesh's arrays are 65 MB, filled whole by the caller, and first touches
     * of fresh memory cost more than the marching cubes that fill them: huge pages, and the
     * last meshes' arrays again where meshes are made one after another (core/alloc.h;
     * bench/results/iso_topology.md) */
    m->verts = wvol__reuse_get(vb);
    m->tris = wvol__reuse_get(tb);
    if (with_normals) m->normals = wvol__reuse_get(vb);
    if (!m->verts || !m->tris || (with_normals && !m->normals)) {
        wvol_mesh_destroy(m);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "mesh of %zu vertices, %zu triangles: out of memory",
                              nverts, ntris);
    }
    *out = m;
    return WVOL_OK;
}

void wvol_mesh_destroy(wvol_mesh *m)
{
    if (!m) return;
    /* the brick path's arrays are reservations filled in part: their used bytes are counted */
    wvol__reuse_put_used(m->verts, 3 * m->nverts * sizeof(float));
    wvol__reuse_put_used(m->normals, 3 * m->nverts * sizeof(float));
    wvol__reuse_put_used(m->tris, 3 * m->ntris * sizeof(uint32_t));
    free(m);
}

static void tri_pts(const wvol_mesh *m, size_t t, double p[3][3])
{
    int a, d;
    for (a = 0; a < 3; a++) {
        const float *v = m->verts + 3 * (size_t)m->tris[3 * t + a];
        for (d = 0; d < 3; d++) p[a][d] = v[d];
    }
}

/* Whether a mesh's arrays are there and its triangles name its vertices: the measures read
 * the vertices through the indices, so a mesh filled by the caller is checked first. */
static int mesh_readable(const wvol_mesh *m)
{
    if (!m) return 0;
    if ((m->nverts && !m->verts) || (m->ntris && !m->tris)) return 0;
    for (size_t i = 0; i < 3 * m->ntris; i++)
        if (m->tris[i] >= m->nverts) return 0;
    return 1;
}

/* The sum of term over the triangles in fixed blocks added in order: the same to the last bit
 * for any thread count (the reports print it), the blocks' sums in parallel. */
static double triangle_sum(const wvol_mesh *m, double (*term)(const wvol_mesh *, size_t, const double[3]),
                           const double ref[3])
{
    enum { BLOCKS = 256 };
    const size_t n = m ? m->ntris : 0;
    double part[BLOCKS], sum = 0.0;
#ifdef _OPENMP
#pragma omp parallel for schedule(static)
#endif
    for (int k = 0; k < BLOCKS; k++) {
        double s = 0.0;
        for (size_t t = n / BLOCKS * (size_t)k + (n % BLOCKS) * (size_t)k / BLOCKS,
                    end = n / BLOCKS * (size_t)(k + 1) + (n % BLOCKS) * (size_t)(k + 1) / BLOCKS;
             t < end; t++)
            s += term(m, t, ref);
        part[k] = s;
    }
    for (int k = 0; k < BLOCKS; k++) sum += part[k];
    return sum;
}

static double tri_area(const wvol_mesh *m, size_t t, const double ref[3])
{
    double p[3][3], u[3], v[3], c[3];
    (void)ref;
    tri_pts(m, t, p);
    for (int d = 0; d < 3; d++) {
        u[d] = p[1][d] - p[0][d];
        v[d] = p[2][d] - p[0][d];
    }
    c[0] = u[1] * v[2] - u[2] * v[1];
    c[1] = u[2] * v[0] - u[0] * v[2];
    c[2] = u[0] * v[1] - u[1] * v[0];
    return 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

/* six times the signed volume of the tetrahedron (ref, triangle t) */
static double tri_volume6(const wvol_mesh *m, size_t t, const double ref[3])
{
    double p[3][3];
    tri_pts(m, t, p);
    for (int a = 0; a < 3; a++)
        for (int e = 0; e < 3; e++) p[a][e] -= ref[e];
    return p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
           p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
}

double wvol_mesh_area(const wvol_mesh *m)
{
    if (m && !mesh_readable(m)) return NAN;
    return triangle_sum(m, tri_area, NULL);
}

double wvol_mesh_volume(const wvol_mesh *m)
{
    double ref[3] = {0, 0, 0}, lo[3], hi[3];
    if (m && !mesh_readable(m)) return NAN;
    if (!m || m->ntris == 0) return 0.0;
    /* relative to the bounding-box centre: keeps the sum well conditioned far from the origin */
    wvol_mesh_bounds(m, lo, hi);
    for (int d = 0; d < 3; d++) ref[d] = 0.5 * (lo[d] + hi[d]);
    return triangle_sum(m, tri_volume6, ref) / 6.0;
}

void wvol_mesh_bounds(const wvol_mesh *m, double lo[3], double hi[3])
{
    size_t i;
    int d;
    if (!m || m->nverts == 0) return;
    for (d = 0; d < 3; d++) lo[d] = hi[d] = m->verts[d];
    for (i = 1; i < m->nverts; i++)
        for (d = 0; d < 3; d++) {
            double x = m->verts[3 * i + d];
            if (x < lo[d]) lo[d] = x;
            if (x > hi[d]) hi[d] = x;
        }
}

/* ---- topology -------------------------------------------------------------- */

/* A use of the undirected edge (a, b), a < b, seen from its smaller vertex a: b << 1 | 1
 * when the triangle walks a -> b. */
static int cmp_edge_key(const void *x, const void *y)
{
    const uint64_t p = *(const uint64_t *)x, q = *(const uint64_t *)y;
    return p < q ? -1 : p > q;
}

/* Sorts a bucket's keys: insertion for the few edges a vertex usually has, qsort for a
 * vertex with many (a fan of thousands would make insertion quadratic). */
static void sort_bucket(uint64_t *k, size_t n)
{
    if (n > 32) {
        qsort(k, n, sizeof *k, cmp_edge_key);
        return;
    }
    for (size_t i = 1; i < n; i++) {
        uint64_t v = k[i];
        size_t j = i;
        for (; j > 0 && k[j - 1] > v; j--) k[j] = k[j - 1];
        k[j] = v;
    }
}

/* Whether triangle v repeats a vertex (such triangles are counted, and left out of the checks). */
static inline int degenerate(const uint32_t *v) { return v[0] == v[1] || v[1] == v[2] || v[0] == v[2]; }

/* The corner (0, 1, 2) of triangle v at vertex i, which v has. */
static inline int corner_of(const uint32_t *v, size_t i) { return v[0] == i ? 0 : v[1] == i ? 1 : 2; }

static uint32_t uf_find(uint32_t *par, uint32_t x)
{
    while (par[x] != x) {
        par[x] = par[par[x]];
        x = par[x];
    }
    return x;
}

wvol_status wvol_mesh_topology(const wvol_mesh *m, wvol_mesh_topo *o, wvol_error *err)
{
    size_t nt, nv, t, i, used = 0, kmax = 0;
    uint64_t *key = NULL;
    uint32_t *par = NULL, *fan = NULL, *cnt = NULL;
    size_t *start = NULL; /* 3 nt fan entries may pass 2^32 */
    unsigned char *seen = NULL;
    wvol_status s = WVOL_OK;

    WVOL_RETURN_IF(!m || !o, err, WVOL_ERR_ARG, "mesh topology: NULL argument");
    memset(o, 0, sizeof *o);
    nt = m->ntris;
    nv = m->nverts;
    for (t = 0; t < 3 * nt; t++)
        WVOL_RETURN_IF(m->tris[t] >= nv, err, WVOL_ERR_FORMAT, "mesh: triangle %zu uses vertex %u of %zu",
                       t / 3, m->tris[t], nv);
    /* huge pages: a 2.7 M triangle mesh's fans alone are 33 MB, and first touches in 4 KiB
     * pages cost more than the checks (core/alloc.h; bench/results/iso_topology.md) */
    par = wvol__reuse_get((nv + 1) * sizeof *par);
    start = wvol__reuse_get((nv + 2) * sizeof *start);
    fan = wvol__reuse_get((3 * nt + 1) * sizeof *fan);
    cnt = wvol__reuse_get((nv + 1) * sizeof *cnt);
    seen = wvol__reuse_get(nt + 1);
    if (!par || !start || !fan || !cnt || !seen) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "mesh topology: out of memory");
        goto done;
    }
    memset(start, 0, (nv + 2) * sizeof *start);
    memset(cnt, 0, (nv + 1) * sizeof *cnt);
    memset(seen, 0, nt + 1);
    /* each vertex's triangles (its fan), and the components by union-find over the edges */
    for (i = 0; i < nv; i++) par[i] = (uint32_t)i;
    for (t = 0; t < nt; t++) {
        const uint32_t *v = m->tris + 3 * t;
        if (degenerate(v)) {
            o->degenerate_tris++;
            continue;
        }
        for (int a = 0; a < 3; a++) {
            uint32_t rp = uf_find(par, v[a]), rq = uf_find(par, v[(a + 1) % 3]);
            if (rp != rq) par[rp] = rq;
            cnt[v[a]]++;
        }
    }
    for (i = 0; i < nv; i++) {
        start[i + 1] = start[i] + cnt[i];
        if (cnt[i] > kmax) kmax = cnt[i];
    }
    memset(cnt, 0, nv * sizeof *cnt);
    for (t = 0; t < nt; t++) {
        const uint32_t *v = m->tris + 3 * t;
        if (degenerate(v)) continue;
        for (int a = 0; a < 3; a++) fan[start[v[a]] + cnt[v[a]]++] = (uint32_t)t;
    }
    key = malloc((2 * kmax + 1) * sizeof *key);
    if (!key) {
        s = wvol_error_set(err, WVOL_ERR_NOMEM, "mesh topology: out of memory");
        goto done;
    }
    for (i = 0; i < nv; i++) {
        uint32_t k = cnt[i], reached = 1, cur, prev_other, q;
        const uint32_t *f = fan + start[i];
        size_t nk = 0;
        if (k == 0) {
            o->unused_verts++;
            continue;
        }
        used++;
        /* The edges from i to larger vertices, each use once: a triangle of i's fan walks
         * i -> its next vertex and its previous vertex -> i. Every use of an edge is found in
         * the fan of its smaller end alone; sorted by the other end, an edge is a run: linear in
         * the triangles, with no array of all half-edges. */
        for (q = 0; q < k; q++) {
            const uint32_t *v = m->tris + 3 * f[q];
            const int a = corner_of(v, i);
            const uint32_t next = v[(a + 1) % 3], prev = v[(a + 2) % 3];
            if (next > i) key[nk++] = (uint64_t)next << 1 | 1;
            if (prev > i) key[nk++] = (uint64_t)prev << 1;
        }
        sort_bucket(key, nk);
        for (size_t e = 0; e < nk;) {
            size_t j = e, fwd = 0, bwd = 0;
            while (j < nk && key[j] >> 1 == key[e] >> 1) {
                if (key[j] & 1) fwd++;
                else bwd++;
                j++;
            }
            o->edges++;
            if (j - e == 1)
                o->boundary_edges++;
            else if (j - e > 2)
                o->nonmanifold_edges++;
            else if (fwd != 1 || bwd != 1)
                o->misoriented_edges++;
            e = j;
        }
        /* the fan must be one disc or one half-disc: walk it through shared edges from the
         * first triangle in one direction, then the other, and compare with its count */
        for (int dirn = 0; dirn < 2; dirn++) {
            cur = f[0];
            {
                const uint32_t *v = m->tris + 3 * cur;
                int a = corner_of(v, i);
                prev_other = dirn == 0 ? v[(a + 1) % 3] : v[(a + 2) % 3];
            }
            for (;;) {
                /* next triangle sharing edge (i, prev_other), other than cur */
                uint32_t next = UINT32_MAX;
                for (q = 0; q < k; q++) {
                    const uint32_t *v = m->tris + 3 * f[q];
                    if (f[q] == cur) continue;
                    if (v[0] == prev_other || v[1] == prev_other || v[2] == prev_other) {
                        next = f[q];
                        break;
                    }
                }
                if (next == UINT32_MAX || next == f[0]) break;
                if (seen[next]) break;
                seen[next] = 1;
                reached++;
                {
                    const uint32_t *v = m->tris + 3 * next;
                    int a;
                    for (a = 0; a < 3; a++)
                        if (v[a] != i && v[a] != prev_other) break;
                    prev_other = v[a];
                }
                cur = next;
            }
        }
        for (q = 0; q < k; q++) seen[f[q]] = 0;
        if (reached != k) o->nonmanifold_verts++;
    }
    {
        size_t comps = 0;
        for (i = 0; i < nv; i++)
            if (cnt[i] && uf_find(par, (uint32_t)i) == i) comps++;
        o->components = comps;
    }
    o->euler = (long long)used - (long long)o->edges + (long long)(nt - o->degenerate_tris);
    o->watertight = o->boundary_edges == 0 && o->nonmanifold_edges == 0 && o->misoriented_edges == 0 &&
                    o->nonmanifold_verts == 0;
done:
    free(key);
    wvol__reuse_put(par);
    wvol__reuse_put(start);
    wvol__reuse_put(fan);
    wvol__reuse_put(cnt);
    wvol__reuse_put(seen);
    return s;
}
