/* SPDX-License-Identifier: MIT */
/* Volume type, status messages, raw I/O and atomic writes. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <omp.h>

#include "check.h"
#include "core/alloc.h"
#include "wvol/wvol.h"

static void test_create_and_overflow(void)
{
    wvol_volume *v = NULL;
    wvol_error err;
    CHECK(wvol_volume_create(&v, 4, 5, 6, &err) == WVOL_OK, "create: %s", err.message);
    CHECK(v && wvol_volume_count(v) == 120, "count");
    CHECK(v && v->data[119] == 0.0f, "zero-filled");
    wvol_volume_destroy(v);
    v = NULL;
    CHECK(wvol_volume_create(&v, SIZE_MAX / 2, 4, 4, &err) == WVOL_ERR_DIMS, "overflow refused");
    CHECK(v == NULL && strstr(err.message, "overflow") != NULL, "message names overflow: %s", err.message);
    CHECK(wvol_volume_create(&v, 0, 4, 4, &err) == WVOL_ERR_DIMS && strstr(err.message, "every dimension must be at least 1"),
          "zero dim refused: %s", err.message);
    wvol_volume_destroy(NULL);
}

static void test_finite(void)
{
    float d[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    wvol_error err;
    CHECK(wvol_check_finite(d, 2, 2, 2, "x", &err) == WVOL_OK, "finite ok");
    d[5] = NAN;
    CHECK(wvol_check_finite(d, 2, 2, 2, "x", &err) == WVOL_ERR_NONFINITE, "NaN refused");
    CHECK(strstr(err.message, "i=1, j=0, k=1") != NULL, "names voxel: %s", err.message);
    d[5] = 0;
    d[2] = INFINITY;
    CHECK(wvol_check_finite(d, 2, 2, 2, "x", &err) == WVOL_ERR_NONFINITE && strstr(err.message, "Inf"),
          "Inf refused: %s", err.message);
    {
        /* large enough to be searched on the threads (in parts of whole 1024-value blocks):
         * the first NaN or Inf named, wherever the parts fall, on 1 to 3 threads; a tail
         * shorter than a block searched too */
        const size_t nx = 1031, ny = 64, nz = 67, n = nx * ny * nz;
        const size_t at[][2] = {{n - 3, n - 1}, {5, n - 2}, {n / 2 + 7, n / 2 + 900}, {n / 3 - 1, 2 * n / 3}};
        float *big = calloc(n, sizeof *big);
        const int before = omp_get_max_threads();
        CHECK(big != NULL, "out of memory");
        for (int threads = 1; big && threads <= 3; threads++) {
            omp_set_num_threads(threads);
            CHECK(wvol_check_finite(big, nx, ny, nz, "big", &err) == WVOL_OK, "%d threads: all finite", threads);
            for (size_t c = 0; c < sizeof at / sizeof at[0]; c++) {
                char want[64];
                size_t i = at[c][0];
                big[at[c][0]] = NAN;
                big[at[c][1]] = INFINITY;
                snprintf(want, sizeof want, "NaN at voxel (i=%zu, j=%zu, k=%zu)", i % nx, i / nx % ny, i / (nx * ny));
                CHECK(wvol_check_finite(big, nx, ny, nz, "big", &err) == WVOL_ERR_NONFINITE &&
                          strstr(err.message, want),
                      "%d threads: the first (%s) named: %s", threads, want, err.message);
                big[at[c][0]] = 0, big[at[c][1]] = 0;
            }
        }
        omp_set_num_threads(before);
        free(big);
    }
}

static void test_raw_roundtrip(void)
{
    wvol_volume *v = NULL, *w = NULL;
    wvol_load_options lo;
    wvol_error err;
    const char *path = "test_volume_rt.raw";
    size_t i;
    wvol_volume_create(&v, 3, 5, 7, &err);
    for (i = 0; i < 105; i++) v->data[i] = (float)i * 0.5f - 10.0f;
    CHECK(wvol_raw_write(v, path, &err) == WVOL_OK, "raw write: %s", err.message);
    wvol_load_options_default(&lo);
    lo.dims[0] = 3; lo.dims[1] = 5; lo.dims[2] = 7;
    CHECK(wvol_volume_load(&w, path, &lo, &err) == WVOL_OK, "raw load: %s", err.message);
    CHECK(w && memcmp(v->data, w->data, 105 * sizeof(float)) == 0, "raw round trip exact");
    wvol_volume_destroy(w);
    w = NULL;
    lo.dims[2] = 8; /* file too short for these dims */
    CHECK(wvol_volume_load(&w, path, &lo, &err) == WVOL_ERR_FORMAT && w == NULL, "short file refused");
    CHECK(strstr(err.message, "bytes") != NULL, "message gives sizes: %s", err.message);
    lo.dims[2] = 6; /* file too long */
    CHECK(wvol_volume_load(&w, path, &lo, &err) == WVOL_ERR_FORMAT, "long file refused");
    remove(path);
    /* unwritable path: error, and nothing left behind */
    CHECK(wvol_raw_write(v, "/nonexistent-dir/x.raw", &err) == WVOL_ERR_IO, "unwritable refused");
    wvol_volume_destroy(v);
}

static void test_sample_types(void)
{
    const uint8_t u8[3] = {0, 128, 255};
    const int16_t i16[2] = {-32768, 32767};
    const uint8_t be16[2] = {0x01, 0x02}; /* big-endian 258 */
    float out[3];
    wvol_samples_to_float(out, u8, 3, WVOL_SAMPLE_TYPE_U8, 0);
    CHECK(out[0] == 0 && out[1] == 128 && out[2] == 255, "u8");
    wvol_samples_to_float(out, i16, 2, WVOL_SAMPLE_TYPE_I16, 0);
    CHECK(out[0] == -32768 && out[1] == 32767, "i16");
    wvol_samples_to_float(out, be16, 1, WVOL_SAMPLE_TYPE_U16, 1);
    CHECK(out[0] == 258, "big-endian u16: %g", out[0]);
    CHECK(wvol_sample_type_parse("int16") == WVOL_SAMPLE_TYPE_I16 && wvol_sample_type_parse("bogus") < 0, "parse");
}

/* wvol__calloc_large gives zeros also where malloc hands back heap memory written before: its
 * blocks from 1 MiB on are whole huge pages cleared by MADV_DONTNEED, not by calloc. A 32 MiB
 * block freed first raises glibc's mmap threshold, so the later blocks come from the heap and
 * a freed, written block is the likely next one. */
static void test_calloc_large_zeroes(void)
{
    const size_t sizes[] = {4000, (size_t)1 << 20, ((size_t)3 << 20) + 12, ((size_t)9 << 20) + 4};
    void *big = malloc((size_t)32 << 20);
    int reused = 0;
    free(big);
    for (size_t k = 0; k < sizeof sizes / sizeof *sizes; k++) {
        const size_t n = sizes[k];
        size_t bytes = n, bad = 0;
        unsigned char *p = wvol__malloc_pages(&bytes), *q;
        CHECK(p != NULL, "malloc_pages %zu", n);
        if (!p) continue;
        memset(p, 0xA5, bytes);
        free(p);
        q = wvol__calloc_large(n / 4, 4);
        CHECK(q != NULL, "calloc_large %zu", n);
        if (!q) continue;
        reused += q == p;
        for (size_t i = 0; i < n / 4 * 4; i++) bad += q[i] != 0;
        CHECK(bad == 0, "calloc_large of %zu bytes: %zu bytes not zero (the block %s a freed, written one)", n,
              bad, q == p ? "is" : "is not");
        memset(q, 0x5A, n / 4 * 4);
        free(q);
    }
    printf("  calloc_large: %d of 4 blocks were a freed, written block\n", reused);
    CHECK(wvol__calloc_large(SIZE_MAX / 2, 4) == NULL, "calloc_large refuses an overflowing size");
}

/* The reuse pool's middle tier (core/alloc.h): a block of some hundred KiB given back serves the
 * next request of at least half its size, not a smaller one, and the tier stays within its bound
 * (16 blocks, 16 MiB). */
static void test_reuse_mid_tier(void)
{
    const size_t KiB = 1024;
    size_t nb, bytes, nb0, bytes0;
    unsigned char *p, *q, *r;
    wvol__reuse_held_mid(&nb0, &bytes0);
    p = wvol__reuse_get(300 * KiB);
    CHECK(p != NULL, "reuse_get(300 KiB)");
    if (!p) return;
    memset(p, 1, 300 * KiB);
    wvol__reuse_put(p);
    wvol__reuse_held_mid(&nb, &bytes);
    CHECK(nb == nb0 + 1 && bytes >= bytes0 + 300 * KiB, "a 300 KiB block given back is kept: %zu -> %zu", nb0, nb);
    r = wvol__reuse_get(100 * KiB); /* less than half of p's size: not p */
    CHECK(r != NULL && r != p, "a 100 KiB request took a 300 KiB block");
    q = wvol__reuse_get(200 * KiB); /* at least half: p again */
    CHECK(q == p, "a 200 KiB request did not get the 300 KiB block given back");
    if (q) memset(q, 2, 200 * KiB);
    wvol__reuse_put(q);
    if (r) memset(r, 3, 100 * KiB);
    wvol__reuse_put(r);
    for (int i = 0; i < 40; i++) { /* more than the bound: the oldest go */
        unsigned char *b = malloc(900 * KiB);
        CHECK(b != NULL, "malloc");
        if (!b) break;
        b[0] = b[900 * KiB - 1] = 4;
        wvol__reuse_put(b);
        wvol__reuse_held_mid(&nb, &bytes);
        CHECK(nb <= 16 && bytes <= ((size_t)16 << 20), "the tier holds %zu blocks, %zu bytes", nb, bytes);
    }
    wvol__reuse_held_mid(&nb0, &bytes0);
    wvol__reuse_put(malloc(1000)); /* small: freed */
    wvol__reuse_held_mid(&nb, &bytes);
    CHECK(nb == nb0 && bytes == bytes0, "a small block was kept: %zu -> %zu", nb0, nb);
}

/* A NULL output pointer is refused with WVOL_ERR_ARG and a message; the void setters and
 * getters given NULL do nothing, or zero their outputs. */
static void test_null_pointers(void)
{
    wvol_volume *v = NULL, *w = NULL;
    wvol_error err;
    float data[8] = {0};
    size_t n = 7;
    CHECK(wvol_volume_create(NULL, 2, 2, 2, &err) == WVOL_ERR_ARG && strstr(err.message, "output pointer"),
          "create NULL: %s", err.message);
    CHECK(wvol_volume_wrap(NULL, data, 2, 2, 2, &err) == WVOL_ERR_ARG && strstr(err.message, "output pointer"),
          "wrap NULL: %s", err.message);
    CHECK(wvol_volume_create(&v, 2, 2, 2, &err) == WVOL_OK, "create: %s", err.message);
    CHECK(wvol_volume_clone(NULL, v, &err) == WVOL_ERR_ARG && strstr(err.message, "output pointer"),
          "clone NULL: %s", err.message);
    if (v) {
        float *keep = v->data;
        v->data = NULL;
        CHECK(wvol_volume_clone(&w, v, &err) == WVOL_ERR_ARG && strstr(err.message, "no data") && !w,
              "clone of no data: %s", err.message);
        v->data = keep;
    }
    wvol_volume_destroy(v);
    CHECK(wvol_size_mul3(2, 3, 4, 4, NULL) == 0, "size_mul3 NULL out gives 0");
    CHECK(wvol_size_mul3(2, 3, 4, 4, &n) == 1 && n == 96, "size_mul3");
    CHECK(wvol_image_create(NULL, 4, 4, &err) == WVOL_ERR_ARG && strstr(err.message, "image: output pointer"),
          "image NULL: %s", err.message);
    CHECK(wvol_mesh_create(NULL, 3, 1, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "mesh: output pointer"),
          "mesh NULL: %s", err.message);
    {
        float *px = NULL;
        int wd = 0, ht = 0;
        CHECK(wvol_exr_read_channel(NULL, &wd, &ht, "x.exr", "R", &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "output pointers"),
              "exr NULL data: %s", err.message);
        CHECK(wvol_exr_read_channel(&px, NULL, &ht, "x.exr", "R", &err) == WVOL_ERR_ARG, "exr NULL width");
        CHECK(wvol_exr_read_channel(&px, &wd, NULL, "x.exr", "R", &err) == WVOL_ERR_ARG, "exr NULL height");
    }
    CHECK(wvol_atomic_open(NULL, "never.raw", &err) == WVOL_ERR_ARG && strstr(err.message, "atomic file"),
          "atomic_open NULL: %s", err.message);
    CHECK(access("never.raw", F_OK) != 0, "nothing written");
    CHECK(wvol_atomic_commit(NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "atomic file"),
          "atomic_commit NULL: %s", err.message);
    CHECK(wvol_render_method_parse(NULL, "auto", &err) == WVOL_ERR_ARG && strstr(err.message, "render: method"),
          "method parse NULL: %s", err.message);
    CHECK(wvol_render_mode_parse(NULL, "xray", &err) == WVOL_ERR_ARG && strstr(err.message, "render: mode"),
          "mode parse NULL: %s", err.message);
    CHECK(wvol_volume_create(NULL, 2, 2, 2, NULL) == WVOL_ERR_ARG, "a NULL err too");

    /* the _default functions: NULL does nothing */
    wvol_feature_params_default(NULL);
    wvol_som_params_default(NULL);
    wvol_compress_params_default(NULL);
    wvol_load_options_default(NULL);
    wvol_iso_params_default(NULL);
    wvol_iso_trace_params_default(NULL);
    wvol_iso_cast_params_default(NULL);
    wvol_lod_params_default(NULL);
    wvol_progressive_params_default(NULL);
    wvol_radiosity_params_default(NULL);
    wvol_render_params_default(NULL);
    wvol_select_params_default(NULL);
    wvol_store_params_default(NULL);
    wvol_transport_params_default(NULL);
    wvol_transport_scene_default(NULL);
    wvol_wvc_params_default(NULL);
    wvol_wvc_read_options_default(NULL);

    /* NULL handles: nothing done, outputs zeroed, values 0 or NaN */
    {
        double o[3] = {5, 5, 5}, d[3] = {5, 5, 5}, q[4] = {5, 5, 5, 5};
        const double c4[4] = {1, 2, 3, 4};
        wvol_geometry g;
        wvol_rng_seed(NULL, 1);
        CHECK(wvol_rng_next(NULL) == 0 && wvol_rng_uniform(NULL) == 0 && wvol_rng_normal(NULL) == 0, "rng NULL");
        CHECK(isnan(wvol_basis_periodised_sup(NULL, 0)) && isnan(wvol_basis_value(NULL, 0, 0.5)), "basis NULL");
        wvol_poly3_affine(NULL, c4, 1, 0);
        wvol_poly3_bernstein(NULL, c4);
        wvol_poly3_affine(q, NULL, 1, 0);
        CHECK(q[0] == 0 && q[3] == 0, "poly3_affine of NULL c zeroes out");
        q[0] = q[3] = 5;
        wvol_poly3_bernstein(q, NULL);
        CHECK(q[0] == 0 && q[3] == 0, "poly3_bernstein of NULL a zeroes bz");
        wvol_store_world_to_voxel(NULL, c4, o);
        CHECK(o[0] == 0 && o[2] == 0, "world_to_voxel of no store zeroes voxel");
        wvol_store_voxel_to_world(NULL, c4, NULL);
        d[0] = 5;
        wvol_store_dir_to_voxel(NULL, c4, d);
        CHECK(d[0] == 0 && d[2] == 0, "dir_to_voxel of no store zeroes dvoxel");
        memset(&g, 0x7f, sizeof g);
        wvol_geometry_of_coeffs(&g, NULL);
        CHECK(g.dims[0] == 0 && g.spacing[1] == 0 && g.origin[2] == 0, "geometry of no coefficients is zero");
        o[0] = d[0] = 5;
        wvol_geometry_bounds(NULL, o, d);
        CHECK(o[0] == 0 && d[0] == 0, "bounds of no geometry zeroed");
        o[0] = d[0] = 5;
        wvol_camera_ray(NULL, 0.5, 0.5, o, d);
        CHECK(o[0] == 0 && d[0] == 0 && d[2] == 0, "ray of no camera zeroed");
    }
}

/* wvol_atomic_remove_pending (a signal handler's clean-up) removes exactly the temporaries not
 * yet committed or aborted, and a writer whose temporary it removed fails at its commit. */
static void test_remove_pending(void)
{
    wvol_atomic_file a, b, c;
    wvol_error err;
    char ta[4200], tb[4200];
    CHECK(wvol_atomic_open(&a, "pending_a.txt", &err) == WVOL_OK, "open a: %s", err.message);
    CHECK(wvol_atomic_open(&b, "pending_b.txt", &err) == WVOL_OK, "open b: %s", err.message);
    CHECK(wvol_atomic_open(&c, "pending_c.txt", &err) == WVOL_OK, "open c: %s", err.message);
    snprintf(ta, sizeof ta, "%s", a.tmp_path);
    snprintf(tb, sizeof tb, "%s", b.tmp_path);
    fputs("a", a.fp);
    CHECK(wvol_atomic_commit(&a, &err) == WVOL_OK, "commit a: %s", err.message);
    wvol_atomic_abort(&c);
    CHECK(access(tb, F_OK) == 0, "b's temporary exists before");
    wvol_atomic_remove_pending();
    CHECK(access(tb, F_OK) != 0, "b's temporary removed");
    CHECK(access("pending_a.txt", F_OK) == 0 && access(ta, F_OK) != 0, "a committed, untouched");
    fputs("b", b.fp);
    CHECK(wvol_atomic_commit(&b, &err) == WVOL_ERR_IO && strstr(err.message, "pending_b.txt"),
          "b's commit fails: %s", err.message);
    CHECK(access("pending_b.txt", F_OK) != 0 && access("pending_c.txt", F_OK) != 0, "b and c not written");
    /* more temporaries than the registry's slots: every one still opens and commits */
    {
        enum { N = 80 };
        wvol_atomic_file f[N];
        char name[64];
        int ok = 1;
        for (int i = 0; i < N; i++) {
            snprintf(name, sizeof name, "pending_%d.txt", i);
            ok &= wvol_atomic_open(&f[i], name, &err) == WVOL_OK;
        }
        for (int i = 0; i < N; i++) ok &= wvol_atomic_commit(&f[i], &err) == WVOL_OK;
        for (int i = 0; i < N; i++) {
            snprintf(name, sizeof name, "pending_%d.txt", i);
            ok &= remove(name) == 0;
        }
        CHECK(ok, "80 atomic files at once");
    }
    remove("pending_a.txt");
}

int main(void)
{
    test_create_and_overflow();
    test_finite();
    test_raw_roundtrip();
    test_sample_types();
    test_calloc_large_zeroes();
    test_reuse_mid_tier();
    test_null_pointers();
    test_remove_pending();
    return check_summary("test_volume");
}
