/* SPDX-License-Identifier: MIT
 * A store opened on a .wvc file (wvol_store_open, libwvol/src/store/store_file.c) gives the
 * same bricked render and the same marching-cubes mesh as a store built in memory from the
 * file's decoded coefficients, within a small memory budget that the chunk cache keeps;
 * octree queries refuse it; a budget below one chunk chain is refused. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/iso.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wvc.h"
#include "store/store_blocks.h"

static const char *PATH = "test_wvc_store.wvc";

/* Writes the phantom's .wvc (db2, 3 levels, 50 dB, small chunks: many of them) and builds
 * the in-memory store of the same decoded coefficients. */
static wvol_store *file_and_memory_store(size_t n, double *vmin, double *vmax)
{
    wvol_volume *v = fixture_volume(n, n - 6, n + 4, fixture_shell_blob, NULL);
    wvol_coeffs *c = NULL, *d = NULL;
    wvol_store *ms = NULL;
    wvol_wvc_params p;
    wvol_error err;
    void *buf = NULL;
    size_t nb = 0;
    if (!v) return NULL;
    wvol_volume_range(v, vmin, vmax, NULL);
    CHECK(wvol_dwt3(&c, v, fixture_filter("db2"), 3, &err) == WVOL_OK, "dwt: %s", err.message);
    wvol_wvc_params_default(&p);
    p.value_min = *vmin, p.value_max = *vmax;
    p.target_sse = wvol_wvc_sse_for_psnr(50, (double)wvol_volume_count(v), *vmin, *vmax);
    p.tile = 8, p.tile_z = 8;
    CHECK(c && wvol_wvc_encode(&buf, &nb, c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
    CHECK(buf && wvol_wvc_save(PATH, buf, nb, &err) == WVOL_OK, "save: %s", err.message);
    CHECK(buf && wvol_wvc_decode(&d, buf, nb, NULL, NULL, &err) == WVOL_OK, "decode: %s", err.message);
    CHECK(d && wvol_store_build(&ms, d, NULL, NULL, &err) == WVOL_OK, "store: %s", err.message);
    free(buf);
    wvol_coeffs_destroy(c);
    wvol_coeffs_destroy(d);
    wvol_volume_destroy(v);
    return ms;
}

static void file_store_meshes_and_renders_like_the_memory_store(void)
{
    double vmin, vmax;
    const size_t n = 56;
    wvol_store *ms = file_and_memory_store(n, &vmin, &vmax), *fs = NULL;
    wvol_error err;
    wvol_wvc_cache_stats cs;
    /* a chunk here is at most 8 bands x 8^3 int32 = 16 KiB: the budget holds 40 of them, a
     * small part of the file's ~200 decoded chunks */
    const size_t budget = 40 * 16500;
    if (!ms) return;
    CHECK(wvol_store_open(&fs, PATH, 1000, NULL, &err) == WVOL_ERR_NOMEM && strstr(err.message, "budget"),
          "a budget below one chunk chain is refused: %s", err.message);
    CHECK(wvol_store_open(&fs, PATH, budget, NULL, &err) == WVOL_OK, "open: %s", err.message);
    if (!fs) {
        wvol_store_destroy(ms);
        return;
    }
    CHECK(wvol_store_is_file(fs) && !wvol_store_is_file(ms), "file stores are told apart");
    {
        /* octree queries refuse a file store instead of answering from the low-pass alone */
        wvol_store_hits h = {0};
        const double lo[3] = {0, 0, 0}, hi[3] = {4, 4, 4};
        CHECK(wvol_store_query_box(fs, lo, hi, &h, &err) == WVOL_ERR_UNSUPPORTED, "query_box refused");
        wvol_store_hits_free(&h);
    }
    {
        /* marching cubes brick by brick: the same mesh from both stores (same coefficients, the
         * same bricks reconstructed from them: the file's looser chunk bounds may only make it
         * reconstruct more bricks, which hold no surface) */
        wvol_mesh *a = NULL, *b = NULL;
        wvol_iso_params ip;
        wvol_iso_stats sa, sb;
        double iso = 0.5 * (vmin + vmax), maxd = 0;
        wvol_iso_params_default(&ip);
        ip.brick = 16;
        CHECK(wvol_iso_extract_store(&a, ms, iso, &ip, &sa, &err) == WVOL_OK, "mc memory: %s", err.message);
        CHECK(wvol_iso_extract_store(&b, fs, iso, &ip, &sb, &err) == WVOL_OK, "mc file: %s", err.message);
        if (a && b) {
            CHECK(a->ntris == b->ntris && a->nverts == b->nverts && a->ntris > 100,
                  "meshes: %zu / %zu triangles, %zu / %zu vertices", a->ntris, b->ntris, a->nverts, b->nverts);
            /* vertices: the same brick reconstructions up to float rounding of the sums */
            if (a->nverts == b->nverts)
                for (size_t i = 0; i < 3 * a->nverts; i++)
                    if (fabs((double)a->verts[i] - (double)b->verts[i]) > maxd)
                        maxd = fabs((double)a->verts[i] - (double)b->verts[i]);
            CHECK(maxd < 1e-4, "vertices differ by %g voxels", maxd);
        }
        {
            /* bricks of 8 (some of them away from the shell): the same mesh from the three
             * stores. With the small budget (fs) the bricks are decided by the index's per-chunk
             * maxima, which skip fewer than the memory store's; with a budget that holds the whole
             * pyramid (big) the bricks the index leaves cost more to rebuild one by one than the
             * whole inverse transform, which the file is then decoded for. The decoded chunks'
             * bounds (the route of a budget that holds every chunk and not the pyramid) are the
             * memory store's, box for box (below). */
            wvol_store *big = NULL;
            wvol_mesh *mm = NULL, *mf = NULL, *mb = NULL;
            wvol_iso_stats s8m, s8f, s8b;
            wvol_iso_params ip8 = ip;
            ip8.brick = 8;
            CHECK(wvol_store_open(&big, PATH, 0, NULL, &err) == WVOL_OK, "open: %s", err.message);
            CHECK(wvol_iso_extract_store(&mm, ms, iso, &ip8, &s8m, &err) == WVOL_OK, "mc memory: %s", err.message);
            CHECK(wvol_iso_extract_store(&mf, fs, iso, &ip8, &s8f, &err) == WVOL_OK, "mc file: %s", err.message);
            CHECK(big && wvol_iso_extract_store(&mb, big, iso, &ip8, &s8b, &err) == WVOL_OK, "mc file: %s",
                  err.message);
            CHECK(mm && mb && mf && mb->ntris == mm->ntris && mb->nverts == mm->nverts && mf->ntris == mm->ntris,
                  "bricks of 8: the same mesh from the three stores");
            CHECK(s8b.whole_inverse && !s8f.whole_inverse && s8b.bricks_skipped == s8f.bricks_skipped &&
                      s8f.bricks_skipped < s8m.bricks_skipped,
                  "bricks skipped: %zu with the whole inverse (%d), %zu from the memory store's bounds, %zu from the "
                  "index's (of %zu)",
                  s8b.bricks_skipped, s8b.whole_inverse, s8m.bricks_skipped, s8f.bricks_skipped, s8m.bricks_total);
            {
                /* the tables' granularity: per chunk (tile 8) for the index's maxima, which hold one
                 * value per chunk (at 2048^3 the small blocks would repeat each over a gigabyte),
                 * the small default blocks for the decoded ones; the memory taken follows */
                wvol__store_blocks *vb = NULL, *vf = NULL;
                wvol__brick_bounds *bbb = NULL, *bbf = NULL;
                int exact_b = 0, exact_f = 1;
                CHECK(wvol__store_blocks_create_exact(&vb, &bbb, big, 1, &exact_b, &err) == WVOL_OK &&
                          wvol__store_blocks_create_exact(&vf, &bbf, fs, 1, &exact_f, &err) == WVOL_OK,
                      "views: %s", err.message);
                {
                    /* the decoded chunks' bounds of every brick of 8 are the memory store's */
                    wvol__store_blocks *vm = NULL;
                    wvol__brick_bounds *bbm = NULL;
                    long *s0[3], *s1[3], buf[6][8];
                    size_t nb[3], total = 1;
                    const size_t dims[3] = {n, n - 6, n + 4};
                    double rm[2 * 8 * 8 * 8], rb[2 * 8 * 8 * 8];
                    for (int ax = 0; ax < 3; ax++) {
                        nb[ax] = (dims[ax] - 1 + 7) / 8;
                        total *= nb[ax];
                        s0[ax] = buf[2 * ax], s1[ax] = buf[2 * ax + 1];
                        for (size_t i = 0; i < nb[ax]; i++) {
                            s0[ax][i] = (long)(8 * i);
                            s1[ax][i] = (long)(8 * i + 8 < dims[ax] - 1 ? 8 * i + 8 : dims[ax] - 1);
                        }
                    }
                    CHECK(total <= 8 * 8 * 8 && wvol__store_blocks_create(&vm, &bbm, ms, 1, &err) == WVOL_OK && bbm && bbb &&
                              wvol__bounds_grid(bbm, (const long *const *)s0, (const long *const *)s1, nb, rm) &&
                              wvol__bounds_grid(bbb, (const long *const *)s0, (const long *const *)s1, nb, rb) &&
                              memcmp(rm, rb, 2 * total * sizeof *rm) == 0,
                          "the decoded chunks' brick bounds are the memory store's (%zu bricks)", total);
                    wvol__store_blocks_destroy(vm);
                }
                CHECK(exact_b && !exact_f && wvol__bounds_block(bbb, 1) == 4 && wvol__bounds_block(bbf, 1) == 8 &&
                          wvol__bounds_block(bbf, 2) == 8 && wvol__bounds_bytes(bbf) < wvol__bounds_bytes(bbb),
                      "bound blocks: decoded %d (edge %zu, %zu bytes), index %d (edges %zu %zu, %zu bytes)", exact_b,
                      wvol__bounds_block(bbb, 1), wvol__bounds_bytes(bbb), exact_f, wvol__bounds_block(bbf, 1),
                      wvol__bounds_block(bbf, 2), wvol__bounds_bytes(bbf));
                wvol__bounds_free(bbb);
                wvol__bounds_free(bbf);
                wvol__store_blocks_destroy(vb);
                wvol__store_blocks_destroy(vf);
            }
            wvol_mesh_destroy(mm);
            wvol_mesh_destroy(mf);
            wvol_mesh_destroy(mb);
            wvol_store_destroy(big);
        }
        wvol_mesh_destroy(a);
        wvol_mesh_destroy(b);
        CHECK(wvol_store_file_stats(fs, &cs, &err) == WVOL_OK, "no decoding error: %s", err.message);
        CHECK(cs.peak <= budget && cs.decoded > 0, "mc: cache peak %zu within %zu, %llu chunks decoded", cs.peak,
              budget, (unsigned long long)cs.decoded);
    }
    {
        /* a bricked render: the same image */
        wvol_geometry g;
        wvol_camera cam;
        wvol_tf tf;
        wvol_render_params rp;
        wvol_image *ia = NULL, *ib = NULL;
        wvol_render_source sa = wvol_render_source_store(ms), sb = wvol_render_source_store(fs);
        wvol_coeffs *d = NULL;
        char tfs[160];
        double e;
        CHECK(wvol_store_densify(fs, &d, &err) == WVOL_OK, "densify reads the file: %s", err.message);
        if (d) wvol_geometry_of_coeffs(&g, d);
        wvol_coeffs_destroy(d);
        snprintf(tfs, sizeof tfs, "0 0.2 0.3 0.9 0\n%g 0.2 0.3 0.9 0\n%g 1 0.8 0.5 0.5\n", vmin + 0.2 * (vmax - vmin),
                 vmax);
        CHECK(wvol_camera_parse(&cam, "persp dir=1,0.7,0.4", &g, 40, 32, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_tf_parse(&tf, tfs, "tf", &err) == WVOL_OK, "%s", err.message);
        wvol_render_params_default(&rp);
        rp.method = WVOL_RENDER_METHOD_BRICKS;
        rp.mode = WVOL_RENDER_MODE_ABSORPTION;
        rp.step = 0.5;
        rp.bricks.brick = 16;
        CHECK(wvol_image_create(&ia, 40, 32, &err) == WVOL_OK && wvol_image_create(&ib, 40, 32, &err) == WVOL_OK,
              "images");
        CHECK(wvol_render(ia, &sa, &cam, &tf, &rp, NULL, &err) == WVOL_OK, "render memory: %s", err.message);
        CHECK(wvol_render(ib, &sb, &cam, &tf, &rp, NULL, &err) == WVOL_OK, "render file: %s", err.message);
        /* the same samples of bricks equal to float rounding (see test_render_bricks.c) */
        e = wvol_image_rmse(ib, ia, -1, 1);
        CHECK(e < 2e-5, "bricked render from the file against the memory store: rel. RMSE %.3g", e);
        CHECK(wvol_store_file_stats(fs, &cs, &err) == WVOL_OK, "no decoding error: %s", err.message);
        CHECK(cs.peak <= budget, "render: cache peak %zu within %zu", cs.peak, budget);
        wvol_image_destroy(ia);
        wvol_image_destroy(ib);
    }
    wvol_store_destroy(fs);
    wvol_store_destroy(ms);
    remove(PATH);
}

/* A file store whose bricks to mesh would cost more to rebuild one by one than the whole
 * inverse transform reads them from the whole reconstruction when its budget has room for the
 * pyramid and the file (stats->whole_inverse; the file decoded whole, not through its chunk
 * cache; with no brick skipped, the mesh of the file decoded whole, bit for bit), and rebuilds
 * them brick by brick when it has not (the memory store's mesh up to the float rounding of the
 * reconstructions: the same triangles, vertices within 1e-4 voxels, as above); the budget is
 * kept. */
static void file_store_meshes_from_the_whole_inverse_when_it_is_cheaper(void)
{
    double vmin, vmax;
    const size_t n = 56;
    wvol_store *ms = file_and_memory_store(n, &vmin, &vmax), *whole = NULL, *tight = NULL;
    wvol_mesh *mm = NULL, *mw = NULL, *mt = NULL;
    wvol_iso_params ip;
    wvol_iso_stats sm, sw, st;
    wvol_wvc_cache_stats cs;
    wvol_error err;
    /* the padded 56 x 56 x 64 float pyramid */
    const size_t pyramid = 56 * 56 * 64 * sizeof(float);
    const double iso = vmin + 0.3 * (vmax - vmin);
    size_t budget = 0;
    double maxd = 0;
    if (!ms) return;
    wvol_iso_params_default(&ip);
    ip.brick = 8; /* small bricks: wide aprons against their size, so the bricks cost more */
    CHECK(wvol_store_open(&whole, PATH, 0, NULL, &err) == WVOL_OK, "open: %s", err.message);
    if (whole) {
        CHECK(wvol_iso_extract_store(&mw, whole, iso, &ip, &sw, &err) == WVOL_OK, "mc file: %s", err.message);
        CHECK(wvol_store_file_stats(whole, &cs, &err) == WVOL_OK, "no decoding error: %s", err.message);
        /* the file decoded whole, straight into the pyramid: through its chunk cache only the
         * low-pass cube's chunk, which the index's bounds read */
        CHECK(cs.decoded <= 1 && wvol_store_file_info(whole)->chunks > 50,
              "whole inverse: %llu chunks decoded through the cache", (unsigned long long)cs.decoded);
        budget = pyramid / 2; /* chunks a brick pins, not the pyramid */
        CHECK(wvol_store_open(&tight, PATH, budget, NULL, &err) == WVOL_OK, "open: %s", err.message);
    }
    if (whole && tight) {
        CHECK(wvol_iso_extract_store(&mm, ms, iso, &ip, &sm, &err) == WVOL_OK, "mc memory: %s", err.message);
        CHECK(wvol_iso_extract_store(&mt, tight, iso, &ip, &st, &err) == WVOL_OK, "mc file: %s", err.message);
        CHECK(!sm.whole_inverse && sw.whole_inverse && !st.whole_inverse,
              "whole inverse: memory store %d, room for the pyramid %d, no room %d (%zu of %zu bricks meshed)",
              sm.whole_inverse, sw.whole_inverse, st.whole_inverse, sw.bricks_meshed, sw.bricks_total);
        if (mm && mw && mt) {
            /* no brick skipped by the index here: the whole reconstruction's dense marching
             * cubes, which is the mesh of the file decoded whole and meshed, bit for bit */
            wvol_coeffs *dc = NULL;
            wvol_volume *dv = NULL;
            wvol_mesh *md = NULL;
            CHECK(sw.bricks_skipped == 0 && wvol_wvc_read(&dc, PATH, NULL, NULL, &err) == WVOL_OK &&
                      wvol_idwt3_consume(&dv, &dc, &err) == WVOL_OK &&
                      wvol_iso_extract(&md, dv, iso, &ip, NULL, &err) == WVOL_OK,
                  "the file decoded whole and meshed: %s", err.message);
            CHECK(md && md->ntris == mw->ntris && md->nverts == mw->nverts &&
                      !memcmp(md->verts, mw->verts, 3 * mw->nverts * sizeof *mw->verts) &&
                      !memcmp(md->tris, mw->tris, 3 * mw->ntris * sizeof *mw->tris),
                  "whole inverse: the mesh of the file decoded whole (%zu / %zu triangles)", mw->ntris,
                  md ? md->ntris : 0);
            wvol_mesh_destroy(md);
            wvol_volume_destroy(dv);
            wvol_coeffs_destroy(dc);
            /* the bricks (no room) against the memory store's: the same reconstructions */
            CHECK(mw->ntris == mm->ntris && mt->ntris == mm->ntris && mt->nverts == mm->nverts && mm->ntris > 100,
                  "triangles: memory %zu, whole %zu, bricks %zu", mm->ntris, mw->ntris, mt->ntris);
            if (mt->nverts == mm->nverts)
                for (size_t i = 0; i < 3 * mm->nverts; i++)
                    if (fabs((double)mt->verts[i] - (double)mm->verts[i]) > maxd)
                        maxd = fabs((double)mt->verts[i] - (double)mm->verts[i]);
            CHECK(maxd < 1e-4, "bricks from the file against the memory store's: vertices differ by %g voxels", maxd);
        }
        CHECK(wvol_store_file_stats(tight, &cs, &err) == WVOL_OK && cs.peak <= budget,
              "tight budget kept: cache peak %zu of %zu", cs.peak, budget);
    }
    wvol_mesh_destroy(mm);
    wvol_mesh_destroy(mw);
    wvol_mesh_destroy(mt);
    wvol_store_destroy(whole);
    wvol_store_destroy(tight);
    wvol_store_destroy(ms);
    remove(PATH);
}

int main(void)
{
    file_store_meshes_and_renders_like_the_memory_store();
    file_store_meshes_from_the_whole_inverse_when_it_is_cheaper();
    return check_summary("test_wvc_store");
}
