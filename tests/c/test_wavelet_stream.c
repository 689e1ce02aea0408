/* SPDX-License-Identifier: MIT */
/* The forward transform streamed along z (wavelet/dwt3_stream.c): bit-identical to the
 * in-memory wvol_dwt3 for every family, odd and even sizes, 1-5 levels, any slab
 * split; rows arrive in increasing z per level; the window does not grow with the
 * depth; rows made in the caller's memory (wvol_dwt3_stream_set_place); rows seen piece by
 * piece as the threads make them (wvol_dwt3_stream_set_pieces); refusals. */
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

/* Data far from 0 against its spread (a skull in HU + 1e6: the first slice's midrange is more
 * than 64 times its spread): both transforms take the offset out of the samples and put it into
 * the low-pass band the same way, bit for bit, every family, thin volumes too (a low-pass band
 * of one coefficient); and the inverse gives the samples back to float32's rounding at their
 * magnitude, where without the offset taken out float32 lost every detail (9 dB). */
static void data_on_an_offset(void)
{
    static const size_t sizes[][3] = {{33, 29, 37}, {32, 32, 32}, {24, 20, 1}};
    for (int fi = 0; fi < wvol_filter_count(); fi++) {
        const wvol_filter *f = wvol_filter_at(fi);
        for (int si = 0; si < 3; si++) {
            const size_t *d = sizes[si];
            wvol_volume *v = volume(d[0], d[1], d[2], 11 + (uint64_t)si), *r = NULL;
            wvol_coeffs *c = NULL;
            wvol_error err;
            int levels = wvol_dwt_max_levels(d[0], d[1], d[2]);
            double sse = 0, lo = INFINITY, hi = -INFINITY, ulp;
            if (!v) continue;
            levels = levels < 3 ? levels : 3;
            if (f->length > 40) levels = 1; /* long filters on small sizes are slow */
            for (size_t i = 0; i < wvol_volume_count(v); i++) {
                v->data[i] = (float)(0.001 * v->data[i] + 1e6); /* HU / 1000 on 1e6: spread ~3, 3e5 x */
                lo = fmin(lo, v->data[i]), hi = fmax(hi, v->data[i]);
            }
            compare(v, f, levels, 5);
            CHECK(wvol_dwt3(&c, v, f, levels, &err) == WVOL_OK && wvol_idwt3(&r, c, &err) == WVOL_OK, "%s: %s",
                  f->name, err.message);
            for (size_t i = 0; r && i < wvol_volume_count(v); i++)
                sse += ((double)r->data[i] - v->data[i]) * ((double)r->data[i] - v->data[i]);
            /* what float32 must round: the samples at 1e6 (spacing 1/16, variance s^2 / 12) and
             * the low-pass band, the offset times the gain 2^(d L / 2) (d transformed axes; a
             * coefficient off by up to half its spacing, one per 2^(d L) samples); bl3's
             * truncated taps reconstruct imperfectly, about 1e-6 of the offset */
            {
                const int dims = (d[0] > 1) + (d[1] > 1) + (d[2] > 1);
                const double low = 1e6 * pow(2.0, 0.5 * dims * levels), s_low = ldexp(1.0, ilogb(low) - 23);
                ulp = sqrt(0.0625 * 0.0625 / 12 + 0.25 * s_low * s_low / pow(2.0, dims * levels));
            }
            CHECK(r && sqrt(sse / (double)wvol_volume_count(v)) <= (f->length > 40 ? 4.0 : 1.5) * ulp,
                  "%s %zux%zux%zu, %d levels: round trip RMSE %g (spread %g at 1e6)", f->name, d[0], d[1], d[2],
                  levels, r ? sqrt(sse / (double)wvol_volume_count(v)) : -1.0, hi - lo);
            wvol_coeffs_destroy(c);
            wvol_volume_destroy(r);
            wvol_volume_destroy(v);
        }
    }
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

/* Rows made in the caller's memory: a pyramid laid out level by level, each row's room
 * 2 cx cy floats (cx cy when z is not transformed). */
typedef struct placed {
    collect k;
    float *data;
    size_t at[32], row[32], rows[32], plane[32];
    int in_room; /* every callback's planes were the room given for the row */
    size_t null_at; /* > 0: the room of level 1's row null_at - 1 is NULL */
} placed;

static float *place(void *user, int level, size_t r)
{
    placed *p = user;
    if (p->null_at && level == 1 && r + 1 == p->null_at) return NULL;
    return r < p->rows[level] ? p->data + p->at[level] + r * p->row[level] : NULL;
}

static wvol_status on_placed(void *user, int level, size_t r, const float *low, const float *high, wvol_error *err)
{
    placed *p = user;
    const float *room = p->data + p->at[level] + r * p->row[level];
    if (low != room || high != (p->row[level] > p->plane[level] ? room + p->plane[level] : NULL)) p->in_room = 0;
    return on_rows(&p->k, level, r, low, high, err);
}

static void placed_rows_equal_the_in_memory_transform(void)
{
    static const size_t sizes[][3] = {{40, 36, 64}, {33, 29, 37}, {48, 40, 1}};
    const wvol_filter *f = NULL;
    wvol_error err;
    CHECK(wvol_filter_get(&f, "coif2", &err) == WVOL_OK, "%s", err.message);
    for (int si = 0; f && si < 3; si++) {
        const size_t *d = sizes[si];
        const int levels = 3;
        wvol_volume *v = volume(d[0], d[1], d[2], 11 + (uint64_t)si);
        wvol_coeffs *ref = NULL, *again = NULL;
        wvol_dwt3_stream *s = NULL;
        placed p;
        size_t total = 0, n;
        memset(&p, 0, sizeof p);
        p.in_room = 1;
        if (!v) continue;
        CHECK(wvol_dwt3(&ref, v, f, levels, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_coeffs_create(&p.k.c, f, levels, v->nx, v->ny, v->nz, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_coeffs_create(&again, f, levels, v->nx, v->ny, v->nz, &err) == WVOL_OK, "%s", err.message);
        if (!ref || !p.k.c || !again) goto next;
        for (int m = 1; m <= levels; m++) {
            size_t cx = ref->px >> (m - 1), cy = ref->py >> (m - 1), cz = ref->pz == 1 ? 1 : ref->pz >> (m - 1);
            p.plane[m] = cx * cy;
            p.row[m] = cz > 1 ? 2 * cx * cy : cx * cy;
            p.rows[m] = cz > 1 ? cz / 2 : 1;
            p.at[m] = total;
            total += p.rows[m] * p.row[m];
        }
        p.data = malloc(total * sizeof(float));
        CHECK(p.data != NULL, "room for the pyramid");
        if (!p.data) goto next;
        CHECK(wvol_dwt3_stream_create(&s, f, levels, v->nx, v->ny, v->nz, on_placed, &p, &err) == WVOL_OK, "%s",
              err.message);
        CHECK(s && wvol_dwt3_stream_set_place(s, place, &err) == WVOL_OK, "%s", err.message);
        CHECK(s && wvol_dwt3_stream_push(s, v->data, v->nz, &err) == WVOL_OK, "%s", err.message);
        CHECK(s && wvol_dwt3_stream_set_place(s, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "first slice"),
              "placing rows after the first slice refused: %s", err.message);
        CHECK(s && wvol_dwt3_stream_finish(s, &err) == WVOL_OK, "%s", err.message);
        CHECK(p.in_room, "%zux%zux%zu: the callback's planes are the rooms given", d[0], d[1], d[2]);
        n = ref->px * ref->py * ref->pz;
        CHECK(memcmp(ref->data, p.k.c->data, n * sizeof(float)) == 0, "%zux%zux%zu: placed rows differ", d[0], d[1],
              d[2]);
        /* the rooms still hold every row after the run: the pyramid is kept as it was made */
        for (int m = 1; m <= levels; m++)
            for (size_t r = 0; r < p.rows[m]; r++) {
                const float *room = p.data + p.at[m] + r * p.row[m];
                wvol_coeffs_put_rows(again, m, r, room, p.row[m] > p.plane[m] ? room + p.plane[m] : NULL);
            }
        CHECK(memcmp(ref->data, again->data, n * sizeof(float)) == 0, "%zux%zux%zu: the kept rooms differ", d[0],
              d[1], d[2]);
        /* a NULL room stops the transform with the row named */
        wvol_dwt3_stream_destroy(s);
        s = NULL;
        p.null_at = 3;
        CHECK(wvol_dwt3_stream_create(&s, f, levels, v->nx, v->ny, v->nz, on_placed, &p, &err) == WVOL_OK, "%s",
              err.message);
        CHECK(s && wvol_dwt3_stream_set_place(s, place, &err) == WVOL_OK, "%s", err.message);
        if (s && p.rows[1] >= 3) {
            wvol_status st = wvol_dwt3_stream_push(s, v->data, v->nz, &err);
            if (!st) st = wvol_dwt3_stream_finish(s, &err);
            CHECK(st == WVOL_ERR_ARG && strstr(err.message, "row 2 of level 1"), "NULL room refused: %s",
                  err.message);
        }
    next:
        wvol_dwt3_stream_destroy(s);
        free(p.data);
        wvol_coeffs_destroy(ref);
        wvol_coeffs_destroy(again);
        wvol_coeffs_destroy(p.k.c);
        wvol_volume_destroy(v);
    }
}

/* Pieces (wvol_dwt3_stream_set_pieces): copied where they belong and counted per plane row;
 * at each row's callback every plane row of it was seen exactly once, with the row's values. */
typedef struct pieces {
    collect k;
    size_t cx[32], cy[32];
    unsigned *cover[32]; /* rows x cy */
    float *lo[32], *hi[32]; /* rows x cx cy */
    int once, same, calls;
} pieces;

static void on_piece(void *user, int level, size_t r, size_t y0, size_t y1, const float *low, const float *high)
{
    pieces *p = user;
    const size_t cx = p->cx[level], cy = p->cy[level];
    for (size_t y = y0; y < y1; y++) __atomic_fetch_add(&p->cover[level][r * cy + y], 1u, __ATOMIC_RELAXED);
    memcpy(p->lo[level] + (r * cy + y0) * cx, low, (y1 - y0) * cx * sizeof(float));
    if (high) memcpy(p->hi[level] + (r * cy + y0) * cx, high, (y1 - y0) * cx * sizeof(float));
    __atomic_fetch_add(&p->calls, 1, __ATOMIC_RELAXED);
}

static wvol_status on_piece_rows(void *user, int level, size_t r, const float *low, const float *high,
                                 wvol_error *err)
{
    pieces *p = user;
    const size_t cx = p->cx[level], cy = p->cy[level];
    for (size_t y = 0; y < cy; y++)
        if (p->cover[level][r * cy + y] != 1) p->once = 0;
    if (memcmp(p->lo[level] + r * cy * cx, low, cx * cy * sizeof(float)) != 0 ||
        (high && memcmp(p->hi[level] + r * cy * cx, high, cx * cy * sizeof(float)) != 0))
        p->same = 0;
    return on_rows(&p->k, level, r, low, high, err);
}

static void pieces_cover_every_row_once(void)
{
    /* 256 x 160: a level-1 plane large enough for the z pass's threads */
    static const size_t sizes[][3] = {{256, 160, 20}, {33, 29, 37}, {48, 40, 1}};
    const wvol_filter *f = NULL;
    wvol_error err;
    CHECK(wvol_filter_get(&f, "db2", &err) == WVOL_OK, "%s", err.message);
    for (int si = 0; f && si < 3; si++) {
        const size_t *d = sizes[si];
        const int levels = 2;
        wvol_volume *v = volume(d[0], d[1], d[2], 21 + (uint64_t)si);
        wvol_coeffs *ref = NULL;
        wvol_dwt3_stream *s = NULL;
        pieces p;
        int room = 1;
        memset(&p, 0, sizeof p);
        p.once = p.same = 1;
        if (!v) continue;
        CHECK(wvol_dwt3(&ref, v, f, levels, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_coeffs_create(&p.k.c, f, levels, v->nx, v->ny, v->nz, &err) == WVOL_OK, "%s", err.message);
        if (!ref || !p.k.c) goto next;
        for (int m = 1; m <= levels; m++) {
            size_t cz = ref->pz == 1 ? 1 : ref->pz >> (m - 1), rows = cz > 1 ? cz / 2 : 1;
            p.cx[m] = ref->px >> (m - 1), p.cy[m] = ref->py >> (m - 1);
            p.cover[m] = calloc(rows * p.cy[m], sizeof(unsigned));
            p.lo[m] = calloc(rows * p.cx[m] * p.cy[m], sizeof(float));
            p.hi[m] = calloc(rows * p.cx[m] * p.cy[m], sizeof(float));
            room &= p.cover[m] && p.lo[m] && p.hi[m];
        }
        CHECK(room, "out of memory");
        if (!room) goto next;
        CHECK(wvol_dwt3_stream_create(&s, f, levels, v->nx, v->ny, v->nz, on_piece_rows, &p, &err) == WVOL_OK, "%s",
              err.message);
        CHECK(s && wvol_dwt3_stream_set_pieces(s, on_piece, &err) == WVOL_OK, "%s", err.message);
        CHECK(s && wvol_dwt3_stream_push(s, v->data, v->nz, &err) == WVOL_OK, "%s", err.message);
        CHECK(s && wvol_dwt3_stream_set_pieces(s, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "first slice"),
              "pieces asked for after the first slice refused: %s", err.message);
        CHECK(s && wvol_dwt3_stream_finish(s, &err) == WVOL_OK, "%s", err.message);
        CHECK(p.once, "%zux%zux%zu: every plane row seen exactly once before its row's callback", d[0], d[1], d[2]);
        CHECK(p.same, "%zux%zux%zu: the pieces hold the row's values", d[0], d[1], d[2]);
        CHECK(p.calls > 0 && (d[0] < 256 || p.calls > 2 * (int)(ref->pz / 2)),
              "%zux%zux%zu: %d pieces (a large plane comes in several)", d[0], d[1], d[2], p.calls);
        CHECK(memcmp(ref->data, p.k.c->data, ref->px * ref->py * ref->pz * sizeof(float)) == 0,
              "%zux%zux%zu: rows with pieces differ", d[0], d[1], d[2]);
    next:
        wvol_dwt3_stream_destroy(s);
        for (int m = 1; m <= levels; m++) {
            free(p.cover[m]);
            free(p.lo[m]);
            free(p.hi[m]);
        }
        wvol_coeffs_destroy(ref);
        wvol_coeffs_destroy(p.k.c);
        wvol_volume_destroy(v);
    }
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
    data_on_an_offset();
    thin_and_flat_volumes();
    memory_does_not_grow_with_depth();
    source_transform_equals_in_memory();
    large_slices_equal_the_in_memory_transform();
    placed_rows_equal_the_in_memory_transform();
    pieces_cover_every_row_once();
    refusals();
    return check_summary("test_wavelet_stream");
}
