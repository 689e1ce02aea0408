/* SPDX-License-Identifier: MIT
 * Tests of the renderer (libwvol/src/render) and the image files (libwvol/src/io/image_*.c). */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "fixtures.h"
#include "render/reference_internal.h"
#include "wvol/image.h"
#include "wvol/render.h"
#include "wvol/volume.h"

/* The paper's Gaussian density, exp(-r^2 / (2 sigma^2)) about the centre, sigma = n/6. */
static double gaussian_at(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    size_t nx = v->nx, ny = v->ny, nz = v->nz;
    double x = (i - (nx - 1) / 2.0) / (nx / 6.0), y = (j - (ny - 1) / 2.0) / (ny / 6.0),
           z = (k - (nz - 1) / 2.0) / (nz / 6.0);
    (void)ctx;
    return (float)exp(-0.5 * (x * x + y * y + z * z));
}

static wvol_volume *gaussian(size_t nx, size_t ny, size_t nz)
{
    return fixture_volume(nx, ny, nz, gaussian_at, NULL);
}

static int image_finite(const wvol_image *img)
{
    size_t i, n = (size_t)img->width * img->height * 4;
    for (i = 0; i < n; i++)
        if (!isfinite(img->rgba[i])) return 0;
    return 1;
}

static void camera_description_is_parsed_and_checked(void)
{
    wvol_geometry g = {{32, 16, 8}, {1, 2, 0.5}, {10, 20, 30}};
    wvol_camera cam;
    wvol_error err;
    double o[3], d[3];
    CHECK(wvol_camera_parse(&cam, "+z", &g, 32, 32, &err) == WVOL_OK, "%s", err.message);
    CHECK(cam.projection == WVOL_PROJECTION_ORTHOGRAPHIC, "ortho by default");
    /* from +z: looking along -z, right = +x, up = +y; the box is 32 x 32 world units */
    CHECK_NEAR(cam.view_height, 32.0, 1e-12, "framed height");
    wvol_camera_ray(&cam, 0.5, 0.5, o, d);
    CHECK_NEAR(d[2], -1.0, 1e-12, "direction");
    CHECK_NEAR(o[0], 10.0, 1e-9, "first pixel centre on voxel 0 (x)");
    CHECK_NEAR(o[1], 20.0 + 15.5 * 2.0 - 0.5, 1e-9, "first pixel centre half a pixel below the top (y)");
    CHECK(wvol_camera_parse(&cam, "persp fov=40 dir=1,1,0.5 zoom=2", &g, 64, 48, &err) == WVOL_OK, "%s", err.message);
    CHECK(cam.projection == WVOL_PROJECTION_PERSPECTIVE && cam.fov_y < 40, "perspective, zoomed");
    CHECK(wvol_camera_parse(&cam, "persp eye=100,100,100 center=26,35,32 up=0,0,1", &g, 64, 48, &err) == WVOL_OK,
          "%s", err.message);
    CHECK(wvol_camera_parse(&cam, "+w", &g, 8, 8, &err) == WVOL_ERR_ARG && strstr(err.message, "+w"), "%s",
          err.message);
    CHECK(wvol_camera_parse(&cam, "persp fov=190", &g, 8, 8, &err) == WVOL_ERR_ARG && strstr(err.message, "fov"), "%s",
          err.message);
    CHECK(wvol_camera_parse(&cam, "dir=0,0,0", &g, 8, 8, &err) == WVOL_ERR_ARG && strstr(err.message, "zero"), "%s",
          err.message);
    CHECK(wvol_camera_parse(&cam, "eye=1,2 center=0,0,0", &g, 8, 8, &err) == WVOL_ERR_ARG, "%s", err.message);
    CHECK(wvol_camera_parse(&cam, "eye=0,0,5 center=0,0,0 up=0,0,1", &g, 8, 8, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "parallel"),
          "%s", err.message);
    CHECK(wvol_camera_parse(&cam, "+z", &g, 0, 8, &err) == WVOL_ERR_ARG, "%s", err.message);
    CHECK(wvol_camera_parse(&cam, "+z height=-1", &g, 8, 8, &err) == WVOL_ERR_ARG, "%s", err.message);
    /* positions far out are refused as such (their squared distances would overflow), not as an
     * eye at the centre; directions of any finite length keep their direction */
    CHECK(wvol_camera_parse(&cam, "persp eye=1e308,0,0", &g, 8, 8, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "eye='1e308,0,0' lies beyond") && !strstr(err.message, "coincide"),
          "%s", err.message);
    CHECK(wvol_camera_parse(&cam, "eye=3,3,3 center=3,3,3", &g, 8, 8, &err) == WVOL_ERR_ARG &&
              strstr(err.message, "coincide"),
          "%s", err.message);
    CHECK(wvol_camera_parse(&cam, "ortho dir=1e300,0,0", &g, 8, 8, &err) == WVOL_OK, "%s", err.message);
    {
        wvol_camera ref;
        CHECK(wvol_camera_parse(&ref, "ortho dir=1,0,0", &g, 8, 8, &err) == WVOL_OK, "%s", err.message);
        for (int a = 0; a < 3; a++)
            CHECK_NEAR(cam.eye[a], ref.eye[a], 1e-9 * (1 + fabs(ref.eye[a])), "dir=1e300,0,0 frames as dir=1,0,0");
        CHECK(wvol_camera_parse(&cam, "persp eye=100,100,100 center=26,35,32 up=0,0,1e200", &g, 8, 8, &err) ==
                  WVOL_OK,
              "a long up vector: %s", err.message);
        cam.eye[0] = 1e200;
        CHECK(wvol_camera_check(&cam, &err) == WVOL_ERR_ARG && strstr(err.message, "within"), "%s", err.message);
    }
    {
        const double dir[3] = {0, 0, -1};
        CHECK(wvol_camera_frame(&cam, &g, dir, WVOL_PROJECTION_PERSPECTIVE, 8, 8, NAN, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "field of view"),
              "NaN fov: %s", err.message);
        CHECK(wvol_camera_frame(&cam, &g, dir, WVOL_PROJECTION_PERSPECTIVE, 8, 8, INFINITY, &err) == WVOL_ERR_ARG,
              "infinite fov: %s", err.message);
        CHECK(wvol_camera_frame(&cam, &g, dir, WVOL_PROJECTION_PERSPECTIVE, 8, 8, 0, &err) == WVOL_OK &&
                  cam.fov_y == 30,
              "fov 0: the default: %s", err.message);
    }
}

static void transfer_functions_parse_and_refuse_bad_input(void)
{
    wvol_tf tf;
    wvol_error err;
    double rgb[3], k;
    CHECK(wvol_tf_parse(&tf, "# comment\nunits diagonal\n0 0 0 1 0\n1 1 0.5 0 2  # end\n", "t", &err) == WVOL_OK,
          "%s", err.message);
    CHECK(tf.count == 2 && tf.per_diagonal == 1, "two points, per diagonal");
    wvol_tf_eval(&tf, 0.5, rgb, &k);
    CHECK_NEAR(k, 1.0, 1e-15, "kappa halfway");
    CHECK_NEAR(rgb[1], 0.25, 1e-15, "green halfway");
    wvol_tf_eval(&tf, -5, rgb, &k);
    CHECK(k == 0 && rgb[2] == 1, "clamped below");
    CHECK(wvol_tf_parse(&tf, "{\"units\": \"world\", \"points\": [[0, 0,0,0, 0], [10, 1,1,1, 0.5]]}", "j", &err) ==
              WVOL_OK,
          "%s", err.message);
    CHECK(tf.count == 2 && !tf.per_diagonal && tf.points[1].opacity == 0.5, "json");
    CHECK(wvol_tf_parse(&tf, "1 0 0 0 0\n0 1 1 1 1\n", "t", &err) == WVOL_ERR_ARG && strstr(err.message, "increase"),
          "%s", err.message);
    CHECK(wvol_tf_parse(&tf, "0 0 0 0 -1\n", "t", &err) == WVOL_ERR_ARG && strstr(err.message, "opacity"), "%s",
          err.message);
    CHECK(wvol_tf_parse(&tf, "0 0 0 0\n", "t.txt", &err) == WVOL_ERR_FORMAT && strstr(err.message, "t.txt:1"), "%s",
          err.message);
    CHECK(wvol_tf_parse(&tf, "0 0 0 0 nan\n", "t", &err) == WVOL_ERR_ARG && strstr(err.message, "non-finite"),
          "NaN refused: %s", err.message);
    CHECK(wvol_tf_parse(&tf, "{\"points\": [[0,1,2]]}", "j", &err) == WVOL_ERR_FORMAT, "%s", err.message);
    CHECK(wvol_tf_parse(&tf, "", "e", &err) == WVOL_ERR_FORMAT && strstr(err.message, "no points"), "%s", err.message);
    CHECK(wvol_tf_preset(&tf, "ct-bone", 0, 0, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_preset(&tf, "gaussian", 0, 1, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_tf_preset(&tf, "nope", 0, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "nope"), "%s", err.message);
    CHECK(wvol_tf_preset(&tf, "gaussian", 2, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "data range"),
          "vmin > vmax: %s", err.message);
    CHECK(wvol_tf_preset(&tf, "ct-bone", 0, NAN, &err) == WVOL_ERR_ARG && strstr(err.message, "data range"),
          "NaN vmax: %s", err.message);
    CHECK(wvol_tf_preset(&tf, "grey", -INFINITY, 1, &err) == WVOL_ERR_ARG && strstr(err.message, "data range"),
          "infinite vmin: %s", err.message);
}

/* Files in the current folder whose names start with prefix and hold ".tmp-" (a writer's
 * temporaries), removed when remove_them (a run killed before this one may have left some). */
static int temporaries(const char *prefix, int remove_them)
{
    int n = 0;
    struct dirent *e;
    DIR *d = opendir(".");
    if (!d) return -1;
    while ((e = readdir(d)))
        if (!strncmp(e->d_name, prefix, strlen(prefix)) && strstr(e->d_name, ".tmp-")) {
            n++;
            if (remove_them) remove(e->d_name);
        }
    closedir(d);
    return n;
}

static void image_files_round_trip(void)
{
    wvol_image *img = NULL;
    wvol_error err;
    float *z, *back = NULL;
    int w = 0, h = 0, i;
    char path[] = "render_test_img.exr";
    CHECK(wvol_image_create(&img, 37, 21, &err) == WVOL_OK, "%s", err.message);
    if (!img) return;
    z = malloc(37 * 21 * sizeof *z);
    for (i = 0; i < 37 * 21; i++) {
        img->rgba[4 * i] = (float)i * 0.25f;
        img->rgba[4 * i + 3] = 1.0f / (1 + i);
        z[i] = (float)(1000 - i);
    }
    CHECK(wvol_image_write_exr(img, path, z, &err) == WVOL_OK, "%s", err.message);
    CHECK(wvol_exr_read_channel(&back, &w, &h, path, "R", &err) == WVOL_OK, "%s", err.message);
    if (back) {
        int same = w == 37 && h == 21;
        for (i = 0; same && i < 37 * 21; i++) same = back[i] == img->rgba[4 * i];
        CHECK(same, "R channel round trip");
        free(back);
        back = NULL;
    }
    CHECK(wvol_exr_read_channel(&back, &w, &h, path, "Z", &err) == WVOL_OK && back && back[5] == 995.0f, "Z channel");
    free(back);
    back = NULL;
    CHECK(wvol_exr_read_channel(&back, &w, &h, path, "Q", &err) == WVOL_ERR_FORMAT && strstr(err.message, "'Q'"), "%s",
          err.message);
    CHECK(wvol_exr_read_channel(&back, &w, &h, "no_such_file.exr", "R", &err) == WVOL_ERR_IO &&
              strstr(err.message, "no_such_file.exr"), "missing file: %s", err.message);
    CHECK(wvol_image_write_png(img, "render_test_img.png", NULL, 1.0, &err) == WVOL_OK, "%s", err.message);
    CHECK(access("render_test_img.png", F_OK) == 0, "png written");
    CHECK(wvol_image_write_exr(img, "no_such_dir/x.exr", NULL, &err) == WVOL_ERR_IO, "%s", err.message);
    CHECK(wvol_image_write_png(img, "no_such_dir/x.png", NULL, 1.0, &err) == WVOL_ERR_IO, "%s", err.message);
    {
        const double bad_exposure[3] = {NAN, -1, INFINITY};
        const float nan_back[3] = {0, NAN, 0};
        for (i = 0; i < 3; i++)
            CHECK(wvol_image_write_png(img, "render_test_bad.png", NULL, bad_exposure[i], &err) == WVOL_ERR_ARG &&
                      strstr(err.message, "exposure"),
                  "exposure %g: %s", bad_exposure[i], err.message);
        CHECK(wvol_image_write_png(img, "render_test_bad.png", nan_back, 1.0, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "background[1]"),
              "NaN background: %s", err.message);
        CHECK(access("render_test_bad.png", F_OK) != 0, "nothing written");
    }
    CHECK_NEAR(wvol_linear_to_srgb(0.5), 0.735356983052, 1e-9, "sRGB of 0.5");
    CHECK_NEAR(wvol_linear_to_srgb(0.002), 0.02584, 1e-9, "sRGB linear segment");
    remove(path);
    remove("render_test_img.png");
    free(z);
    wvol_image_destroy(img);
}

/* A write that fails (here a file size limit: EFBIG, as a full disk gives ENOSPC) is an error
 * naming its cause, the previous file stays and no temporary is left; in a child process
 * under an alarm: OpenEXR reports a failure in its header holding its context's lock, and an
 * error handler that takes the lock again would hang. */
static void image_writes_that_fail(void)
{
    const char *exr = "render_test_full.exr", *png = "render_test_full.png";
    wvol_image *img = NULL;
    wvol_error err;
    pid_t pid;
    int status = 0;
    CHECK(wvol_image_create(&img, 64, 48, &err) == WVOL_OK, "%s", err.message);
    if (!img) return;
    temporaries("render_test_full.", 1);
    for (int i = 0; i < 64 * 48 * 4; i++) img->rgba[i] = (float)((i * 7919) % 1000) / 1000.0f; /* incompressible */
    fflush(NULL);
    pid = fork();
    if (pid == 0) {
        struct rlimit lim = {100, 100};
        int bad = 0;
        FILE *fp;
        char old[8] = {0};
        for (int k = 0; k < 2; k++) {
            const char *path = k ? png : exr;
            wvol_status st;
            fp = fopen(path, "w");
            if (!fp || fputs("old", fp) == EOF || fclose(fp) != 0) _exit(64);
            signal(SIGXFSZ, SIG_IGN);
            if (setrlimit(RLIMIT_FSIZE, &lim) != 0) _exit(65);
            alarm(60);
            st = k ? wvol_image_write_png(img, path, NULL, 1.0, &err) : wvol_image_write_exr(img, path, NULL, &err);
            if (st != WVOL_ERR_IO) bad |= 1 << (3 * k);
            else if (!strstr(err.message, path) || !strstr(err.message, strerror(EFBIG))) {
                fprintf(stderr, "message: %s\n", err.message);
                bad |= 2 << (3 * k);
            }
            fp = fopen(path, "r");
            if (!fp || !fgets(old, sizeof old, fp) || strcmp(old, "old") != 0) bad |= 4 << (3 * k);
            if (fp) fclose(fp);
            remove(path);
        }
        _exit(bad);
    }
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid, "fork and wait");
    CHECK(WIFEXITED(status), "the writes returned (signal %d: SIGALRM means a hang)",
          WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0,
          "failed writes: exit %d (bits 0/3: not an I/O error (EXR/PNG), 1/4: message without the path or cause, "
          "2/5: the old file changed)",
          WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    CHECK(temporaries("render_test_full.", 1) == 0, "no temporary left");
    wvol_image_destroy(img);
}

/* Along an axis through voxel centres, trilinear interpolation clamped to the edge
 * integrates over the cell box to exactly sum(f) * spacing (midpoint rule with knots
 * on step boundaries). */
static void reference_xray_along_axis_sums_voxels(void)
{
    wvol_volume *v = gaussian(12, 10, 9);
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_error err;
    double maxrel = 0, dir[3] = {0, 0, -1};
    size_t i, j, k;
    double sp[3] = {0.5, 0.5, 1.3}, org[3] = {-3, 2, 5};
    if (!v) return;
    wvol_volume_set_geometry(v, sp, org, NULL);
    wvol_geometry_of_volume(&g, v);
    CHECK(wvol_camera_frame(&cam, &g, dir, WVOL_PROJECTION_ORTHOGRAPHIC, 12, 10, 0, &err) == WVOL_OK, "%s", err.message);
    wvol_image_create(&img, 12, 10, NULL);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    p.step = 0.5 / 0.5 * 1.3 / 2; /* step in smallest spacing: half a voxel along z */
    CHECK(wvol_render_reference(img, v, &cam, NULL, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    for (j = 0; j < 10; j++)
        for (i = 0; i < 12; i++) {
            double s = 0, got = img->rgba[4 * (i + 12 * (9 - j))];
            for (k = 0; k < 9; k++) s += v->data[i + 12 * (j + 10 * k)];
            s *= 1.3;
            if (fabs(got - s) / s > maxrel) maxrel = fabs(got - s) / s;
        }
    CHECK(maxrel < 1e-6, "reference X-ray = sum * spacing: max relative error %g", maxrel);
    wvol_image_destroy(img);
    wvol_volume_destroy(v);
}

static void empty_space_skipping_changes_nothing_on(int noisy)
{
    wvol_volume *v = gaussian(40, 40, noisy ? 24 : 40);
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_render_stats st;
    wvol_tf tf;
    wvol_error err;
    size_t i;
    if (!v) return;
    for (i = 0; i < wvol_volume_count(v); i++)
        if (v->data[i] < 0.3f) v->data[i] = 0; /* empty space around the blob */
    if (noisy) {
        /* CT-like: noise of +-0.05 everywhere (a hash of the index), anisotropic slices, so
         * empty bricks hold values on both sides of 0 and only the TF's zero range (kappa 0
         * below 0: the preset's first point is at 0) makes them empty */
        const double sp[3] = {1, 1, 1.7}, org[3] = {0, 0, 0};
        for (i = 0; i < wvol_volume_count(v); i++) {
            uint64_t h = (uint64_t)(i + 1) * 0x9E3779B97F4A7C15ull;
            h ^= h >> 31;
            h *= 0xBF58476D1CE4E5B9ull;
            h ^= h >> 29;
            v->data[i] += (float)(0.1 * ((double)(h >> 11) / 9007199254740992.0 - 0.5) - (v->data[i] == 0 ? 0.05 : 0));
        }
        CHECK(wvol_volume_set_geometry(v, sp, org, &err) == WVOL_OK, "%s", err.message);
    }
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&cam, "persp dir=1,0.7,0.4", &g, 48, 40, NULL);
    wvol_image_create(&a, 48, 40, NULL);
    wvol_image_create(&b, 48, 40, NULL);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    wvol_render_params_default(&p);
    p.reference.brick = 4;
    CHECK(wvol_render_reference(a, v, &cam, &tf, &p, &st, &err) == WVOL_OK, "%s", err.message);
    CHECK(st.skipped > 0, "some bricks skipped (%zu)", st.skipped);
    p.reference.brick = 0;
    CHECK(wvol_render_reference(b, v, &cam, &tf, &p, NULL, &err) == WVOL_OK, "%s", err.message);
    /* a skipped brick is one whose samples all add nothing (zero opacity): the same samples are
     * taken elsewhere, so the image is the same, bit for bit */
    CHECK(memcmp(a->rgba, b->rgba, (size_t)48 * 40 * 4 * sizeof *a->rgba) == 0, "skipping (noisy %d): rmse %g", noisy,
          wvol_image_rmse(a, b, -1, 0));
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_volume_destroy(v);
}

/* The reference's min/max grid skips without changing the image: on a blob in empty space,
 * and on a noisy, anisotropic one whose empty bricks are empty only through the TF (noise
 * below its first point). */
static void empty_space_skipping_changes_nothing(void)
{
    empty_space_skipping_changes_nothing_on(0);
    empty_space_skipping_changes_nothing_on(1);
}

/* Rays that miss, graze an edge or a corner, start inside, run parallel to a face; opacity
 * so high that transmittance underflows; an empty volume: no NaN anywhere. */
static void degenerate_rays_give_no_nan(void)
{
    wvol_volume *v = gaussian(16, 16, 16), *e = NULL;
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_tf tf, hot;
    wvol_error err;
    const char *specs[] = {"+z",  "+z height=100",           "dir=1,1,1",
                           "ortho eye=-0.5,-0.5,40 center=-0.5,-0.5,0 up=0,1,0 height=1",
                           "ortho eye=-0.5,7,40 center=-0.5,7,0 up=0,1,0 height=2", /* along a face */
                           "persp eye=7.5,7.5,7.5 center=0,0,0 fov=120",              /* inside */
                           "persp eye=100,100,100 center=200,200,200 fov=10"};        /* looks away */
    int s, m;
    if (!v) return;
    wvol_volume_create(&e, 16, 16, 16, NULL);
    wvol_geometry_of_volume(&g, v);
    wvol_image_create(&img, 24, 24, NULL);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    wvol_tf_parse(&hot, "0 1 1 1 1e30\n1 1 1 1 1e300\n", "hot", NULL);
    for (s = 0; s < (int)(sizeof specs / sizeof *specs); s++)
        for (m = 0; m < 3; m++) {
            const wvol_tf *tfs[2] = {&tf, &hot};
            int t;
            CHECK(wvol_camera_parse(&cam, specs[s], &g, 24, 24, &err) == WVOL_OK, "%s: %s", specs[s], err.message);
            for (t = 0; t < 2; t++) {
                wvol_render_params_default(&p);
                p.mode = (wvol_render_mode)m;
                p.termination = t ? 0 : 1e-6;
                CHECK(wvol_render_reference(img, v, &cam, tfs[t], &p, NULL, &err) == WVOL_OK, "%s", err.message);
                CHECK(image_finite(img), "finite image: camera '%s' mode %d tf %d", specs[s], m, t);
                CHECK(wvol_render_reference(img, e, &cam, tfs[t], &p, NULL, &err) == WVOL_OK, "%s", err.message);
                CHECK(image_finite(img), "finite image of an empty volume: camera '%s' mode %d", specs[s], m);
            }
        }
    /* a bad image size is refused */
    wvol_camera_parse(&cam, "+z", &g, 8, 8, NULL);
    CHECK(wvol_render_reference(img, v, &cam, &tf, NULL, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "24x24"),
          "%s", err.message);
    /* shading is a flag: another value is refused */
    wvol_camera_parse(&cam, "+z", &g, 24, 24, NULL);
    wvol_render_params_default(&p);
    p.shading = 7;
    CHECK(wvol_render_reference(img, v, &cam, &tf, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "shading 7"),
          "shading 7: %s", err.message);
    wvol_image_destroy(img);
    wvol_volume_destroy(v);
    wvol_volume_destroy(e);
}

/* Reference convergence: halving the step changes the absorption image less and less. */
static void reference_converges_with_step(void)
{
    wvol_volume *v = gaussian(24, 24, 24);
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img[3] = {NULL, NULL, NULL};
    wvol_render_params p;
    wvol_tf tf;
    double steps[3] = {0.5, 0.25, 0.125}, e1, e2;
    int i;
    if (!v) return;
    wvol_geometry_of_volume(&g, v);
    wvol_camera_parse(&cam, "persp dir=0.3,1,0.2", &g, 32, 32, NULL);
    wvol_tf_preset(&tf, "gaussian", 0, 1, NULL);
    wvol_render_params_default(&p);
    for (i = 0; i < 3; i++) {
        wvol_image_create(&img[i], 32, 32, NULL);
        p.step = steps[i];
        wvol_render_reference(img[i], v, &cam, &tf, &p, NULL, NULL);
    }
    e1 = wvol_image_rmse(img[0], img[2], -1, 1);
    e2 = wvol_image_rmse(img[1], img[2], -1, 1);
    CHECK(e2 < e1 && e1 < 1e-2, "step refinement: %g then %g", e1, e2);
    for (i = 0; i < 3; i++) wvol_image_destroy(img[i]);
    wvol_volume_destroy(v);
}

/* Random voxel values in [-0.2, 1.2): every transfer-function segment, and values beyond
 * the end points, along every ray. */
static double noise_at(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)v, (void)i, (void)j, (void)k;
    return -0.2 + 1.4 * fixture_urand((uint64_t *)ctx);
}

/* The blocked inner loop (runs of samples strictly inside a brick, 8 at a time, render/ref_samples.h)
 * against the sample-by-sample path, which a colour volume forces (its nearest-voxel lookup
 * is per sample). Odd sizes, oblique and perspective rays (runs of every length, blocks cut
 * short), transfer functions of several segments (the per-block segment test and its
 * fallback), opacity high enough to terminate rays inside a block, both absorption modes
 * (the linear one with clamps), bricks of 3 and 8 voxels.
 * - A coloured TF: the blocked loop composites sample by sample with the per-sample path's
 *   arithmetic, so the transmittance, and the alpha channel, must be equal bit for bit (the
 *   colours differ: the colour volume replaces the TF's).
 * - A white TF and a uniform white colour volume: the same colours. Absorption-linear must
 *   be equal bit for bit in every channel; absorption takes the one-colour shortcut (one
 *   exponential per block, T_0 exp(-dt sum kappa), colour c (T_0 - T_8)), the same integral
 *   rounded differently: a few ulp of double, at most an ulp of the float pixel, or a
 *   termination one sample apart when T meets the threshold within those ulps, which moves
 *   the pixel by less than the threshold (1e-6): 2e-6 bounds both, while a wrong block
 *   (a lane counted twice or missed: ~1e-2 of a pixel at these opacities) exceeds it. */
static void blocked_loop_equals_per_sample_path(void)
{
    uint64_t seed = 0x5eed1234abcdull;
    wvol_volume *v = fixture_volume(37, 29, 23, noise_at, &seed);
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_params p;
    wvol_tf tf;
    wvol_error err;
    float *white;
    size_t nvox = 37 * 29 * 23, i;
    const char *specs[] = {"+z", "dir=1,0.7,0.4", "persp dir=-0.3,1,0.2 fov=40"};
    const double opacity[2] = {1, 400}; /* per diagonal: faint, and opaque enough to terminate */
    int s, m, o, brick, coloured;
    if (!v) return;
    white = malloc(3 * nvox * sizeof *white);
    if (!white) {
        wvol_volume_destroy(v);
        return;
    }
    for (i = 0; i < 3 * nvox; i++) white[i] = 1.0f;
    wvol_geometry_of_volume(&g, v);
    wvol_image_create(&a, 41, 33, NULL);
    wvol_image_create(&b, 41, 33, NULL);
    for (coloured = 0; coloured < 2; coloured++)
        for (o = 0; o < 2; o++) {
            char text[256];
            if (coloured)
                /* opaque below its first point: the values below 0 take the first point's kappa */
                snprintf(text, sizeof text, "units diagonal\n0 1 0 0 %g\n0.25 0 1 0 %g\n0.5 0 0 1 %g\n1 1 1 0 %g\n",
                         0.3 * opacity[o], 0.5 * opacity[o], 0.1 * opacity[o], opacity[o]);
            else
                snprintf(text, sizeof text, "units diagonal\n0 1 1 1 0\n0.25 1 1 1 %g\n0.5 1 1 1 %g\n1 1 1 1 %g\n",
                         0.5 * opacity[o], 0.1 * opacity[o], opacity[o]);
            CHECK(wvol_tf_parse(&tf, text, "test", &err) == WVOL_OK, "%s", err.message);
            for (s = 0; s < 3; s++)
                for (m = WVOL_RENDER_MODE_ABSORPTION; m <= WVOL_RENDER_MODE_ABSORPTION_LINEAR; m++)
                    for (brick = 3; brick <= 8; brick += 5) {
                        wvol_render_stats sa, sb;
                        size_t diff = 0;
                        double worst = 0;
                        int exact = coloured || m == WVOL_RENDER_MODE_ABSORPTION_LINEAR;
                        CHECK(wvol_camera_parse(&cam, specs[s], &g, 41, 33, &err) == WVOL_OK, "%s", err.message);
                        wvol_render_params_default(&p);
                        p.mode = (wvol_render_mode)m;
                        p.reference.brick = brick;
                        p.step = 0.37;
                        CHECK(wvol_render_reference(a, v, &cam, &tf, &p, &sa, &err) == WVOL_OK, "%s", err.message);
                        p.colors = white;
                        p.colors_count = 3 * nvox;
                        CHECK(wvol_render_reference(b, v, &cam, &tf, &p, &sb, &err) == WVOL_OK, "%s", err.message);
                        for (i = 0; i < (size_t)41 * 33 * 4; i++) {
                            double dv = fabs((double)a->rgba[i] - (double)b->rgba[i]);
                            if (coloured && i % 4 != 3) continue; /* the colour volume's colours */
                            diff += dv != 0;
                            if (dv > worst) worst = dv;
                        }
                        if (exact)
                            CHECK(diff == 0, "blocked vs per sample: %zu channels differ ('%s', mode %d, opacity %g, %s TF)",
                                  diff, specs[s], m, opacity[o], coloured ? "coloured" : "white");
                        else
                            CHECK(worst <= 2e-6, "blocked (one colour) vs per sample: %.3g apart ('%s', opacity %g)",
                                  worst, specs[s], opacity[o]);
                        CHECK(sa.samples == sb.samples && sa.clamped == sb.clamped &&
                                  (exact ? sa.terminated == sb.terminated
                                         : (sa.terminated > sb.terminated ? sa.terminated - sb.terminated
                                                                          : sb.terminated - sa.terminated) <= 2),
                              "same counts: samples %zu/%zu terminated %zu/%zu clamped %zu/%zu", sa.samples,
                              sb.samples, sa.terminated, sb.terminated, sa.clamped, sb.clamped);
                        if (o == 1 && s == 0) CHECK(sa.terminated > 0, "opaque TF terminates rays (%zu)", sa.terminated);
                    }
        }
    free(white);
    wvol_image_destroy(a);
    wvol_image_destroy(b);
    wvol_volume_destroy(v);
}

/* wvol__cam_box_pixels: every pixel outside its rectangle misses the volume (the bricked walk
 * skips those pixels' rays untested), for perspective and orthographic cameras, framed,
 * zoomed in (the volume beyond the image), grazing, from inside the volume and from beside a
 * face, on a non-square image; and for a framed perspective view it leaves pixels out. */
static void camera_box_pixels_hold_every_hit(void)
{
    wvol_geometry g = {{40, 30, 20}, {1, 1, 1.5}, {-20, -15, -15}};
    const char *specs[] = {"persp dir=1,0.7,0.4", "persp dir=1,0.7,0.4 zoom=3", "persp dir=0,0,1",
                           "ortho dir=0.3,1,-0.5", "ortho dir=0,1,0 zoom=0.5", "persp eye=0,0,0 center=1,0.2,0.1",
                           "persp eye=-20.6,0,0 center=1,0,0", "persp eye=-21,14.7,0 center=20,14.7,0"};
    double lo[3], hi[3];
    size_t left_out_framed = 0;
    wvol_geometry_bounds(&g, lo, hi);
    for (size_t c = 0; c < sizeof specs / sizeof *specs; c++) {
        wvol_camera cam;
        wvol__cam k;
        wvol_error err;
        int r[4];
        size_t hits = 0, misses_outside = 0, hits_outside = 0;
        if (wvol_camera_parse(&cam, specs[c], &g, 90, 70, &err) != WVOL_OK) {
            CHECK(0, "%s: %s", specs[c], err.message);
            continue;
        }
        wvol__cam_init(&k, &cam);
        wvol__cam_box_pixels(&k, lo, hi, r);
        CHECK(r[0] >= 0 && r[1] >= 0 && r[2] <= 90 && r[3] <= 70 && r[0] <= r[2] && r[1] <= r[3],
              "%s: rectangle %d %d %d %d outside the image", specs[c], r[0], r[1], r[2], r[3]);
        for (int y = 0; y < 70; y++)
            for (int x = 0; x < 90; x++) {
                double o[3], d[3], t0, t1;
                const int hit = pixel_span(&k, lo, hi, x, y, o, d, &t0, &t1);
                const int in = x >= r[0] && x < r[2] && y >= r[1] && y < r[3];
                hits += (size_t)hit;
                if (!in) {
                    hits_outside += (size_t)hit;
                    misses_outside += (size_t)!hit;
                }
            }
        CHECK(hits_outside == 0, "%s: %zu pixels outside the rectangle %d %d %d %d meet the volume", specs[c],
              hits_outside, r[0], r[1], r[2], r[3]);
        CHECK(hits > 0, "%s: no pixel meets the volume (nothing checked)", specs[c]);
        if (c == 0) left_out_framed = misses_outside;
    }
    CHECK(left_out_framed > 1000, "framed perspective view: only %zu pixels left out", left_out_framed);
}

int main(void)
{
    camera_description_is_parsed_and_checked();
    camera_box_pixels_hold_every_hit();
    transfer_functions_parse_and_refuse_bad_input();
    image_files_round_trip();
    image_writes_that_fail();
    reference_xray_along_axis_sums_voxels();
    empty_space_skipping_changes_nothing();
    degenerate_rays_give_no_nan();
    reference_converges_with_step();
    blocked_loop_equals_per_sample_path();
    return check_summary("test_render");
}
