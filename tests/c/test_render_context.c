/* SPDX-License-Identifier: MIT
 * Tests of the render context (libwvol/src/render/context.c, the bricked state kept across
 * frames in render/bricks.c): every frame's image must be the one-shot wvol_render's bit for
 * bit, whatever the context holds (camera turned between frames, bricks cached or evicted by a
 * small budget, one and two threads), a TF change, a mode change, a settings change and a
 * source change must drop exactly what depends on them, and the brick cache must stay within
 * its budget. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/render.h"
#include "wvol/store.h"

enum { W = 48, H = 40 };

/* A shell and a blob (fixture_shell_blob) with noise (+-0.05 from a hash of the voxel
 * index) and anisotropic voxels: noisy bricks, bricks empty under a thresholded TF, sub-cells
 * of both kinds. */
static double noisy_voxel(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    uint64_t h = (uint64_t)(i + v->nx * (j + v->ny * k)) * 0x9E3779B97F4A7C15ull;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 32;
    return fixture_shell_blob(v, i, j, k, ctx) + 0.1 * ((double)(h >> 11) / 9007199254740992.0 - 0.5);
}

static wvol_volume *noisy(size_t nx, size_t ny, size_t nz)
{
    const double sp[3] = {1.0, 1.0, 1.7};
    return fixture_with_spacing(fixture_volume(nx, ny, nz, noisy_voxel, NULL), sp);
}

/* Two TFs with different kappa thresholds (their sub-cells and empty bricks differ), and the
 * first with other colours only (the same kappa: the rates are kept). */
static const char *TF_A = "units diagonal\n0.25 0.2 0.3 0.9 0\n1 1 0.8 0.5 30\n";
static const char *TF_B = "units diagonal\n0.5 1 1 1 0\n1.2 1 0.9 0.7 60\n";
static const char *TF_A_RECOLOURED = "units diagonal\n0.25 0.9 0.1 0.1 0\n1 0.1 0.9 0.2 30\n";

/* The camera `spec` turned by deg degrees about +z through its look-at point (a user rotating
 * the view between frames). */
static wvol_camera turned(const wvol_geometry *g, const char *spec, double deg)
{
    wvol_camera c;
    wvol_error err;
    double k = deg * 3.14159265358979323846 / 180.0, v[2];
    CHECK(wvol_camera_parse(&c, spec, g, W, H, &err) == WVOL_OK, "%s", err.message);
    v[0] = c.eye[0] - c.center[0], v[1] = c.eye[1] - c.center[1];
    c.eye[0] = c.center[0] + v[0] * cos(k) - v[1] * sin(k);
    c.eye[1] = c.center[1] + v[0] * sin(k) + v[1] * cos(k);
    return c;
}

/* One frame through the context and the same frame one-shot: 1 when both ran; the images
 * must be equal bit for bit and take the same samples. */
static int frame_equals_one_shot(wvol_render_context *ctx, const wvol_render_source *src, const wvol_camera *cam,
                                 const char *tftext, const wvol_render_params *p, wvol_render_stats *sc,
                                 const char *what)
{
    wvol_image *a = NULL, *b = NULL;
    wvol_render_stats so;
    wvol_tf tf;
    wvol_error err;
    int ok = 0;
    memset(sc, 0, sizeof *sc);
    memset(&so, 0, sizeof so);
    CHECK(wvol_tf_parse(&tf, tftext, "tf", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_image_create(&a, W, H, &err) == WVOL_OK && wvol_image_create(&b, W, H, &err) == WVOL_OK, "%s",
          err.message);
    if (a && b) {
        CHECK(wvol_render_context_frame(ctx, a, cam, &tf, p, sc, &err) == WVOL_OK, "%s: %s", what, err.message);
        CHECK(wvol_render(b, src, cam, &tf, p, &so, &err) == WVOL_OK, "%s: %s", what, err.message);
        CHECK(memcmp(a->rgba, b->rgba, sizeof(float) * 4 * W * H) == 0, "%s: context frame differs from one-shot",
              what);
        CHECK(sc->samples == so.samples && sc->method == so.method, "%s: %zu samples (method %d) against %zu (%d)",
              what, sc->samples, (int)sc->method, so.samples, (int)so.method);
        CHECK(so.context_frame == 0, "%s: one-shot frame reports context frame %d", what, so.context_frame);
        ok = 1;
        {
            double alpha = 0;
            for (size_t i = 3; i < 4u * W * H; i += 4) alpha += a->rgba[i];
            CHECK(alpha > 1, "%s: empty image (alpha sum %.3g): nothing compared", what, alpha);
        }
    }
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    return ok;
}

/* A camera turned frame after frame through one context, then frames of the first camera
 * again: bit for bit the one-shot images, with a budget that holds every brick (later frames
 * of an unchanged camera then build nothing), one that holds a few (bricks evicted and built
 * again), and the default; one and two threads; a perspective, an oblique orthographic and an
 * axis-parallel orthographic camera (brick orders with every kind of axis). With two threads
 * and a cache that holds the bricks, the later frames walk tiles of their own (tiles_own) and
 * the one-shot frames share each tile: the images must still be equal. */
static void frames_equal_one_shot(void)
{
    wvol_volume *v = noisy(70, 64, 40);
    wvol_store *s = v ? fixture_store(v, "db2", 2, 0.05, 0) : NULL;
    wvol_render_source src = wvol_render_source_store(s);
    wvol_geometry g;
    const char *cams[3] = {"persp dir=1,0.7,0.4", "ortho dir=0.3,1,-0.5", "ortho dir=0,0,1"};
    const size_t brick_bytes = 10 * 10 * 10 * sizeof(float); /* bricks of 8: 10^3 voxels */
    const size_t budgets[3] = {1000 * brick_bytes, 12 * brick_bytes, 0};
    CHECK(s != NULL, "store");
    if (!s) goto done;
    wvol_geometry_of_volume(&g, v);
    for (int c = 0; c < 3; c++)
        for (int bi = 0; bi < 3; bi++)
            for (int threads = 1; threads <= 2; threads++) {
                wvol_render_context *ctx = NULL;
                wvol_render_params p;
                wvol_render_stats st;
                wvol_error err;
                char what[160];
                size_t reused = 0;
                int own = 0;
                wvol_render_params_default(&p);
                p.method = WVOL_RENDER_METHOD_BRICKS;
                p.mode = WVOL_RENDER_MODE_ABSORPTION;
                p.bricks.brick = 8;
                p.step = 0.45;
                p.threads = threads;
                p.tile = 16; /* several tiles: the cache serves tiles of one frame too */
                CHECK(wvol_render_context_create(&ctx, &src, &p, budgets[bi], &err) == WVOL_OK, "%s", err.message);
                if (!ctx) continue;
                for (int f = 0; f < 7; f++) {
                    /* frames 0..4 turned by 3 degrees each, 5 and 6 the first camera again */
                    const wvol_camera cam = turned(&g, cams[c], f < 5 ? 3.0 * f : 0.0);
                    snprintf(what, sizeof what, "%s, budget %zu, %d threads, frame %d", cams[c], budgets[bi], threads,
                             f);
                    if (!frame_equals_one_shot(ctx, &src, &cam, TF_A, &p, &st, what)) break;
                    CHECK(st.context_frame == f + 1, "%s: context frame %d", what, st.context_frame);
                    CHECK(st.rates_reused == (f > 0), "%s: rates_reused %d", what, st.rates_reused);
                    if (budgets[bi]) CHECK(st.cache_bytes <= budgets[bi], "%s: cache %zu bytes over its budget", what,
                                           st.cache_bytes);
                    CHECK(wvol_render_context_bytes(ctx) >= st.cache_bytes && st.bytes >= st.cache_bytes,
                          "%s: context bytes %zu, frame bytes %zu, cache %zu", what, wvol_render_context_bytes(ctx),
                          st.bytes, st.cache_bytes);
                    if (f > 0) reused += st.bricks_reused;
                    own += st.tiles_own;
                    if (threads == 1 || f == 0)
                        CHECK(st.tiles_own == 0, "%s: tiles of its own with %s", what,
                              threads == 1 ? "one thread" : "nothing cached yet");
                    else if (bi == 0)
                        CHECK(st.tiles_own == 1, "%s: shared tiles though the cache holds every brick built", what);
                    if (bi == 0 && f == 6)
                        CHECK(st.bricks_built == 0, "%s: the same camera again with every brick cached built %zu",
                              what, st.bricks_built);
                }
                CHECK(reused > 0, "%s: later frames took no brick from the cache", what);
                if (threads == 2 && budgets[bi] != 12 * brick_bytes)
                    CHECK(own > 0, "%s: no frame walked tiles of its own (that path then untested)", what);
                wvol_render_context_destroy(ctx);
            }
done:
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

/* What depends on what: a TF with other kappas recomputes the rates (its image is the new
 * TF's one-shot image, though the cached bricks carry the old TF's sub-cells), a recoloured TF
 * keeps them, the X-ray mode, shading with the low-pass gradient (a settings change: the state
 * built again), another store through set_source (everything dropped), a dense volume (nothing
 * kept), and a failed frame leaves the context usable. */
static void changes_drop_what_depends_on_them(void)
{
    wvol_volume *v = noisy(56, 48, 36);
    wvol_store *s1 = v ? fixture_store(v, "db2", 2, 0.05, 0) : NULL;
    wvol_store *s2 = v ? fixture_store(v, "db2", 2, 0.2, 0) : NULL;
    wvol_render_source src1 = wvol_render_source_store(s1), src2 = wvol_render_source_store(s2);
    wvol_render_source vsrc = wvol_render_source_volume(v);
    wvol_render_context *ctx = NULL;
    wvol_render_params p;
    wvol_render_stats st;
    wvol_geometry g;
    wvol_camera cam, bad;
    wvol_image *img = NULL;
    wvol_tf tf;
    wvol_error err;
    CHECK(s1 && s2, "stores");
    if (!s1 || !s2) goto done;
    wvol_geometry_of_volume(&g, v);
    cam = turned(&g, "persp dir=1,0.7,0.4", 0);
    wvol_render_params_default(&p);
    p.bricks.brick = 16;
    p.threads = 2;
    p.step = 0.5;
    CHECK(wvol_render_context_create(&ctx, &src1, &p, 0, &err) == WVOL_OK, "%s", err.message);
    if (!ctx) goto done;
    /* B first: its cached bricks carry B's sub-cells, which are zero where A's kappa is not */
    frame_equals_one_shot(ctx, &src1, &cam, TF_B, &p, &st, "TF B");
    CHECK(st.method == WVOL_RENDER_METHOD_BRICKS, "AUTO on a store in absorption: method %d", (int)st.method);
    frame_equals_one_shot(ctx, &src1, &cam, TF_A, &p, &st, "TF A after B");
    CHECK(st.rates_reused == 0 && st.context_frame == 2, "TF A after B: rates_reused %d, frame %d", st.rates_reused,
          st.context_frame);
    CHECK(st.bricks_reused > 0, "TF A after B: no cached brick taken (their sub-cells then untested)");
    frame_equals_one_shot(ctx, &src1, &cam, TF_B, &p, &st, "TF B after A");
    CHECK(st.rates_reused == 0, "TF B after A: rates kept");
    frame_equals_one_shot(ctx, &src1, &cam, TF_A, &p, &st, "TF A again");
    frame_equals_one_shot(ctx, &src1, &cam, TF_A_RECOLOURED, &p, &st, "TF A recoloured");
    CHECK(st.rates_reused == 1, "recoloured TF: rates dropped");
    p.mode = WVOL_RENDER_MODE_XRAY;
    p.method = WVOL_RENDER_METHOD_BRICKS;
    frame_equals_one_shot(ctx, &src1, &cam, TF_A, &p, &st, "X-ray");
    CHECK(st.rates_reused == 0, "X-ray after absorption: rates kept");
    p.mode = WVOL_RENDER_MODE_ABSORPTION;
    p.method = WVOL_RENDER_METHOD_AUTO;
    p.shading = 1;
    p.gradient_levels = 1;
    frame_equals_one_shot(ctx, &src1, &cam, TF_A, &p, &st, "low-pass gradient");
    CHECK(st.context_frame == 1, "settings change: frame %d, the state not built again", st.context_frame);
    p.shading = 0;
    p.gradient_levels = 0;
    CHECK(wvol_render_context_set_source(ctx, &src2, &err) == WVOL_OK, "%s", err.message);
    frame_equals_one_shot(ctx, &src2, &cam, TF_A, &p, &st, "second store");
    CHECK(st.context_frame == 1 && st.bricks_reused == 0, "new store: frame %d, %zu bricks reused",
          st.context_frame, st.bricks_reused);
    /* a failed frame (a camera refused) changes nothing kept */
    bad = cam;
    bad.fov_y = 0;
    CHECK(wvol_image_create(&img, W, H, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_parse(&tf, TF_A, "tf", &err) == WVOL_OK, "%s", err.message);
    if (img) CHECK(wvol_render_context_frame(ctx, img, &bad, &tf, &p, &st, &err) == WVOL_ERR_ARG, "bad camera taken");
    frame_equals_one_shot(ctx, &src2, &cam, TF_A, &p, &st, "after a failed frame");
    CHECK(st.context_frame == 2 && st.bricks_reused > 0, "after a failed frame (not counted): frame %d, %zu reused",
          st.context_frame, st.bricks_reused);
    /* a dense volume: wvol_render's reference, nothing kept */
    CHECK(wvol_render_context_set_source(ctx, &vsrc, &err) == WVOL_OK, "%s", err.message);
    frame_equals_one_shot(ctx, &vsrc, &cam, TF_A, &p, &st, "dense volume");
    CHECK(st.method == WVOL_RENDER_METHOD_REFERENCE && wvol_render_context_bytes(ctx) == 0,
          "dense volume: method %d, context holds %zu bytes", (int)st.method, wvol_render_context_bytes(ctx));
done:
    wvol_image_destroy(img);
    wvol_render_context_destroy(ctx);
    wvol_store_destroy(s1);
    wvol_store_destroy(s2);
    wvol_volume_destroy(v);
}

/* Two threads walking tiles of their own (the cache holds every brick built so far) in a frame
 * that needs bricks never built: a zoomed view first (the middle of the volume), then the
 * whole volume, then the whole volume turned. The new bricks are built by the tiles that
 * need them (a brick two threads need at once may be built twice): the images are the
 * one-shot's. */
static void own_tiles_build_new_bricks(void)
{
    wvol_volume *v = noisy(70, 64, 40);
    wvol_store *s = v ? fixture_store(v, "db2", 2, 0.05, 0) : NULL;
    wvol_render_source src = wvol_render_source_store(s);
    wvol_render_context *ctx = NULL;
    wvol_render_params p;
    wvol_render_stats st;
    wvol_geometry g;
    wvol_camera cam;
    wvol_error err;
    CHECK(s != NULL, "store");
    if (!s) goto done;
    wvol_geometry_of_volume(&g, v);
    wvol_render_params_default(&p);
    p.method = WVOL_RENDER_METHOD_BRICKS;
    p.bricks.brick = 8;
    p.step = 0.5;
    p.threads = 2;
    p.tile = 8; /* many tiles: the threads' tiles need the same new bricks at about the same time */
    CHECK(wvol_render_context_create(&ctx, &src, &p, 0, &err) == WVOL_OK, "%s", err.message);
    if (!ctx) goto done;
    cam = turned(&g, "ortho dir=0.3,1,-0.5 zoom=4", 0);
    frame_equals_one_shot(ctx, &src, &cam, TF_A, &p, &st, "zoomed view");
    CHECK(st.tiles_own == 0 && st.bricks_built > 0, "zoomed view (first frame): tiles_own %d, %zu built",
          st.tiles_own, st.bricks_built);
    cam = turned(&g, "ortho dir=0.3,1,-0.5", 0);
    frame_equals_one_shot(ctx, &src, &cam, TF_A, &p, &st, "whole view after the zoomed one");
    CHECK(st.tiles_own == 1 && st.bricks_built > 0, "whole view after the zoomed one: tiles_own %d, %zu built",
          st.tiles_own, st.bricks_built);
    cam = turned(&g, "ortho dir=0.3,1,-0.5", 20);
    frame_equals_one_shot(ctx, &src, &cam, TF_B, &p, &st, "turned, another TF");
done:
    wvol_render_context_destroy(ctx);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
}

static void refusals(void)
{
    wvol_render_context *ctx = (wvol_render_context *)&ctx;
    wvol_render_source none = wvol_render_source_store(NULL), odd = {(wvol_render_source_kind)7, NULL, NULL};
    wvol_error err;
    CHECK(wvol_render_context_create(&ctx, NULL, NULL, 0, &err) == WVOL_ERR_ARG && !ctx, "no source taken");
    CHECK(wvol_render_context_create(&ctx, &none, NULL, 0, &err) == WVOL_ERR_ARG && !ctx, "NULL store taken");
    CHECK(wvol_render_context_create(&ctx, &odd, NULL, 0, &err) == WVOL_ERR_ARG && !ctx, "unknown kind taken");
    CHECK(wvol_render_context_create(NULL, &none, NULL, 0, &err) == WVOL_ERR_ARG, "NULL output taken");
    {
        wvol_volume *v = NULL;
        wvol_render_params p;
        wvol_render_source src;
        CHECK(wvol_volume_create(&v, 4, 4, 4, &err) == WVOL_OK, "%s", err.message);
        src = wvol_render_source_volume(v);
        wvol_render_params_default(&p);
        p.step = NAN;
        CHECK(wvol_render_context_create(&ctx, &src, &p, 0, &err) == WVOL_ERR_ARG && !ctx && strstr(err.message, "step"),
              "NaN step taken: %s", err.message);
        wvol_volume_destroy(v);
    }
    CHECK(wvol_render_context_frame(NULL, NULL, NULL, NULL, NULL, NULL, &err) == WVOL_ERR_ARG, "NULL context taken");
    wvol_render_context_destroy(NULL);
}

int main(void)
{
    frames_equal_one_shot();
    changes_drop_what_depends_on_them();
    own_tiles_build_new_bricks();
    refusals();
    return check_summary("test_render_context");
}
