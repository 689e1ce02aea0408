/* SPDX-License-Identifier: MIT */
/* The forward transform streamed along z (wavelet/dwt3_stream.c): bit-identical to the
 * in-memory wvol_dwt3 for every family, odd and even sizes, 1-5 levels, any slab
 * split; rows arrive in increasing z per level; the window does not grow with the
 * depth; refusals. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "wvol/source.h"
#include "wvol/wavelet.h"
#include "wvol_synth.h"

typedef struct collect {
    wvol_coeffs *c;
    size_t next[32]; /* next row expected per level */
    int order_ok;
    int fail_at_level; /* > 0: the callback fails at this level's first row */
} collect;

static wvol_status on_rows(void *user, int level, size_t r, const float *low, const float *high, wvol_error *err)
{
    collect *k = user;
    if (k->fail_at_level == level) return wvol_error_set(err, WVOL_ERR_IO, "stop at level %d", level);
    if (r != k->next[level]) k->order_ok = 0;
    k->next[level] = r + 1;
    wvol_coeffs_put_rows(k->c, level, r, low, high);
    return WVOL_OK;
}

/* A volume with structure at every scale and no symmetry: the noisy skull. */
static wvol_volume *volume(size_t nx, size_t ny, size_t nz, uint64_t seed)
{
    wvol_synth_params p;
    wvol_volume *v = NULL;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[0] = nx, p.dims[1] = ny, p.dims[2] = nz;
    p.seed = seed;
    p.noise = 30;
    CHECK(wvol_synth_make(&v, NULL, "skull", &p, &err) == WVOL_OK, "%s", err.message);
    return v;
}

/* Streams v in slabs of `slab` slices; compares every coefficient bit for bit. */
static void compare(const wvol_volume *v, const wvol_filter *f, int levels, size_t slab)
{
    wvol_coeffs *ref = NULL;
    wvol_dwt3_stream *s = NULL;
    wvol_error err;
    collect k;
    size_t n, diff = 0, first = 0;
    memset(&k, 0, sizeof k);
    k.order_ok = 1;
    CHECK(wvol_dwt3(&ref, v, f, levels, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_coeffs_create(&k.c, f, levels, v->nx, v->ny, v->nz, &err) == WVOL_OK, "%s", err.message);
    if (!ref || !k.c) goto out;
    /* poison: a coefficient never written shows up as a difference */
    n = ref->px * ref->py * ref->pz;
    for (size_t i = 0; i < n; i++) k.c->data[i] = NAN;
    CHECK(wvol_dwt3_stream_create(&s, f, levels, v->nx, v->ny, v->nz, on_rows, &k, &err) == WVOL_OK, "%s",
          err.message);
    for (size_t z0 = 0; s && z0 < v->nz; z0 += slab) {
        size_t cnt = v->nz - z0 < slab ? v->nz - z0 : slab;
        CHECK(wvol_dwt3_stream_push(s, v->data + v->nx * v->ny * z0, cnt, &err) == WVOL_OK, "%s", err.message);
    }
    CHECK(s && wvol_dwt3_stream_finish(s, &err) == WVOL_OK, "%s", s ? err.message : "no stream");
    for (size_t i = 0; i < n; i++)
        if (memcmp(&ref->data[i], &k.c->data[i], sizeof(float)) != 0) {
            if (!diff) first = i;
            diff++;
        }
    CHECK(diff == 0, "%s %zux%zux%zu, %d levels, slabs of %zu: %zu of %zu coefficients differ (first at %zu: %.9g vs %.9g)",
          f->name, v->nx, v->ny, v->nz, levels, slab, diff, n, first, ref->data[first], k.c->data[first]);
    CHECK(k.order_ok, "%s: rows out of order", f->name);
    for (int m = 1; m <= levels; m++) {
        size_t cz = ref->pz == 1 ? 1 : ref->pz >> (m - 1), rows = cz > 1 ? cz / 2 : 1;
        CHECK(k.next[m] == rows, "%s level %d: %zu rows of %zu", f->name, m, k.next[m], rows);
    }
out:
    wvol_dwt3_stream_destroy(s);
    wvol_coeffs_destroy(ref);
    wvol_coeffs_destroy(k.c);
}

static void every_family_equals_the_in_memory_transform(void)
{
    /* odd, even and non-multiple sizes, several depths, every family and 1..5 levels
     * (as many as the size allows) */
    static const size_t sizes[][3] = {{40, 36, 64}, {33, 29, 37}, {32, 32, 32}, {24, 20, 70}};
    for (int fi = 0; fi < wvol_filter_count(); fi++) {
        const wvol_filter *f = wvol_filter_at(fi);
        for (int si = 0; si < 4; si++) {
            const size_t *d = sizes[si];
            wvol_volume *v = volume(d[0], d[1], d[2], 3 + (uint64_t)si);
            int maxl = wvol_dwt_max_levels(d[0], d[1], d[2]);
            if (!v) continue;
            for (int levels = 1; levels <= 5 && levels <= maxl; levels++) {
                /* long filters on small sizes are slow: fewer combinations there */
                if (f->length > 40 && levels != 3) continue;
                compare(v, f, levels, (size_t)(1 + (levels + si) % 5) * 3);
            }
            wvol_volume_destroy(v);
        }
    }
}

static void slab_split_does_not_matter(void)
{
    const wvol_filter *f = NULL;
    wvol_error err;
    wvol_volume *v = volume(30, 26, 90, 9);
    CHECK(wvol_filter_get(&f, "coif2", &err) == WVOL_OK, "%s", err.message);
    if (v && f) {
        compare(v, f, 4, 1);
        compare(v, f, 4, 7);
        compare(v, f, 4, 90);
    }
    wvol_volume_destroy(v);
}

static void thin_and_flat_volumes(void)
{
    const wvol_filter *f = NULL;
    wvol_error err;
    wvol_volume *v2 = volume(48, 40, 1, 4), *v3 = volume(1, 40, 48, 5), *v4 = volume(36, 1, 44, 6);
    CHECK(wvol_filter_get(&f, "db3", &err) == WVOL_OK, "%s", err.message);
    if (f && v2) compare(v2, f, 3, 1); /* a 2D image: z untransformed */
    if (f && v3) compare(v3, f, 3, 5); /* x untransformed */
    if (f && v4) compare(v4, f, 2, 4); /* y untransformed */
    wvol_volume_destroy(v2);
    wvol_volume_destroy(v3);
    wvol_volume_destroy(v4);
}

static wvol_status count_rows(void *user, int level, size_t r, const float *low, const float *high, wvol_error *err)
{
    (void)level, (void)r, (void)low, (void)high, (void)err;
    (*(size_t *)user)++;
    return WVOL_OK;
}

/* The window holds a fixed number of slices per level: the same bytes at depth 512 and
 * at depth 4096 (a volume that is never made: the slices are pushed from one buffer). */
static void memory_does_not_grow_with_depth(void)
{
    const wvol_filter *f = NULL;
    wvol_error err;
    wvol_dwt3_stream *a = NULL, *b = NULL;
    size_t rows = 0;
    float *slice = calloc(64 * 48, sizeof(float));
    CHECK(wvol_filter_get(&f, "db4", &err) == WVOL_OK, "%s", err.message);
    CHECK(f && wvol_dwt3_stream_create(&a, f, 3, 64, 48, 512, count_rows, &rows, &err) == WVOL_OK, "%s", err.message);
    CHECK(f && wvol_dwt3_stream_create(&b, f, 3, 64, 48, 4096, count_rows, &rows, &err) == WVOL_OK, "%s",
          err.message);
    if (a && b) {
        CHECK(wvol_dwt3_stream_bytes(a) == wvol_dwt3_stream_bytes(b), "window %zu bytes at depth 512, %zu at 4096",
              wvol_dwt3_stream_bytes(a), wvol_dwt3_stream_bytes(b));
        /* and far below the volume: 64 x 48 x 4096 floats are 48 MiB */
        CHECK(wvol_dwt3_stream_bytes(b) < (size_t)64 * 48 * 4096 * 4 / 8, "window %zu bytes",
              wvol_dwt3_stream_bytes(b));
        for (int z = 0; z < 4096; z++) {
            wvol_status st;
            slice[0] = (float)z;
            st = wvol_dwt3_stream_push(b, slice, 1, &err);
            CHECK(st == WVOL_OK, "%s", err.message);
            if (st) break;
        }
        CHECK(wvol_dwt3_stream_finish(b, &err) == WVOL_OK, "%s", err.message);
        CHECK(rows == 2048 + 1024 + 512, "%zu rows", rows);
    }
    wvol_dwt3_stream_destroy(a);
    wvol_dwt3_stream_destroy(b);
    free(slice);
}

/* wvol_dwt3_source over a generator = wvol_dwt3 of the generated volume. */
static void source_transform_equals_in_memory(void)
{
    const wvol_filter *f = NULL;
    wvol_synth_params p;
    wvol_source *src = NULL;
    wvol_volume *v = NULL;
    wvol_coeffs *ref = NULL;
    wvol_error err;
    collect k;
    size_t bytes = 0;
    memset(&k, 0, sizeof k);
    k.order_ok = 1;
    wvol_synth_params_default(&p);
    p.dims[0] = 40, p.dims[1] = 35, p.dims[2] = 150;
    CHECK(wvol_filter_get(&f, "db2", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_synth_source(&src, "turbulence", &p, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_synth_make(&v, NULL, "turbulence", &p, &err) == WVOL_OK, "%s", err.message);
    if (!f || !src || !v) goto out;
    CHECK(wvol_dwt3(&ref, v, f, 3, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_coeffs_create(&k.c, f, 3, 40, 35, 150, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_dwt3_source(src, f, 3, on_rows, &k, &bytes, &err) == WVOL_OK, "%s", err.message);
    CHECK(ref && k.c && memcmp(ref->data, k.c->data, ref->px * ref->py * ref->pz * sizeof(float)) == 0,
          "source transform differs from the in-memory one");
    CHECK(bytes > 0, "bytes reported");
out:
    wvol_source_destroy(src);
    wvol_volume_destroy(v);
    wvol_coeffs_destroy(ref);
    wvol_coeffs_destroy(k.c);
}

static void refusals(void)
{
    const wvol_filter *f = NULL;
    wvol_error err;
    wvol_dwt3_stream *s = NULL;
    collect k;
    float buf[8 * 8 * 8];
    memset(&k, 0, sizeof k);
    memset(buf, 0, sizeof buf);
    CHECK(wvol_filter_get(&f, "haar", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_dwt3_stream_create(&s, f, 4, 8, 8, 8, on_rows, &k, &err) == WVOL_ERR_ARG && !s,
          "4 levels of an 8^3 volume refused");
    CHECK(wvol_dwt3_stream_create(&s, f, 2, 8, 8, 0, on_rows, &k, &err) == WVOL_ERR_DIMS, "empty volume refused");
    CHECK(wvol_dwt3_stream_create(&s, NULL, 2, 8, 8, 8, on_rows, &k, &err) == WVOL_ERR_ARG, "no filter refused");
    CHECK(wvol_dwt3_stream_create(&s, f, 2, 8, 8, 8, NULL, &k, &err) == WVOL_ERR_ARG, "no callback refused");
    CHECK(wvol_dwt3_stream_create(&s, f, 2, 8, 8, 8, on_rows, &k, &err) == WVOL_OK, "%s", err.message);
    if (s) {
        CHECK(wvol_dwt3_stream_finish(s, &err) == WVOL_ERR_ARG, "finish before every slice refused");
        CHECK(wvol_dwt3_stream_push(s, buf, 9, &err) == WVOL_ERR_ARG, "too many slices refused");
        k.fail_at_level = 1;
        CHECK(wvol_dwt3_stream_push(s, buf, 8, &err) == WVOL_ERR_IO && strstr(err.message, "stop at level 1"),
              "the callback's failure is returned: %s", err.message);
        CHECK(wvol_dwt3_stream_finish(s, &err) == WVOL_ERR_ARG, "a failed stream refuses to go on");
    }
    wvol_dwt3_stream_destroy(s);
    /* overflow of float32 is refused, as wvol_dwt3 refuses it */
    for (int i = 0; i < 512; i++) buf[i] = 3e38f;
    s = NULL;
    CHECK(wvol_dwt3_stream_create(&s, f, 3, 8, 8, 8, on_rows, &k, &err) == WVOL_OK, "%s", err.message);
    k.fail_at_level = 0;
    memset(k.next, 0, sizeof k.next);
    k.c = NULL;
    CHECK(s && wvol_dwt3_stream_push(s, buf, 8, &err) == WVOL_ERR_NONFINITE, "overflow refused: %s", err.message);
    wvol_dwt3_stream_destroy(s);
}

/* Slices of 4 MiB and more are transformed in smaller batches (less memory for the ring
 * and the slab): the coefficients stay the in-memory transform's, and the window of a
 * 2048^2 stream holds fewer slices than eight per batch would. */
static void large_slices_equal_the_in_memory_transform(void)
{
    const wvol_filter *f = NULL;
    wvol_dwt3_stream *s = NULL;
    wvol_error err;
    wvol_volume *v = NULL;
    size_t rows = 0;
    CHECK(wvol_filter_get(&f, "db2", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_volume_create(&v, 1024, 1024, 21, &err) == WVOL_OK, "%s", err.message);
    if (v && f) {
        /* no symmetry, every scale: a hashed value plus a ramp */
        for (size_t i = 0; i < v->nx * v->ny * v->nz; i++)
            v->data[i] = (float)(wvol_hash64(i) >> 40) * 1e-4f + (float)(i % 1031) * 0.01f;
        compare(v, f, 2, 5);
        compare(v, f, 3, 21);
    }
    wvol_volume_destroy(v);
    /* db2 at 2048^2: the level-1 window is the 2 wrap rows, a ring of L + batch and the
     * two output rows, with the last input slice and level 2's quarter-size window; with a
     * batch of 8 that is about 21 slices of 16 MiB, with 2 about 14 */
    CHECK(f && wvol_dwt3_stream_create(&s, f, 2, 2048, 2048, 64, count_rows, &rows, &err) == WVOL_OK, "%s",
          err.message);
    if (s)
        CHECK(wvol_dwt3_stream_bytes(s) < (size_t)16 * 2048 * 2048 * 4, "window of %zu bytes at 2048^2",
              wvol_dwt3_stream_bytes(s));
    wvol_dwt3_stream_destroy(s);
}

int main(void)
{
    every_family_equals_the_in_memory_transform();
    slab_split_does_not_matter();
    thin_and_flat_volumes();
    memory_does_not_grow_with_depth();
    source_transform_equals_in_memory();
    large_slices_equal_the_in_memory_transform();
    refusals();
    return check_summary("test_wavelet_stream");
}
