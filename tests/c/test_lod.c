/* SPDX-License-Identifier: MIT
 * Level of detail by screen size (wvol/lod.h, libwvol/src/pipeline/lod.c) and a store's
 * coarser level (wvol_store_level_volume, libwvol/src/store/level.c): the level choice for
 * orthographic and perspective cameras with its clamps; a coarse-level frame is the frame of
 * the coarse decode (wvol_idwt3_level); the reported extra error is the dropped levels'
 * energy; level of detail off gives wvol_render's image bit for bit; a file-backed store's
 * level decodes only the chunks of the levels kept; bad levels are refused with a message. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/iso.h"
#include "wvol/lod.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wvc.h"

static wvol_geometry cube_geometry(size_t n, double spacing)
{
    wvol_geometry g;
    for (int a = 0; a < 3; a++) g.dims[a] = n, g.spacing[a] = spacing, g.origin[a] = 0.0;
    return g;
}

static wvol_camera ortho(double view_height, int pixels)
{
    wvol_camera c;
    memset(&c, 0, sizeof c);
    c.projection = WVOL_PROJECTION_ORTHOGRAPHIC;
    c.width = c.height = pixels;
    c.eye[0] = 32, c.eye[1] = 32, c.eye[2] = -100;
    c.center[0] = 32, c.center[1] = 32, c.center[2] = 32;
    c.up[1] = 1;
    c.view_height = view_height;
    return c;
}

static void level_choice_orthographic(void)
{
    wvol_geometry g = cube_geometry(64, 1.0);
    wvol_camera c;
    double fp;
    /* footprint = view_height / height; level L while 2^L voxels <= footprint */
    c = ortho(64, 64);
    CHECK(wvol_lod_level(&c, &g, 4, &fp) == 0 && fabs(fp - 1.0) < 1e-12, "1 voxel per pixel: level 0 (fp %g)", fp);
    c = ortho(64, 33);
    CHECK(wvol_lod_level(&c, &g, 4, &fp) == 0, "a footprint just under 2 voxels stays at level 0 (fp %g)", fp);
    c = ortho(64, 32);
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 1, "2 voxels per pixel: level 1");
    c = ortho(64, 16);
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 2, "4 voxels per pixel: level 2");
    c = ortho(64, 9);
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 2, "7.1 voxels per pixel: level 2");
    c = ortho(64, 1);
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 4, "clamped at the levels available (4)");
    CHECK(wvol_lod_level(&c, &g, 0, NULL) == 0, "no levels: level 0");
    CHECK(wvol_lod_level(&c, &g, -3, NULL) == 0, "negative levels read as 0");
    c = ortho(64, 256);
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 0, "pixels smaller than voxels: level 0");
    /* the largest spacing of a transformed axis decides; a 1-voxel axis does not */
    g.spacing[2] = 3.0;
    c = ortho(64, 32);
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 0, "an axis of spacing 3 keeps a 2-unit footprint at level 0");
    g.dims[2] = 1;
    CHECK(wvol_lod_level(&c, &g, 4, NULL) == 1, "a 1-voxel axis's spacing does not count");
}

static void level_choice_perspective(void)
{
    wvol_geometry g = cube_geometry(64, 1.0);
    wvol_camera c;
    double fp, lo[3], hi[3], d, want;
    wvol_error err;
    memset(&c, 0, sizeof c);
    c.projection = WVOL_PROJECTION_PERSPECTIVE;
    c.width = c.height = 32;
    c.fov_y = 30;
    c.center[0] = c.center[1] = c.center[2] = 31.5;
    c.eye[0] = 31.5, c.eye[1] = 31.5, c.eye[2] = -300;
    c.up[1] = 1;
    CHECK(wvol_camera_check(&c, &err) == WVOL_OK, "camera: %s", err.message);
    wvol_geometry_bounds(&g, lo, hi);
    d = lo[2] - c.eye[2]; /* the nearest point is on the face z = lo */
    want = 2.0 * d * tan(15.0 * 3.14159265358979323846 / 180.0) / 32.0;
    {
        int L = wvol_lod_level(&c, &g, 5, &fp), wantL = (int)floor(log2(want));
        CHECK_NEAR(fp, want, 1e-9 * want, "perspective footprint at the nearest point");
        CHECK(L == wantL, "perspective level %d, expected %d (footprint %g)", L, wantL, fp);
    }
    /* off-axis: the nearest point is a corner region; the distance is Euclidean */
    c.eye[0] = -200, c.eye[1] = -100, c.eye[2] = -300;
    wvol_lod_level(&c, &g, 5, &fp);
    d = sqrt((lo[0] + 200) * (lo[0] + 200) + (lo[1] + 100) * (lo[1] + 100) + (lo[2] + 300) * (lo[2] + 300));
    CHECK_NEAR(fp, 2.0 * d * tan(15.0 * 3.14159265358979323846 / 180.0) / 32.0, 1e-9 * fp, "corner distance");
    /* the eye inside the volume sees voxels at distance 0: full resolution */
    c.eye[0] = 10, c.eye[1] = 10, c.eye[2] = 10;
    CHECK(wvol_lod_level(&c, &g, 5, &fp) == 0 && fp == 0, "eye inside: level 0 (fp %g)", fp);
    /* far away: clamped at the levels */
    c.eye[0] = 31.5, c.eye[1] = 31.5, c.eye[2] = -1e7;
    CHECK(wvol_lod_level(&c, &g, 3, NULL) == 3, "far camera clamps at the levels");
}

/* The phantom, its coefficients and the store of all of them. */
typedef struct fixture {
    wvol_volume *v;
    wvol_coeffs *c;
    wvol_store *s;
    double vmin, vmax;
} fixture;

static int fixture_make(fixture *f, size_t n, int levels)
{
    wvol_error err;
    memset(f, 0, sizeof *f);
    f->v = fixture_volume(n, n - 6, n + 4, fixture_shell_blob, NULL);
    if (!f->v) return 0;
    wvol_volume_range(f->v, &f->vmin, &f->vmax, NULL);
    CHECK(wvol_dwt3(&f->c, f->v, fixture_filter("db2"), levels, &err) == WVOL_OK, "dwt: %s", err.message);
    CHECK(f->c && wvol_store_build(&f->s, f->c, NULL, NULL, &err) == WVOL_OK, "store: %s", err.message);
    return f->s != NULL;
}

static void fixture_free(fixture *f)
{
    wvol_store_destroy(f->s);
    wvol_coeffs_destroy(f->c);
    wvol_volume_destroy(f->v);
}

/* Largest |a - b| over the volumes, -1 when the grids differ (dims, spacing, origin). */
static double volume_diff(const wvol_volume *a, const wvol_volume *b)
{
    double m = 0;
    size_t n;
    if (!a || !b || a->nx != b->nx || a->ny != b->ny || a->nz != b->nz) return -1;
    for (int k = 0; k < 3; k++)
        if (fabs(a->spacing[k] - b->spacing[k]) > 1e-12 || fabs(a->origin[k] - b->origin[k]) > 1e-12) return -1;
    n = wvol_volume_count(a);
    for (size_t i = 0; i < n; i++) m = fmax(m, fabs((double)a->data[i] - b->data[i]));
    return m;
}

/* Sum c^2 of the detail bands of levels 1..L, straight from the pyramid. */
static double detail_energy(const wvol_coeffs *c, int L)
{
    double e = 0;
    for (int m = 1; m <= L; m++)
        for (int band = 1; band < 8; band++)
            for (size_t r = 0; r < (c->pz >> m); r++)
                for (size_t q = 0; q < (c->py >> m); q++)
                    for (size_t p = 0; p < (c->px >> m); p++) {
                        size_t i = wvol_coeffs_index(c, m, band, p, q, r);
                        if (i != (size_t)-1) e += (double)c->data[i] * c->data[i];
                    }
    return e;
}

static void store_level_is_the_coarse_decode(void)
{
    fixture f;
    wvol_error err;
    if (!fixture_make(&f, 40, 3)) return fixture_free(&f);
    for (int L = 0; L <= 3; L++) {
        wvol_volume *a = NULL, *b = NULL, *d = NULL;
        double e = -1, ed = -1, tol = 1e-5 * (f.vmax - f.vmin), diff;
        CHECK(wvol_store_level_volume(&a, f.s, L, &err) == WVOL_OK, "store level %d: %s", L, err.message);
        CHECK(wvol_idwt3_level(&b, f.c, L, &err) == WVOL_OK, "idwt3_level %d: %s", L, err.message);
        diff = volume_diff(a, b);
        /* float rounding of two inverse transforms of the same coefficients */
        CHECK(diff >= 0 && diff <= tol, "level %d: store's coarse volume vs wvol_idwt3_level: %g (tol %g)", L, diff,
              tol);
        CHECK(wvol_store_level_energy(f.s, L, &e, &err) == WVOL_OK, "energy: %s", err.message);
        CHECK_NEAR(e, detail_energy(f.c, L), 1e-9 * (1 + e), "store level energy = sum c^2 of levels 1..L");
        wvol_volume_destroy(b);
        b = NULL;
        /* a dense volume's level: the transform of L levels (its own padding), then the level */
        if (L > 0) {
            wvol_coeffs *cl = NULL;
            CHECK(wvol_dwt3(&cl, f.v, fixture_filter("db2"), L, &err) == WVOL_OK, "dwt %d", L);
            CHECK(cl && wvol_idwt3_level(&b, cl, L, &err) == WVOL_OK, "idwt3_level");
            CHECK(wvol_volume_level(&d, f.v, fixture_filter("db2"), L, &ed, &err) == WVOL_OK, "volume level: %s",
                  err.message);
            diff = volume_diff(d, b);
            CHECK(diff >= 0 && diff <= 0, "level %d: wvol_volume_level vs idwt3_level(dwt3): %g", L, diff);
            CHECK(cl && fabs(ed - detail_energy(cl, L)) <= 1e-6 * (1 + ed), "volume level energy %g vs %g", ed,
                  cl ? detail_energy(cl, L) : 0.0);
            wvol_coeffs_destroy(cl);
        }
        wvol_volume_destroy(a), wvol_volume_destroy(b), wvol_volume_destroy(d);
    }
    {
        /* bad levels are refused with a message naming the range */
        wvol_volume *a = NULL;
        double e;
        CHECK(wvol_store_level_volume(&a, f.s, -1, &err) == WVOL_ERR_ARG && strstr(err.message, "0..3") && !a,
              "level -1 refused: %s", err.message);
        CHECK(wvol_store_level_volume(&a, f.s, 4, &err) == WVOL_ERR_ARG && strstr(err.message, "0..3") && !a,
              "level 4 of 3 refused: %s", err.message);
        CHECK(wvol_store_level_energy(f.s, 4, &e, &err) == WVOL_ERR_ARG, "energy of level 4 refused");
        CHECK(wvol_volume_level(&a, f.v, fixture_filter("db2"), -2, NULL, &err) == WVOL_ERR_ARG && !a,
              "volume level -2 refused: %s", err.message);
        CHECK(wvol_volume_level(&a, f.v, fixture_filter("db2"), 40, NULL, &err) == WVOL_ERR_ARG && !a,
              "volume level 40 refused: %s", err.message);
    }
    fixture_free(&f);
}

static double image_maxdiff(const wvol_image *a, const wvol_image *b)
{
    double m = 0;
    for (size_t i = 0; i < 4 * (size_t)a->width * (size_t)a->height; i++)
        m = fmax(m, fabs((double)a->rgba[i] - b->rgba[i]));
    return m;
}

static void frames(void)
{
    fixture f;
    wvol_error err;
    wvol_tf tf;
    wvol_camera cam;
    wvol_geometry g;
    wvol_render_params rp;
    wvol_lod_params lp;
    wvol_lod_stats ls;
    wvol_render_stats st;
    wvol_image *a = NULL, *b = NULL;
    wvol_render_source src;
    const double dir[3] = {0.3, -1.0, 0.4};
    if (!fixture_make(&f, 48, 3)) return fixture_free(&f);
    wvol_geometry_of_volume(&g, f.v);
    CHECK(wvol_tf_preset(&tf, "gaussian", f.vmin, f.vmax, &err) == WVOL_OK, "tf");
    /* 12 pixels across a 48-voxel volume framed in perspective: a coarse level */
    CHECK(wvol_camera_frame(&cam, &g, dir, WVOL_PROJECTION_PERSPECTIVE, 12, 12, 30, &err) == WVOL_OK, "camera");
    CHECK(wvol_image_create(&a, 12, 12, &err) == WVOL_OK && wvol_image_create(&b, 12, 12, &err) == WVOL_OK, "images");
    if (!a || !b) goto done;
    wvol_render_params_default(&rp);
    rp.method = WVOL_RENDER_METHOD_BRICKS;
    wvol_lod_params_default(&lp);
    src = wvol_render_source_store(f.s);
    {
        int want = wvol_lod_level(&cam, &g, 3, NULL);
        wvol_volume *coarse = NULL;
        CHECK(want >= 1, "the framed 12^2 view of 48^3 asks for a coarse level (%d)", want);
        CHECK(wvol_render_lod(a, &src, &cam, &tf, &rp, &lp, &st, &ls, &err) == WVOL_OK, "lod frame: %s", err.message);
        CHECK(ls.level == want && st.method == WVOL_RENDER_METHOD_REFERENCE, "level %d (want %d), method %s",
              ls.level, want, wvol_render_method_name(st.method));
        CHECK(ls.dims[0] == (48 + (1u << want) - 1) >> want, "coarse dims %zu", ls.dims[0]);
        /* the frame of the coarse decode: the reference integrator on wvol_idwt3_level */
        CHECK(wvol_idwt3_level(&coarse, f.c, want, &err) == WVOL_OK, "coarse decode");
        CHECK(coarse && wvol_render_reference(b, coarse, &cam, &tf, &rp, NULL, &err) == WVOL_OK, "ref: %s",
              err.message);
        /* same samples of volumes equal to float rounding (1e-5 of the range, see above): the
         * images agree far within 1e-4 */
        CHECK(image_maxdiff(a, b) <= 1e-4, "coarse frame vs frame of the coarse decode: %g", image_maxdiff(a, b));
        CHECK_NEAR(ls.energy, detail_energy(f.c, want), 1e-9 * (1 + ls.energy), "reported energy");
        CHECK_NEAR(ls.rmse, sqrt(detail_energy(f.c, want) / (double)wvol_volume_count(f.v)), 1e-9,
                   "reported RMSE = sqrt(energy / voxels)");
        wvol_volume_destroy(coarse);
    }
    {
        /* off: wvol_render's image bit for bit; the same for a dense volume */
        wvol_render_source vs = wvol_render_source_volume(f.v);
        lp.enabled = 0;
        CHECK(wvol_render_lod(a, &src, &cam, &tf, &rp, &lp, &st, &ls, &err) == WVOL_OK && ls.level == 0, "off");
        CHECK(wvol_render(b, &src, &cam, &tf, &rp, NULL, &err) == WVOL_OK, "render");
        CHECK(!memcmp(a->rgba, b->rgba, 4 * 12 * 12 * sizeof(float)), "level of detail off: bit for bit (store)");
        rp.method = WVOL_RENDER_METHOD_AUTO;
        CHECK(wvol_render_lod(a, &vs, &cam, &tf, &rp, &lp, &st, &ls, &err) == WVOL_OK && ls.level == 0, "off");
        CHECK(wvol_render(b, &vs, &cam, &tf, &rp, NULL, &err) == WVOL_OK, "render");
        CHECK(!memcmp(a->rgba, b->rgba, 4 * 12 * 12 * sizeof(float)), "level of detail off: bit for bit (volume)");
        /* a method off the source's grid (spline) ignores level of detail */
        lp.enabled = 1;
        rp.method = WVOL_RENDER_METHOD_SPLINE;
        rp.mode = WVOL_RENDER_MODE_XRAY;
        CHECK(wvol_render_lod(a, &src, &cam, NULL, &rp, &lp, &st, &ls, &err) == WVOL_OK && ls.level == 0 &&
                  st.method == WVOL_RENDER_METHOD_SPLINE,
              "spline renders full resolution");
        rp.mode = WVOL_RENDER_MODE_ABSORPTION;
        /* a dense volume's coarse frame is the frame of its level through db2 */
        rp.method = WVOL_RENDER_METHOD_AUTO;
        lp.level = 1;
        {
            wvol_volume *coarse = NULL;
            CHECK(wvol_render_lod(a, &vs, &cam, &tf, &rp, &lp, &st, &ls, &err) == WVOL_OK && ls.level == 1,
                  "volume at level 1: %s", err.message);
            CHECK(wvol_volume_level(&coarse, f.v, fixture_filter("db2"), 1, NULL, &err) == WVOL_OK, "level");
            CHECK(coarse && wvol_render_reference(b, coarse, &cam, &tf, &rp, NULL, &err) == WVOL_OK, "ref");
            CHECK(!memcmp(a->rgba, b->rgba, 4 * 12 * 12 * sizeof(float)), "volume's level 1 frame: bit for bit");
            wvol_volume_destroy(coarse);
        }
        lp.level = 4;
        CHECK(wvol_render_lod(a, &src, &cam, &tf, &rp, &lp, &st, &ls, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "0..3"),
              "a level above the store's refused: %s", err.message);
        lp.level = -2;
        CHECK(wvol_render_lod(a, &src, &cam, &tf, &rp, &lp, &st, &ls, &err) == WVOL_ERR_ARG, "level -2 refused");
    }
done:
    wvol_image_destroy(a), wvol_image_destroy(b);
    fixture_free(&f);
}

static const char *PATH = "test_lod.wvc";

/* A file-backed store's level reads only the chunks of the levels above it, and its frame
 * and mesh are those of the coarse decode of the file. */
static void file_store_levels(void)
{
    fixture f;
    wvol_error err;
    wvol_wvc_params p;
    void *buf = NULL;
    size_t nb = 0;
    wvol_coeffs *d = NULL;
    wvol_store *fs = NULL;
    uint64_t decoded[4] = {0};
    if (!fixture_make(&f, 48, 3)) return fixture_free(&f);
    wvol_wvc_params_default(&p);
    p.value_min = f.vmin, p.value_max = f.vmax;
    p.target_sse = wvol_wvc_sse_for_psnr(50, (double)wvol_volume_count(f.v), f.vmin, f.vmax);
    p.tile = 8, p.tile_z = 8;
    CHECK(wvol_wvc_encode(&buf, &nb, f.c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
    CHECK(buf && wvol_wvc_save(PATH, buf, nb, &err) == WVOL_OK, "save: %s", err.message);
    CHECK(buf && wvol_wvc_decode(&d, buf, nb, NULL, NULL, &err) == WVOL_OK, "decode: %s", err.message);
    free(buf);
    for (int L = 3; L >= 0 && d; L--) {
        wvol_volume *a = NULL, *b = NULL;
        wvol_wvc_cache_stats cs;
        double e = -1, want = 0, diff;
        const wvol_wvc_info *I;
        /* a fresh store each time: its cache counts only this level's reads */
        CHECK(wvol_store_open(&fs, PATH, 0, NULL, &err) == WVOL_OK, "open: %s", err.message);
        if (!fs) break;
        CHECK(wvol_store_level_volume(&a, fs, L, &err) == WVOL_OK, "file level %d: %s", L, err.message);
        CHECK(wvol_idwt3_level(&b, d, L, &err) == WVOL_OK, "decoded level");
        diff = volume_diff(a, b);
        CHECK(diff >= 0 && diff <= 1e-5 * (f.vmax - f.vmin), "file level %d vs coarse decode: %g", L, diff);
        CHECK(wvol_store_file_stats(fs, &cs, &err) == WVOL_OK, "file stats: %s", err.message);
        decoded[L] = cs.decoded;
        I = wvol_store_file_info(fs);
        for (int i = 0; i < I->nsections; i++)
            if (I->sections[i].band && I->sections[i].level <= L) want += I->sections[i].energy;
        CHECK(wvol_store_level_energy(fs, L, &e, &err) == WVOL_OK && e == want, "file energy %g vs %g", e, want);
        /* the band table's energies are the encoder's input: the original coefficients' */
        CHECK_NEAR(e, detail_energy(f.c, L), 1e-6 * (1 + e), "file energy = sum c^2 of levels 1..L");
        if (L == 1) {
            /* marching cubes on the level = on the coarse decode: the same mesh */
            wvol_mesh *ma = NULL, *mb = NULL;
            double th = 0.5;
            CHECK(wvol_iso_extract(&ma, a, th, NULL, NULL, &err) == WVOL_OK, "mc a");
            CHECK(wvol_iso_extract(&mb, b, th, NULL, NULL, &err) == WVOL_OK, "mc b");
            CHECK(ma && mb && ma->ntris == mb->ntris && ma->ntris > 0, "mesh of the level: %zu vs %zu triangles",
                  ma ? ma->ntris : 0, mb ? mb->ntris : 0);
            wvol_mesh_destroy(ma), wvol_mesh_destroy(mb);
        }
        wvol_volume_destroy(a), wvol_volume_destroy(b);
        wvol_store_destroy(fs);
        fs = NULL;
    }
    /* coarser levels decode fewer chunks: the file is read only down to the level (levels 3
     * and 2 may both need only the coarsest chunk here: level 3's details fit one tile) */
    CHECK(decoded[3] <= decoded[2] && decoded[2] < decoded[1] && decoded[1] < decoded[0],
          "chunks decoded per level 3..0: %llu %llu %llu %llu", (unsigned long long)decoded[3],
          (unsigned long long)decoded[2], (unsigned long long)decoded[1], (unsigned long long)decoded[0]);
    wvol_coeffs_destroy(d);
    remove(PATH);
    fixture_free(&f);
}

int main(void)
{
    level_choice_orthographic();
    level_choice_perspective();
    store_level_is_the_coarse_decode();
    frames();
    file_store_levels();
    return check_summary("test_lod");
}
