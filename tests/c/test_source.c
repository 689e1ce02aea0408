/* SPDX-License-Identifier: MIT */
/* Volume sources (core/source.c, io/source_file.c) and the slab writer (io/nrrd_write.c):
 * slabs read from raw and NRRD (raw, gzip, detached) files equal the same slices of the
 * whole-file readers in any order; other formats are read whole; damaged files, NaN and
 * bad ranges are refused with a message; slabs of several MiB, read and checked on several
 * threads, are the same; row bands of the sources that seek and of the generators equal the
 * same rows; the slab writer's files equal the whole-volume writers' and nothing is left when
 * a write is abandoned. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <omp.h>

#include "check.h"
#include "wvol/compress.h"
#include "wvol/io.h"
#include "wvol/source.h"
#include "wvol_synth.h"
#include "core/source_volume.h"

#define DIR_ "test_source.d"

static wvol_volume *skull(size_t nx, size_t ny, size_t nz)
{
    wvol_synth_params p;
    wvol_volume *v = NULL;
    wvol_error err;
    wvol_synth_params_default(&p);
    p.dims[0] = nx, p.dims[1] = ny, p.dims[2] = nz;
    p.noise = 10;
    CHECK(wvol_synth_make(&v, NULL, "skull", &p, &err) == WVOL_OK, "%s", err.message);
    return v;
}

/* Row bands (core/source_volume.h) equal the same rows of the volume, where the source has
 * them (expect_rows); a source without them says so and reads nothing. */
static void rows_match(wvol_source *s, const wvol_volume *v, int expect_rows, const char *what)
{
    static const size_t plan[][4] = {{0, 3, 0, 2}, {5, 4, 3, 7}, {1, 1, 0, 1}, {9, 2, 1, 16}, {2, 5, 4, 1}};
    const size_t nx = v->nx;
    float *buf = malloc(v->nx * v->ny * v->nz * sizeof *buf);
    wvol_error err;
    for (size_t i = 0; buf && i < sizeof plan / sizeof plan[0]; i++) {
        size_t z0 = plan[i][0], nz = plan[i][1], y0 = plan[i][2], ny = plan[i][3];
        wvol_status st;
        int same = 1;
        if (z0 + nz > v->nz || y0 + ny > v->ny) continue;
        st = wvol__source_read_rows(s, buf, z0, nz, y0, ny, &err);
        if (!expect_rows) {
            CHECK(st == WVOL_ERR_UNSUPPORTED, "%s: no row bands (status %d)", what, (int)st);
            break;
        }
        CHECK(st == WVOL_OK, "%s: rows %zu+%zu of slices %zu+%zu: %s", what, y0, ny, z0, nz, err.message);
        for (size_t k = 0; k < nz; k++)
            same &= memcmp(buf + k * nx * ny, v->data + nx * (v->ny * (z0 + k) + y0), nx * ny * sizeof *buf) == 0;
        CHECK(same, "%s: rows %zu+%zu of slices %zu+%zu differ", what, y0, ny, z0, nz);
    }
    if (expect_rows && buf) {
        CHECK(wvol__source_read_rows(s, buf, 0, 1, v->ny - 1, 2, &err) == WVOL_ERR_ARG, "%s: rows past the end", what);
        CHECK(wvol__source_read_rows(s, buf, v->nz - 1, 2, 0, 1, &err) == WVOL_ERR_ARG, "%s: slices past the end",
              what);
    }
    free(buf);
}

/* Reads every slab of a source in the given order of (z0, nz) and compares with v. */
static void slabs_match(wvol_source *s, const wvol_volume *v, const char *what)
{
    /* forward, then backward, then overlapping: gzip restarts for the backward reads */
    static const size_t plan[][2] = {{0, 3}, {3, 5}, {8, 1}, {20, 3}, {2, 7}, {0, 1}, {11, 12}, {22, 1}};
    size_t slice = v->nx * v->ny;
    float *buf = malloc(12 * slice * sizeof *buf);
    wvol_error err;
    for (size_t i = 0; buf && i < sizeof plan / sizeof plan[0]; i++) {
        size_t z0 = plan[i][0], nz = plan[i][1];
        if (z0 + nz > v->nz) continue;
        CHECK(wvol_source_read(s, buf, z0, nz, &err) == WVOL_OK, "%s: slab %zu+%zu: %s", what, z0, nz, err.message);
        CHECK(memcmp(buf, v->data + z0 * slice, nz * slice * sizeof *buf) == 0, "%s: slab %zu+%zu differs", what, z0,
              nz);
    }
    CHECK(wvol_source_read(s, buf, v->nz - 1, 2, &err) == WVOL_ERR_ARG, "%s: a slab past the end refused", what);
    free(buf);
}

static void file_sources_equal_whole_reads(void)
{
    wvol_volume *v = skull(21, 17, 23), *back = NULL;
    wvol_source *s = NULL;
    wvol_load_options lo;
    wvol_error err;
    const char *nrrds[] = {DIR_ "/a.nrrd", DIR_ "/b.nhdr"};
    size_t dims[3];
    double sp[3], org[3];
    if (!v) return;
    for (int gz = 0; gz < 2; gz++)
        for (int k = 0; k < 2; k++) {
            char what[64];
            snprintf(what, sizeof what, "%s %s", nrrds[k], gz ? "gzip" : "raw");
            CHECK(wvol_nrrd_write_gzip(v, nrrds[k], gz ? 6 : 0, &err) == WVOL_OK, "%s", err.message);
            CHECK(wvol_source_open(&s, nrrds[k], NULL, &err) == WVOL_OK, "%s: %s", what, err.message);
            if (!s) continue;
            CHECK(wvol_source_streams(s), "%s streams", what);
            wvol_source_geometry(s, dims, sp, org);
            CHECK(dims[0] == 21 && dims[1] == 17 && dims[2] == 23 && sp[0] == v->spacing[0] &&
                      org[2] == v->origin[2],
                  "%s: geometry", what);
            slabs_match(s, v, what);
            rows_match(s, v, !gz, what);
            wvol_source_destroy(s);
            s = NULL;
        }
    CHECK(wvol_raw_write(v, DIR_ "/c.raw", &err) == WVOL_OK, "%s", err.message);
    wvol_load_options_default(&lo);
    lo.dims[0] = 21, lo.dims[1] = 17, lo.dims[2] = 23;
    CHECK(wvol_source_open(&s, DIR_ "/c.raw", &lo, &err) == WVOL_OK, "%s", err.message);
    if (s) slabs_match(s, v, "raw");
    if (s) rows_match(s, v, 1, "raw");
    wvol_source_destroy(s);
    s = NULL;
    /* a raw file's geometry from the options: one that is not a place is refused when the source
     * is made, by the whole reader as by the streamed one */
    {
        wvol_volume *w = NULL;
        lo.spacing[1] = 0;
        CHECK(wvol_source_open(&s, DIR_ "/c.raw", &lo, &err) == WVOL_ERR_ARG && !s &&
                  strstr(err.message, "spacing[1] = 0"), "raw source with spacing 0: %s", err.message);
        lo.spacing[1] = 1;
        lo.origin[2] = NAN;
        CHECK(wvol_volume_load(&w, DIR_ "/c.raw", &lo, &err) == WVOL_ERR_ARG && !w && strstr(err.message, "origin[2]"),
              "raw volume with a NaN origin: %s", err.message);
        lo.origin[2] = 0;
    }
    /* a raw file of another sample type converts as the whole reader does */
    {
        unsigned short u[4 * 3 * 2];
        FILE *fp = fopen(DIR_ "/u.raw", "wb");
        for (int i = 0; i < 24; i++) u[i] = (unsigned short)(1000 * i + 7);
        if (fp) fwrite(u, sizeof u, 1, fp), fclose(fp);
        wvol_load_options_default(&lo);
        lo.dims[0] = 4, lo.dims[1] = 3, lo.dims[2] = 2;
        lo.raw_type = WVOL_SAMPLE_TYPE_U16;
        CHECK(wvol_raw_read(&back, DIR_ "/u.raw", &lo, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_source_open(&s, DIR_ "/u.raw", &lo, &err) == WVOL_OK, "%s", err.message);
        if (s && back) slabs_match(s, back, "uint16 raw");
        if (s && back) rows_match(s, back, 1, "uint16 raw");
        wvol_source_destroy(s);
        wvol_volume_destroy(back);
        s = NULL, back = NULL;
    }
    /* a format without slab reads is read whole (a .vti when VTK is built, else refused) */
    if (wvol_format_supported(DIR_ "/d.vti", 1) && wvol_volume_save(v, DIR_ "/d.vti", &err) == WVOL_OK) {
        CHECK(wvol_source_open(&s, DIR_ "/d.vti", NULL, &err) == WVOL_OK, "%s", err.message);
        CHECK(s && !wvol_source_streams(s), ".vti is read whole");
        if (s) slabs_match(s, v, "vti");
        if (s) rows_match(s, v, 1, "vti");
        wvol_source_destroy(s);
        s = NULL;
    }
    /* a volume in memory has row bands too */
    CHECK(wvol_source_of_volume(&s, v, &err) == WVOL_OK, "%s", err.message);
    if (s) rows_match(s, v, 1, "volume");
    wvol_source_destroy(s);
    s = NULL;
    /* the whole volume through the source */
    CHECK(wvol_source_open(&s, DIR_ "/a.nrrd", NULL, &err) == WVOL_OK, "%s", err.message);
    CHECK(s && wvol_source_read_volume(s, &back, &err) == WVOL_OK, "%s", err.message);
    CHECK(back && memcmp(back->data, v->data, wvol_volume_count(v) * sizeof(float)) == 0, "read_volume");
    wvol_source_destroy(s);
    wvol_volume_destroy(back);
    wvol_volume_destroy(v);
}

/* A generator's row bands equal the same rows of the volume it makes whole, noise included. */
static void synth_rows_equal_whole(void)
{
    const char *kinds[] = {"skull", "turbulence", "shepp-logan"};
    for (int i = 0; i < 3; i++) {
        wvol_synth_params p;
        wvol_volume *v = NULL;
        wvol_source *s = NULL;
        wvol_error err;
        wvol_synth_params_default(&p);
        p.dims[0] = 19, p.dims[1] = 17, p.dims[2] = 23;
        p.noise = 7;
        CHECK(wvol_synth_make(&v, NULL, kinds[i], &p, &err) == WVOL_OK, "%s", err.message);
        CHECK(wvol_synth_source(&s, kinds[i], &p, &err) == WVOL_OK, "%s", err.message);
        if (v && s) rows_match(s, v, 1, kinds[i]);
        wvol_source_destroy(s);
        wvol_volume_destroy(v);
    }
}

static void copy_truncated(const char *from, const char *to, long cut)
{
    FILE *a = fopen(from, "rb"), *b = fopen(to, "wb");
    long n;
    char *buf;
    if (!a || !b) {
        if (a) fclose(a);
        if (b) fclose(b);
        return;
    }
    fseek(a, 0, SEEK_END);
    n = ftell(a);
    fseek(a, 0, SEEK_SET);
    buf = malloc((size_t)n);
    if (buf && fread(buf, 1, (size_t)n, a) == (size_t)n) fwrite(buf, 1, (size_t)(n - cut), b);
    free(buf);
    fclose(a);
    fclose(b);
}

static void damaged_files_are_refused(void)
{
    wvol_volume *v = skull(16, 12, 10);
    wvol_source *s = NULL;
    wvol_load_options lo;
    wvol_error err;
    float *buf = malloc(16 * 12 * 10 * sizeof *buf);
    if (!v || !buf) goto out;
    /* raw: wrong size */
    CHECK(wvol_raw_write(v, DIR_ "/t.raw", &err) == WVOL_OK, "%s", err.message);
    wvol_load_options_default(&lo);
    lo.dims[0] = 16, lo.dims[1] = 12, lo.dims[2] = 11;
    CHECK(wvol_source_open(&s, DIR_ "/t.raw", &lo, &err) == WVOL_ERR_FORMAT && strstr(err.message, "bytes"),
          "raw of the wrong size: %s", err.message);
    /* NRRD raw: truncated data refused at open */
    CHECK(wvol_nrrd_write(v, DIR_ "/t.nrrd", &err) == WVOL_OK, "%s", err.message);
    copy_truncated(DIR_ "/t.nrrd", DIR_ "/tt.nrrd", 100);
    CHECK(wvol_source_open(&s, DIR_ "/tt.nrrd", NULL, &err) == WVOL_ERR_FORMAT && strstr(err.message, "truncated"),
          "truncated NRRD: %s", err.message);
    /* gzip: truncated data refused at the slab that runs out */
    CHECK(wvol_nrrd_write_gzip(v, DIR_ "/g.nrrd", 6, &err) == WVOL_OK, "%s", err.message);
    copy_truncated(DIR_ "/g.nrrd", DIR_ "/gt.nrrd", 200);
    CHECK(wvol_source_open(&s, DIR_ "/gt.nrrd", NULL, &err) == WVOL_OK, "%s", err.message);
    if (s) {
        wvol_status st = wvol_source_read(s, buf, 0, 10, &err);
        CHECK(st == WVOL_ERR_FORMAT && (strstr(err.message, "truncated") || strstr(err.message, "corrupt")),
              "truncated gzip: %d %s", (int)st, err.message);
    }
    wvol_source_destroy(s);
    s = NULL;
    /* NaN: refused naming the voxel in the whole volume's indices */
    v->data[5 + 16 * (7 + 12 * 8)] = NAN;
    CHECK(wvol_nrrd_write(v, DIR_ "/n.nrrd", &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_source_open(&s, DIR_ "/n.nrrd", NULL, &err) == WVOL_OK, "%s", err.message);
    CHECK(s && wvol_source_read(s, buf, 0, 8, &err) == WVOL_OK, "slices before the NaN read");
    CHECK(s && wvol_source_read(s, buf, 6, 4, &err) == WVOL_ERR_NONFINITE && strstr(err.message, "i=5, j=7, k=8"),
          "NaN named: %s", err.message);
    /* the same in a row band: rows 5 .. 8 of slices 7 .. 8, the voxel in the volume's indices */
    CHECK(s && wvol__source_read_rows(s, buf, 7, 2, 5, 4, &err) == WVOL_ERR_NONFINITE &&
              strstr(err.message, "i=5, j=7, k=8"),
          "NaN named in a row band: %s", err.message);
    CHECK(s && wvol__source_read_rows(s, buf, 7, 2, 0, 5, &err) == WVOL_OK, "rows before the NaN's read");
    wvol_source_destroy(s);
    s = NULL;
    CHECK(wvol_source_open(&s, DIR_ "/none.nrrd", NULL, &err) == WVOL_ERR_IO, "missing file refused");
out:
    free(buf);
    wvol_volume_destroy(v);
}

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

static void slab_writer_writes_what_the_volume_writers_write(void)
{
    wvol_volume *v = skull(19, 13, 11), *back = NULL;
    wvol_slab_writer *w = NULL;
    wvol_error err;
    size_t dims[3] = {19, 13, 11}, slice = 19 * 13;
    const char *paths[] = {DIR_ "/w.raw", DIR_ "/w.nrrd", DIR_ "/w.nhdr", DIR_ "/wg.nrrd"};
    if (!v) return;
    for (int k = 0; k < 4; k++) {
        unsigned long long bytes = 0;
        remove(paths[k]); /* from an earlier run */
        CHECK(wvol_slab_writer_open(&w, paths[k], dims, v->spacing, v->origin, k == 3 ? 4 : 0, &err) == WVOL_OK, "%s",
              err.message);
        CHECK(!exists(paths[k]), "%s: nothing under the name before commit", paths[k]);
        for (size_t z = 0; w && z < 11; z += 4)
            CHECK(wvol_slab_writer_put(w, v->data + z * slice, z + 4 <= 11 ? 4 : 11 - z, &err) == WVOL_OK, "%s",
                  err.message);
        CHECK(w && wvol_slab_writer_commit(w, &bytes, &err) == WVOL_OK, "%s", err.message);
        w = NULL;
        if (k == 0) {
            wvol_load_options lo;
            wvol_load_options_default(&lo);
            memcpy(lo.dims, dims, sizeof dims);
            CHECK(wvol_raw_read(&back, paths[k], &lo, &err) == WVOL_OK, "%s", err.message);
            CHECK(bytes == 19 * 13 * 11 * 4, "raw bytes %llu", bytes);
        } else {
            CHECK(wvol_nrrd_read(&back, paths[k], &err) == WVOL_OK, "%s", err.message);
            CHECK(back && back->spacing[1] == v->spacing[1] && back->origin[0] == v->origin[0], "%s: geometry",
                  paths[k]);
        }
        CHECK(back && memcmp(back->data, v->data, wvol_volume_count(v) * sizeof(float)) == 0, "%s: samples", paths[k]);
        wvol_volume_destroy(back);
        back = NULL;
    }
    /* missing slices: refused at commit, no file; abort: no file */
    CHECK(wvol_slab_writer_open(&w, DIR_ "/x.nhdr", dims, NULL, NULL, 0, &err) == WVOL_OK, "%s", err.message);
    CHECK(w && wvol_slab_writer_put(w, v->data, 10, &err) == WVOL_OK, "%s", err.message);
    CHECK(w && wvol_slab_writer_put(w, v->data, 2, &err) == WVOL_ERR_ARG, "slices past the end refused");
    CHECK(w && wvol_slab_writer_commit(w, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "10 of 11"),
          "incomplete volume refused: %s", err.message);
    CHECK(!exists(DIR_ "/x.nhdr") && !exists(DIR_ "/x.raw"), "nothing left of an incomplete volume");
    CHECK(wvol_slab_writer_open(&w, DIR_ "/y.nrrd", dims, NULL, NULL, 3, &err) == WVOL_OK, "%s", err.message);
    wvol_slab_writer_abort(w);
    CHECK(!exists(DIR_ "/y.nrrd"), "nothing left after abort");
    CHECK(wvol_slab_writer_open(&w, DIR_ "/y.vti", dims, NULL, NULL, 0, &err) == WVOL_ERR_UNSUPPORTED,
          "slab writes only raw and NRRD");
    CHECK(wvol_slab_writer_open(&w, DIR_ "/y.raw", dims, NULL, NULL, 3, &err) == WVOL_ERR_ARG, "no gzip raw");
    wvol_volume_destroy(v);
}

/* A raw float32 file whose slabs are large enough (4 MiB) to be read in parts on several
 * threads (io/source_file.c) and checked the same way (core/source.c): the same values, the
 * range a compression reports, and a NaN or Inf in any part refused with its voxel named. */
static void large_slabs_read_on_threads(void)
{
    const size_t nx = 128, ny = 96, nz = 110, slice = nx * ny;
    wvol_volume *v = skull(nx, ny, nz);
    float *buf = malloc(nz * slice * sizeof *buf);
    wvol_load_options lo;
    wvol_error err;
    const int before = omp_get_max_threads();
    double vmin, vmax;
    if (!v || !buf) {
        CHECK(0, "out of memory");
        goto out;
    }
    wvol_volume_range(v, &vmin, &vmax, NULL);
    CHECK(wvol_raw_write(v, DIR_ "/big.raw", &err) == WVOL_OK, "%s", err.message);
    wvol_load_options_default(&lo);
    lo.dims[0] = nx, lo.dims[1] = ny, lo.dims[2] = nz;
    for (int threads = 1; threads <= 3; threads++) {
        static const size_t plan[][2] = {{0, 110}, {7, 100}, {0, 90}, {30, 80}};
        wvol_source *s = NULL;
        wvol_compress_params cp;
        wvol_compress_stream_report rep;
        omp_set_num_threads(threads);
        CHECK(wvol_source_open(&s, DIR_ "/big.raw", &lo, &err) == WVOL_OK, "%s", err.message);
        for (size_t i = 0; s && i < sizeof plan / sizeof plan[0]; i++) {
            size_t z0 = plan[i][0], n = plan[i][1];
            memset(buf, 0, n * slice * sizeof *buf);
            CHECK(wvol_source_read(s, buf, z0, n, &err) == WVOL_OK, "%d threads, slab %zu+%zu: %s", threads, z0, n,
                  err.message);
            CHECK(memcmp(buf, v->data + z0 * slice, n * slice * sizeof *buf) == 0, "%d threads: slab %zu+%zu differs",
                  threads, z0, n);
        }
        wvol_compress_params_default(&cp);
        cp.for_file = 1;
        cp.quant.psnr = 40;
        CHECK(s && wvol_compress_stream(DIR_ "/big.wvc", s, &cp, &rep, &err) == WVOL_OK, "%s", err.message);
        CHECK(rep.value_min == vmin && rep.value_max == vmax, "%d threads: range %g..%g, the volume's %g..%g", threads,
              rep.value_min, rep.value_max, vmin, vmax);
        wvol_source_destroy(s);
        s = NULL;
        /* a NaN near the start, an Inf in the last part: the voxel named */
        for (int k = 0; k < 2; k++) {
            size_t at = k ? (nz - 2) * slice + 5 * nx + 9 : 3 * slice + 2;
            float keep = v->data[at];
            FILE *fp;
            v->data[at] = k ? INFINITY : NAN;
            fp = fopen(DIR_ "/bad.raw", "wb");
            if (fp) fwrite(v->data, sizeof(float), nz * slice, fp), fclose(fp);
            v->data[at] = keep;
            CHECK(wvol_source_open(&s, DIR_ "/bad.raw", &lo, &err) == WVOL_OK, "%s", err.message);
            if (s) {
                char want[64];
                snprintf(want, sizeof want, "(i=%zu, j=%zu, k=%zu)", at % nx, (at % slice) / nx, at / slice);
                CHECK(wvol_source_read(s, buf, 0, nz, &err) == WVOL_ERR_NONFINITE && strstr(err.message, want) &&
                          strstr(err.message, k ? "Inf" : "NaN"),
                      "%d threads: %s refused at %s: %s", threads, k ? "Inf" : "NaN", want, err.message);
            }
            wvol_source_destroy(s);
            s = NULL;
        }
    }
    omp_set_num_threads(before);
out:
    free(buf);
    wvol_volume_destroy(v);
}

/* A user's read callback that fails without a message: the source names itself and the slab. */
static wvol_status silent_failure(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err)
{
    (void)ctx, (void)dst, (void)z0, (void)nz, (void)err;
    return WVOL_ERR_IO;
}

static void silent_callback_failure_gets_a_message(void)
{
    static const wvol_source_ops ops = {silent_failure, NULL};
    const size_t dims[3] = {4, 4, 8};
    wvol_source *s = NULL;
    wvol_error err;
    float buf[4 * 4 * 3];
    CHECK(wvol_source_create(&s, dims, NULL, NULL, "mine", 1, &ops, NULL, &err) == WVOL_OK, "%s", err.message);
    if (!s) return;
    wvol_error_set(&err, WVOL_ERR_ARG, "an earlier message");
    CHECK(wvol_source_read(s, buf, 2, 3, &err) == WVOL_ERR_IO && err.status == WVOL_ERR_IO &&
              strstr(err.message, "mine: read of slices 2..4 failed (status"),
          "generic message: %s", err.message);
    CHECK(wvol_source_read(s, buf, 2, 3, NULL) == WVOL_ERR_IO, "no err: the status alone");
    wvol_source_destroy(s);
}

int main(void)
{
    mkdir(DIR_, 0755);
    silent_callback_failure_gets_a_message();
    file_sources_equal_whole_reads();
    synth_rows_equal_whole();
    large_slabs_read_on_threads();
    damaged_files_are_refused();
    slab_writer_writes_what_the_volume_writers_write();
    return check_summary("test_source");
}
