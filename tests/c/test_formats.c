/* SPDX-License-Identifier: MIT */
/* The OpenVDB and VTK adapters through the load/save dispatch (also run under ASan):
 * round trips keep every sample and the geometry, bad files give an error naming the
 * file, the mesh writer checks its input. `test_formats --mesh PATH` only writes the
 * test mesh (tests/python/test_formats.py reads it back with VTK). */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "io/adapters.h"
#include "wvol/io.h"

static const float tet_xyz[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
static const unsigned tet_tris[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
static const float tet_nrm[] = {-1, -1, -1, 1, 0, 0, 0, 1, 0, 0, 0, 1};

static wvol_volume *make_volume(size_t nx, size_t ny, size_t nz)
{
    wvol_volume *v = NULL;
    size_t i, n;
    if (wvol_volume_create(&v, nx, ny, nz, NULL) != WVOL_OK) return NULL;
    n = wvol_volume_count(v);
    for (i = 0; i < n; i++) v->data[i] = (i % 7 == 0) ? 0.0f : (float)i * 0.37f - 11.0f;
    v->spacing[0] = v->spacing[1] = v->spacing[2] = 0.625;
    v->origin[0] = -1.5;
    v->origin[1] = 0.125; /* float32-exact: NIfTI stores float32 geometry */
    v->origin[2] = 1024.25;
    return v;
}

static int same(const wvol_volume *a, const wvol_volume *b)
{
    return a->nx == b->nx && a->ny == b->ny && a->nz == b->nz &&
           memcmp(a->spacing, b->spacing, sizeof a->spacing) == 0 &&
           memcmp(a->origin, b->origin, sizeof a->origin) == 0 &&
           memcmp(a->data, b->data, wvol_volume_count(a) * sizeof(float)) == 0;
}

static void round_trips(const char *dir)
{
    static const char *exts[] = {".vdb", ".vti", ".mha", ".nii", ".nii.gz", ".vtk"};
    wvol_volume *v = make_volume(9, 4, 5);
    char path[512];
    size_t e;
    CHECK(v != NULL, "create");
    if (!v) return;
    for (e = 0; e < sizeof exts / sizeof exts[0]; e++) {
        wvol_error err;
        wvol_volume *back = NULL;
        wvol_error_clear(&err);
        snprintf(path, sizeof path, "%s/rt%s", dir, exts[e]);
        CHECK(wvol_format_supported(path, 1) && wvol_format_supported(path, 0), "%s supported", exts[e]);
        CHECK(wvol_volume_save(v, path, &err) == WVOL_OK, "save %s: %s", exts[e], err.message);
        CHECK(wvol_volume_load(&back, path, NULL, &err) == WVOL_OK, "load %s: %s", exts[e], err.message);
        if (back) CHECK(same(v, back), "%s round trip differs", exts[e]);
        wvol_volume_destroy(back);
        remove(path);
    }
    wvol_volume_destroy(v);
}

static void bad_files(const char *dir)
{
    static const char *names[] = {"bad.vdb", "bad.vti", "bad.mha", "bad.nii", "bad.vtk"};
    char path[512];
    size_t i;
    for (i = 0; i < sizeof names / sizeof names[0]; i++) {
        wvol_error err;
        wvol_volume *v = (wvol_volume *)1;
        wvol_status st;
        FILE *fp;
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        fp = fopen(path, "w");
        if (!fp) continue;
        fputs("not a volume at all\n", fp);
        fclose(fp);
        wvol_error_clear(&err);
        st = wvol_volume_load(&v, path, NULL, &err);
        CHECK(st == WVOL_ERR_FORMAT, "%s: status %d (%s)", names[i], (int)st, err.message);
        CHECK(v == NULL, "%s: output not cleared", names[i]);
        CHECK(strstr(err.message, names[i]) != NULL, "%s: message does not name the file: %s", names[i],
              err.message);
        remove(path);
    }
}

static void meshes(const char *dir)
{
    char path[512];
    wvol_error err;
    static const unsigned bad_tris[] = {0, 1, 4};
    snprintf(path, sizeof path, "%s/m.vtp", dir);
    wvol_error_clear(&err);
    CHECK(wvol__vtk_write_mesh(path, tet_xyz, 4, tet_tris, 4, tet_nrm, &err) == WVOL_OK, "mesh: %s", err.message);
    CHECK(access(path, R_OK) == 0, "mesh file missing");
    CHECK(wvol__vtk_write_mesh(path, tet_xyz, 4, tet_tris, 4, NULL, &err) == WVOL_OK, "mesh: %s", err.message);
    CHECK(wvol__vtk_write_mesh(path, tet_xyz, 4, bad_tris, 1, NULL, &err) == WVOL_ERR_ARG, "bad index accepted");
    CHECK(strstr(err.message, "vertex 4") != NULL, "message: %s", err.message);
    CHECK(wvol__vtk_write_mesh(path, NULL, 0, NULL, 0, NULL, &err) == WVOL_OK, "empty mesh: %s", err.message);
    remove(path);
}

int main(int argc, char **argv)
{
    char dir[] = "/tmp/wvol_test_formats_XXXXXX";
#if !defined(WVOL_HAVE_OPENVDB) || !defined(WVOL_HAVE_VTK)
    (void)argc, (void)argv, (void)dir;
    printf("test_formats: skipped (this build lacks the OpenVDB or VTK adapter)\n");
    return 0;
#endif
    if (argc == 3 && !strcmp(argv[1], "--mesh")) {
        wvol_error err;
        wvol_error_clear(&err);
        if (wvol__vtk_write_mesh(argv[2], tet_xyz, 4, tet_tris, 4, tet_nrm, &err) != WVOL_OK) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        return 0;
    }
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    round_trips(dir);
    bad_files(dir);
    meshes(dir);
    rmdir(dir);
    return check_summary("test_formats");
}
