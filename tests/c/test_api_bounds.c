/* SPDX-License-Identifier: MIT */
/* Public entry points given counts, sizes, indices and descriptors out of their range: each is
 * refused with a message (or, for the functions without a status, gives the documented empty
 * answer) instead of starting billions of threads, looping without end or reading and writing
 * outside its arrays. Cases from a probe of the C API under AddressSanitizer. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/analysis.h"
#include "wvol/iso.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"
#include "wvol_synth.h"

static int has(const wvol_error *e, const char *words)
{
    return strstr(e->message, words) != NULL;
}

/* Thread counts above 4096 would each start a thread with its stack: refused at every entry
 * point that takes one. */
static void test_thread_counts(const wvol_volume *v, const wvol_store *s, const char *wvc_path)
{
    wvol_error err;
    wvol_mesh *m = NULL;
    wvol_iso_params ip;
    wvol_iso_trace_params tp;
    wvol_render_params rp;
    wvol_image *img = NULL;
    wvol_camera cam;
    wvol_geometry g;
    wvol_tf tf;
    wvol_render_source src = wvol_render_source_volume(v);
    float *buf = malloc(8 * 8 * 8 * sizeof *buf);

    wvol_iso_params_default(&ip);
    ip.threads = 5000;
    CHECK(wvol_iso_extract(&m, v, 0.5, &ip, NULL, &err) == WVOL_ERR_ARG && has(&err, "threads 5000 outside 0..4096"),
          "iso extract: %s", err.message);
    CHECK(wvol_iso_extract_store(&m, s, 0.5, &ip, NULL, &err) == WVOL_ERR_ARG && has(&err, "threads 5000"),
          "iso extract store: %s", err.message);
    CHECK(m == NULL, "no mesh");

    CHECK(wvol_image_create(&img, 4, 4, &err) == WVOL_OK, "%s", err.message);
    wvol_geometry_of_volume(&g, v);
    CHECK(wvol_camera_parse(&cam, "+z", &g, 4, 4, &err) == WVOL_OK, "%s", err.message);
    wvol_iso_trace_params_default(&tp);
    tp.threads = 1 << 30;
    CHECK(wvol_iso_raytrace(img, NULL, NULL, s, &cam, 0.5, &tp, NULL, &err) == WVOL_ERR_ARG &&
              has(&err, "threads 1073741824 outside"),
          "iso raytrace: %s", err.message);
    wvol_render_params_default(&rp);
    rp.threads = 1 << 30;
    CHECK(wvol_tf_preset(&tf, "grey", 0.0, 1.0, &err) == WVOL_OK, "preset: %s", err.message);
    CHECK(wvol_render(img, &src, &cam, &tf, &rp, NULL, &err) == WVOL_ERR_ARG && has(&err, "threads"),
          "render: %s", err.message);
    wvol_image_destroy(img);

    if (wvc_path && buf) {
        wvol_wvc_file *f = NULL;
        const size_t lo[3] = {0, 0, 0}, hi[3] = {8, 8, 8};
        double sp[3], org[3];
        CHECK(wvol_wvc_open(&f, wvc_path, 0, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_wvc_read_region_into(buf, f, lo, hi, 0, -1, sp, org, &err) == WVOL_ERR_ARG &&
                  has(&err, "threads -1 outside"),
              "region: %s", err.message);
        CHECK(wvol_wvc_read_region_into(buf, f, lo, hi, 0, 1 << 30, sp, org, &err) == WVOL_ERR_ARG,
              "region: %s", err.message);
        CHECK(wvol_wvc_read_piece_into(buf, 8 * 8 * 8, f, lo, hi, 0, -1, sp, org, &err) != WVOL_OK,
              "piece: threads -1 accepted");
        CHECK(wvol_wvc_read_region_into(buf, f, lo, hi, 0, 2, sp, org, &err) == WVOL_OK, "region: %s", err.message);
        /* a box beyond the grid has no budget (0), not one counted with wrapped sizes */
        const size_t far[3] = {SIZE_MAX, 4, 4};
        CHECK(wvol_wvc_slab_budget(f, 0, lo, far) == 0, "slab budget of a box beyond the grid");
        CHECK(wvol_wvc_slab_budget(f, 0, lo, hi) > 0, "slab budget of the whole grid");
        wvol_wvc_close(f);
    }
    free(buf);
}

/* The exact tracer refines a crossing by bisection in float64: a tolerance or a chunk far
 * below what float64 positions resolve is refused instead of looping. */
static void test_trace_tolerance(const wvol_store *s)
{
    wvol_error err;
    wvol_iso_trace_params tp;
    wvol_iso_hit hit;
    const double o[3] = {-5, 4, 4}, d[3] = {1, 0, 0};
    wvol_iso_trace_params_default(&tp);
    tp.tolerance = 1e-300;
    CHECK(wvol_iso_trace_ray(s, 0.5, o, d, &tp, &hit, &err) == WVOL_ERR_ARG && has(&err, "tolerance"),
          "tolerance 1e-300: %s", err.message);
    wvol_iso_trace_params_default(&tp);
    tp.chunk = 1e-300;
    CHECK(wvol_iso_trace_ray(s, 0.5, o, d, &tp, &hit, &err) == WVOL_ERR_ARG && has(&err, "chunk"),
          "chunk 1e-300: %s", err.message);
    wvol_iso_trace_params_default(&tp);
    tp.tolerance = 1e-8; /* fine, and reachable */
    CHECK(wvol_iso_trace_ray(s, 0.5, o, d, &tp, &hit, &err) == WVOL_OK, "tolerance 1e-8: %s", err.message);
}

static void test_descriptors_and_indices(void)
{
    wvol_error err;
    float d[8] = {0};
    /* sizes whose product overflows, and no samples */
    CHECK(wvol_check_finite(d, SIZE_MAX, 2, 2, "x", &err) == WVOL_ERR_ARG && has(&err, "overflow"),
          "check_finite overflow: %s", err.message);
    CHECK(wvol_check_finite(NULL, 2, 2, 2, "x", &err) == WVOL_ERR_ARG, "check_finite NULL: %s", err.message);
    CHECK(wvol_check_finite(d, 2, 2, 2, "x", &err) == WVOL_OK, "8 zeros are finite");

    /* a row a level does not have is ignored, not written past the array */
    {
        wvol_coeffs *c = NULL;
        float row[64];
        for (int i = 0; i < 64; i++) row[i] = 7.0f;
        CHECK(wvol_coeffs_create(&c, fixture_filter("haar"), 1, 4, 4, 4, &err) == WVOL_OK, "%s", err.message);
        if (c) {
            wvol_coeffs_put_rows(c, 1, 2, row, row); /* level 1 of a 4^3 cube has rows 0, 1 */
            wvol_coeffs_put_rows(c, 9, 0, row, row);
            int changed = 0;
            for (size_t i = 0; i < 64; i++) changed += c->data[i] != 0.0f;
            CHECK(changed == 0, "%d values written by rows that do not exist", changed);
            wvol_coeffs_put_rows(c, 1, 1, row, row);
            changed = 0;
            for (size_t i = 0; i < 64; i++) changed += c->data[i] != 0.0f;
            CHECK(changed > 0, "row 1 of level 1 is written");
            wvol_coeffs_destroy(c);
        }
    }

    /* no bytes is no .wvc file: refused, nothing left at the path */
    {
        char path[] = "/tmp/wvol_api_bounds_XXXXXX";
        int fd = mkstemp(path);
        CHECK(fd >= 0, "mkstemp");
        if (fd >= 0) {
            close(fd);
            unlink(path);
            CHECK(wvol_wvc_save(path, NULL, 100, &err) == WVOL_ERR_ARG, "save NULL: %s", err.message);
            CHECK(wvol_wvc_save(path, d, 0, &err) == WVOL_ERR_ARG && has(&err, "no encoded bytes"),
                  "save 0 bytes: %s", err.message);
            CHECK(access(path, F_OK) != 0, "nothing written at %s", path);
        }
    }

    /* a piece index outside the table: the empty range */
    {
        wvol_basis *b = NULL;
        double lo = 0, hi = 0;
        CHECK(wvol_basis_create(&b, fixture_filter("db2"), 4, &err) == WVOL_OK, "%s", err.message);
        if (b) {
            wvol_basis_piece_range(b, 0, -1, &lo, &hi);
            CHECK(lo > hi, "piece -1: [%g, %g]", lo, hi);
            wvol_basis_piece_range(b, 1, 1 << 30, &lo, &hi);
            CHECK(lo > hi, "piece 2^30: [%g, %g]", lo, hi);
            wvol_basis_piece_range(b, 0, 0, &lo, &hi);
            CHECK(lo <= hi, "piece 0: [%g, %g]", lo, hi);
            wvol_basis_destroy(b);
        }
    }

    /* a mesh filled by the caller whose triangles name missing vertices, or without arrays */
    {
        float verts[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
        uint32_t tris[3] = {0, 1, 99};
        wvol_mesh m;
        memset(&m, 0, sizeof m);
        m.verts = verts, m.nverts = 3, m.tris = tris, m.ntris = 1;
        CHECK(isnan(wvol_mesh_area(&m)) && isnan(wvol_mesh_volume(&m)), "index 99 of 3 vertices");
        tris[2] = 2;
        CHECK(fabs(wvol_mesh_area(&m) - 0.5) < 1e-12, "area of the unit right triangle");
        m.verts = NULL, m.nverts = 5;
        CHECK(isnan(wvol_mesh_area(&m)), "no vertex array");
        CHECK(wvol_mesh_save(&m, "/tmp/wvol_api_bounds_no_vertices.ply", &err) == WVOL_ERR_ARG &&
                  has(&err, "no array"),
              "save without vertices: %s", err.message);
        CHECK(access("/tmp/wvol_api_bounds_no_vertices.ply", F_OK) != 0, "nothing written");
        CHECK(wvol_mesh_area(NULL) == 0.0, "NULL mesh");
    }

    /* winners that name no neuron map to no class */
    {
        wvol_som som;
        int nc[2] = {3, 4};
        const int32_t win[4] = {0, 1, 99999, -5};
        int32_t out[4];
        memset(&som, 0, sizeof som);
        som.dims[0] = 2, som.dims[1] = som.dims[2] = 1, som.neurons = 2, som.neuron_class = nc;
        wvol_som_apply_classes(out, win, 4, &som);
        CHECK(out[0] == 3 && out[1] == 4 && out[2] == -1 && out[3] == -1, "classes %d %d %d %d", out[0], out[1],
              out[2], out[3]);
    }

    /* an info descriptor not made by the parser */
    {
        wvol_wvc_info *info = calloc(1, sizeof *info);
        if (info) {
            info->step = 1.0;
            info->rounding = 0.38;
            info->nsections = 10000;
            CHECK(wvol_wvc_max_coeff_error(info) == 0.0, "10000 sections");
            info->nsections = 1;
            CHECK(wvol_wvc_max_coeff_error(info) > 0.0, "one section");
            free(info);
        }
    }

    /* an iterator not advanced by wvol_store_next: no shift past the bands */
    {
        wvol_volume *v = fixture_volume(8, 8, 8, fixture_shell_blob, NULL);
        wvol_store *s = v ? fixture_store(v, "haar", 2, 1.0, 0) : NULL;
        if (s) {
            wvol_store_iter it = {1, 100000};
            wvol_store_coeff c;
            size_t n = 0;
            while (wvol_store_next(s, &it, &c) && n < 100000) n++;
            CHECK(n < 100000, "the iteration ends");
            wvol_store_destroy(s);
        }
        wvol_volume_destroy(v);
    }

    /* f^ at an infinite point: NaN, as at a NaN one */
    {
        wvol_volume *v = fixture_volume(8, 8, 8, fixture_shell_blob, NULL);
        wvol_coeffs *c = NULL;
        wvol_basis *b = NULL;
        if (v && wvol_dwt3(&c, v, fixture_filter("db2"), 2, &err) == WVOL_OK &&
            wvol_basis_create(&b, fixture_filter("db2"), 4, &err) == WVOL_OK) {
            const double inf[3] = {INFINITY, 0, 0}, ok[3] = {3, 3, 3};
            CHECK(isnan(wvol_fhat_eval(c, b, inf, NULL)), "f^ at +inf");
            CHECK(isfinite(wvol_fhat_eval(c, b, ok, NULL)), "f^ at (3, 3, 3)");
        }
        wvol_basis_destroy(b);
        wvol_coeffs_destroy(c);
        wvol_volume_destroy(v);
    }

    /* a synthetic volume whose byte count overflows */
    {
        wvol_synth_params p;
        wvol_volume *v = NULL;
        wvol_synth_params_default(&p);
        p.dims[0] = SIZE_MAX, p.dims[1] = SIZE_MAX, p.dims[2] = 8;
        CHECK(wvol_synth_make(&v, NULL, "turbulence", &p, &err) == WVOL_ERR_DIMS && has(&err, "overflows"),
              "synth: %s", err.message);
        CHECK(v == NULL, "no volume");
    }
}

int main(void)
{
    wvol_error err;
    wvol_volume *v = fixture_volume(8, 8, 8, fixture_shell_blob, NULL);
    wvol_store *s = v ? fixture_store(v, "db2", 2, 1.0, 0) : NULL;
    char path[] = "/tmp/wvol_api_bounds_wvc_XXXXXX";
    int fd = mkstemp(path);
    int have_wvc = 0;
    CHECK(v && s && fd >= 0, "fixtures");
    if (fd >= 0) close(fd);
    if (v && fd >= 0) {
        wvol_compress_params cp;
        wvol_compressed kept;
        void *buf = NULL;
        size_t n = 0;
        wvol_wvc_params wp;
        wvol_compress_params_default(&cp);
        cp.wavelet = "haar";
        cp.levels = 2;
        if (wvol_compress(&kept, v, &cp, &err) == WVOL_OK) {
            wvol_wvc_params_default(&wp);
            wp.step = 1e-3;
            wp.tile = 8;
            wp.value_min = 0, wp.value_max = 1;
            if (wvol_wvc_encode(&buf, &n, kept.coeffs, &wp, NULL, &err) == WVOL_OK &&
                wvol_wvc_save(path, buf, n, &err) == WVOL_OK)
                have_wvc = 1;
            free(buf);
            wvol_compressed_free(&kept);
        }
        CHECK(have_wvc, "fixture .wvc: %s", err.message);
    }
    if (v && s) {
        test_thread_counts(v, s, have_wvc ? path : NULL);
        test_trace_tolerance(s);
    }
    test_descriptors_and_indices();
    if (fd >= 0) unlink(path);
    wvol_store_destroy(s);
    wvol_volume_destroy(v);
    return check_summary("api_bounds");
}
