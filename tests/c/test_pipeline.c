/* SPDX-License-Identifier: MIT */
/* The library's two entry points: wvol_compress (transform -> selection -> store, the
 * quantiser's error-target rule) and wvol_render (AUTO resolved by the library, one call for
 * a dense volume or a store): what they choose, that they equal the per-method calls they
 * stand for, and what they refuse. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/compress.h"
#include "wvol/render.h"
#include "wvol/wvc.h"

static double blob(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double x = (double)i - 0.45 * (double)v->nx, y = (double)j - 0.5 * (double)v->ny, z = (double)k - 0.55 * (double)v->nz;
    (void)ctx;
    return exp(-(x * x + y * y + z * z) / 40.0);
}

/* Bit-equal images (the same call underneath must give the same bits). */
static int same_image(const wvol_image *a, const wvol_image *b)
{
    return a->width == b->width && a->height == b->height &&
           !memcmp(a->rgba, b->rgba, 4 * sizeof(float) * (size_t)a->width * (size_t)a->height);
}

static void compress_defaults_and_refusals(void)
{
    wvol_volume *v = fixture_volume(24, 20, 16, blob, NULL);
    wvol_compress_params p;
    wvol_compressed c;
    wvol_error err;
    if (!v) return;
    wvol_compress_params_default(&p);
    /* the default levels: 3 for a store, 5 for a file, capped at what the volume allows (16 -> 4) */
    CHECK(wvol_compress_levels(v, &p) == 3, "store levels %d", wvol_compress_levels(v, &p));
    p.for_file = 1;
    CHECK(wvol_compress_levels(v, &p) == 4, "file levels capped at 4: %d", wvol_compress_levels(v, &p));
    p.for_file = 0;
    p.select.mode = WVOL_SELECT_FRACTION;
    p.select.fraction = 0.1;
    CHECK(wvol_compress(&c, v, &p, &err) == WVOL_OK, "%s", err.message);
    if (c.store) {
        wvol_store_info si;
        wvol_store_get_info(c.store, &si);
        CHECK(c.levels == 3 && si.levels == 3 && si.kept == c.report.kept, "levels %d, kept %zu / %zu", c.levels,
              si.kept, c.report.kept);
        CHECK(wvol_store_basis(c.store)->J == 4, "default spline J %d", wvol_store_basis(c.store)->J);
        CHECK(c.value_max > 0.9 && c.value_min >= 0, "range %g..%g", c.value_min, c.value_max);
    }
    wvol_compressed_free(&c);
    CHECK(c.store == NULL && c.coeffs == NULL, "free leaves the result zeroed");
    wvol_compressed_free(NULL);
    /* refusals, each naming the parameter; nothing left allocated */
    p.levels = 5;
    CHECK(wvol_compress(&c, v, &p, &err) == WVOL_ERR_ARG && strstr(err.message, "levels 5") && !c.store,
          "too many levels: %s", err.message);
    p.levels = 2;
    p.select.drop_levels = 2;
    CHECK(wvol_compress(&c, v, &p, &err) == WVOL_ERR_ARG && strstr(err.message, "drop_levels"), "%s", err.message);
    p.select.drop_levels = 0;
    p.wavelet = "db99";
    CHECK(wvol_compress(&c, v, &p, &err) == WVOL_ERR_ARG && strstr(err.message, "db99"), "%s", err.message);
    CHECK(wvol_compress(&c, NULL, NULL, &err) == WVOL_ERR_ARG, "no volume");
    p.wavelet = "db2";
    p.for_file = 1;
    p.select.mode = WVOL_SELECT_ALL;
    CHECK(wvol_compress(&c, v, &p, &err) == WVOL_OK, "%s", err.message);
    {
        void *buf = NULL;
        size_t n = 0;
        p.quant.format_version = 7;
        CHECK(wvol_compress_encode(&buf, &n, &c, &p, NULL, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "format version 7") && !buf,
              "format version 7: %s", err.message);
    }
    wvol_compressed_free(&c);
    wvol_volume_destroy(v);
}

static void quantiser_rule(void)
{
    wvol_compress_quant q;
    wvol_compress_params p;
    wvol_wvc_params wp;
    wvol_error err;
    double n = 1000, floor120 = wvol_wvc_sse_for_psnr(120, n, 0, 1);
    wvol_compress_params_default(&p);
    q = p.quant;
    /* the share rule: 2% of the dropped energy, never below what 120 dB allows */
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_OK && fabs(wp.target_sse - 0.02) < 1e-15,
          "share: %g", wp.target_sse);
    CHECK(wvol_compress_wvc_params(&wp, &q, 0.0, n, 0, 1, &err) == WVOL_OK && wp.target_sse >= floor120 * 0.999,
          "floor: %g vs %g", wp.target_sse, floor120);
    /* the PSNR rule: the step meets budget - dropped */
    q.psnr = 40;
    CHECK(wvol_compress_wvc_params(&wp, &q, 0.01, n, 0, 1, &err) == WVOL_OK &&
              fabs(wp.target_sse - (wvol_wvc_sse_for_psnr(40, n, 0, 1) - 0.01)) < 1e-12,
          "psnr: %g", wp.target_sse);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "dropped"),
          "dropping beyond the target: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 0.0, n, 2, 2, &err) == WVOL_ERR_ARG && strstr(err.message, "constant"),
          "constant volume: %s", err.message);
    q.psnr = 0;
    q.share = 1.5;
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "share"),
          "share out of range: %s", err.message);
    q.share = 0.02;
    q.step = 0.25;
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_OK && wp.step == 0.25, "explicit step");
    /* refused whatever the rule (a step given too), naming the value */
    q.format_version = 7;
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "format version 7"),
          "format version 7: %s", err.message);
    q.format_version = 0;
    q.psnr = NAN;
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "PSNR"),
          "NaN PSNR: %s", err.message);
    q.psnr = -1;
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "PSNR -1"),
          "negative PSNR: %s", err.message);
    q.psnr = 0;
    CHECK(wvol_compress_wvc_params(&wp, &q, NAN, n, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "dropped"),
          "NaN dropped: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, -1, n, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "dropped"),
          "negative dropped: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, 0, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "voxel"),
          "no voxels: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, -5, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "voxel"),
          "negative voxels: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, NAN, 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "voxel"),
          "NaN voxels: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 2, 1, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "value range"),
          "vmin > vmax: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, 0, INFINITY, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "value range"),
          "infinite vmax: %s", err.message);
    CHECK(wvol_compress_wvc_params(&wp, &q, 1.0, n, NAN, 1, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "value range"),
          "NaN vmin: %s", err.message);
}

static void render_resolves_auto(void)
{
    wvol_volume *v = fixture_volume(24, 24, 16, blob, NULL);
    wvol_compressed c = {0};
    wvol_render_source vol, st;
    wvol_render_params p;
    wvol_render_stats s;
    wvol_geometry g;
    wvol_camera ortho, persp;
    wvol_image *a = NULL, *b = NULL;
    wvol_tf tf;
    wvol_error err;
    CHECK(v && fixture_compress(&c, v, "db2", 3, 0.2, 0, 1) == 0, "volume and store");
    if (!c.store) {
        wvol_volume_destroy(v);
        return;
    }
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&ortho, "+z", &g, 24, 24, NULL);
    wvol_camera_parse(&persp, "persp dir=1,0.7,0.4", &g, 24, 24, NULL);
    wvol_tf_resolve(&tf, "gaussian", 0, 1, NULL);
    wvol_image_create(&a, 24, 24, NULL);
    wvol_image_create(&b, 24, 24, NULL);
    vol = wvol_render_source_volume(v);
    st = wvol_render_source_store(c.store);
    if (!a || !b) goto done;

    /* a dense volume: reference, the same bits as the per-method call */
    wvol_render_params_default(&p);
    CHECK(wvol_render(a, &vol, &persp, &tf, &p, &s, &err) == WVOL_OK && s.method == WVOL_RENDER_METHOD_REFERENCE,
          "volume auto: %s %s", err.message, wvol_render_method_name(s.method));
    CHECK(wvol_render_reference(b, v, &persp, &tf, &p, NULL, &err) == WVOL_OK && same_image(a, b), "volume = reference");
    /* a store: bricks for absorption, axis for an X-ray along an axis, bricks for an oblique X-ray */
    CHECK(wvol_render(a, &st, &persp, &tf, &p, &s, &err) == WVOL_OK && s.method == WVOL_RENDER_METHOD_BRICKS,
          "store auto: %s", wvol_render_method_name(s.method));
    CHECK(wvol_render_bricks(b, c.store, &persp, &tf, &p, NULL, &err) == WVOL_OK && same_image(a, b), "store = bricks");
    p.mode = WVOL_RENDER_MODE_XRAY;
    CHECK(wvol_render(a, &st, &ortho, NULL, &p, &s, &err) == WVOL_OK && s.method == WVOL_RENDER_METHOD_AXIS,
          "xray +z: %s", wvol_render_method_name(s.method));
    CHECK(wvol_render_xray_axis(b, c.store, &ortho, &p, NULL, &err) == WVOL_OK && same_image(a, b), "store = axis");
    CHECK(wvol_render(a, &st, &persp, NULL, &p, &s, &err) == WVOL_OK && s.method == WVOL_RENDER_METHOD_BRICKS,
          "xray perspective: %s", wvol_render_method_name(s.method));
    /* reference from a store: the dense reconstruction of its coefficients, its price reported */
    p.mode = WVOL_RENDER_MODE_ABSORPTION;
    p.method = WVOL_RENDER_METHOD_REFERENCE;
    CHECK(wvol_render(a, &st, &persp, &tf, &p, &s, &err) == WVOL_OK && s.method == WVOL_RENDER_METHOD_REFERENCE &&
              s.reconstruct_cpu_seconds >= 0 && s.reconstruct_cpu_seconds <= s.cpu_seconds,
          "store reference: %s", err.message);
    {
        wvol_volume *rec = NULL;
        CHECK(wvol_idwt3(&rec, c.coeffs, &err) == WVOL_OK && wvol_render_reference(b, rec, &persp, &tf, &p, NULL, &err) == WVOL_OK &&
                  same_image(a, b),
              "store reference = reference on the reconstruction");
        wvol_volume_destroy(rec);
    }
    /* refusals */
    p.method = WVOL_RENDER_METHOD_BRICKS;
    CHECK(wvol_render(a, &vol, &persp, &tf, &p, &s, &err) == WVOL_ERR_UNSUPPORTED && strstr(err.message, "bricks"),
          "store method on a volume: %s", err.message);
    p.method = (wvol_render_method)42;
    CHECK(wvol_render(a, &st, &persp, &tf, &p, &s, &err) == WVOL_ERR_ARG, "unknown method");
    p.method = WVOL_RENDER_METHOD_AUTO;
    vol.kind = (wvol_render_source_kind)9;
    CHECK(wvol_render(a, &vol, &persp, &tf, &p, &s, &err) == WVOL_ERR_ARG, "unknown source kind");
    CHECK(wvol_render(a, NULL, &persp, &tf, &p, &s, &err) == WVOL_ERR_ARG, "no source");
    st.store = NULL;
    CHECK(wvol_render(a, &st, &persp, &tf, &p, &s, &err) == WVOL_ERR_ARG, "no store");
done:
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_compressed_free(&c);
    wvol_volume_destroy(v);
}

static void names_round_trip(void)
{
    wvol_render_method m;
    wvol_render_mode mode;
    wvol_error err;
    for (int i = 0; i <= WVOL_RENDER_METHOD_SPLAT; i++)
        CHECK(wvol_render_method_parse(&m, wvol_render_method_name((wvol_render_method)i), &err) == WVOL_OK && (int)m == i,
              "method %d", i);
    for (int i = 0; i <= WVOL_RENDER_MODE_ABSORPTION_LINEAR; i++)
        CHECK(wvol_render_mode_parse(&mode, wvol_render_mode_name((wvol_render_mode)i), &err) == WVOL_OK && (int)mode == i,
              "mode %d", i);
    CHECK(wvol_render_method_parse(&m, "magic", &err) == WVOL_ERR_ARG && strstr(err.message, "magic"), "%s", err.message);
    CHECK(wvol_render_mode_parse(&mode, "mip", &err) == WVOL_ERR_ARG && strstr(err.message, "mip"), "%s", err.message);
    CHECK(!strcmp(wvol_render_method_name((wvol_render_method)-1), "unknown"), "out-of-range name");
}

int main(void)
{
    compress_defaults_and_refusals();
    quantiser_rule();
    render_resolves_auto();
    names_round_trip();
    return check_summary("test_pipeline");
}
