/* SPDX-License-Identifier: MIT
 * Uses an installed libwvol from outside the tree: the version, a db2 transform and
 * its inverse, and the optional parts (missing ones must answer WVOL_ERR_UNSUPPORTED). Like
 * many users' programs, it loads no volume file: a .vtp mesh must still reach the VTK adapter
 * (with the static library, nothing else here links the adapter module's forwarders in). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "wvol/wvol.h"

static int failed;
#define EXPECT(cond, ...) ((cond) ? (void)0 : (failed++, fprintf(stderr, "wvol_consumer: " __VA_ARGS__), (void)fputc('\n', stderr)))

int main(void)
{
    wvol_volume *v = NULL, *back = NULL;
    wvol_coeffs *c = NULL;
    const wvol_filter *f = NULL;
    wvol_error err;
    double maxerr = 0;
    size_t i, n;

    wvol_error_clear(&err);
    EXPECT(wvol_version() == WVOL_VERSION_NUMBER, "library %d, header %d", wvol_version(), WVOL_VERSION_NUMBER);
    EXPECT(!strcmp(wvol_version_string(), WVOL_VERSION_STRING), "version string %s", wvol_version_string());

    if (wvol_volume_create(&v, 20, 16, 12, &err) || wvol_filter_get(&f, "db2", &err)) {
        fprintf(stderr, "wvol_consumer: %s\n", err.message);
        return 1;
    }
    /* names with their type's prefix, and the deprecated aliases kept for 0.1 */
    EXPECT(f->family == WVOL_FAMILY_DAUBECHIES && WVOL_DAUBECHIES == WVOL_FAMILY_DAUBECHIES, "db2 family");
    EXPECT(wvol_sample_type_size(WVOL_SAMPLE_TYPE_F64) == 8 && WVOL_F64 == WVOL_SAMPLE_TYPE_F64, "float64 size");
    EXPECT(WVOL_NORMALS_GRADIENT == WVOL_ISO_NORMALS_GRADIENT && WVOL_PSI == WVOL_BASIS_PSI, "aliases");
    n = wvol_volume_count(v);
    for (i = 0; i < n; i++) v->data[i] = (float)sin(0.1 * (double)i) + (float)(i % 5);
    if (wvol_dwt3(&c, v, f, 2, &err) || wvol_idwt3(&back, c, &err)) {
        fprintf(stderr, "wvol_consumer: %s\n", err.message);
        return 1;
    }
    for (i = 0; i < n; i++) maxerr = fmax(maxerr, fabs((double)back->data[i] - (double)v->data[i]));
    EXPECT(maxerr < 1e-4, "db2 round trip error %g", maxerr);

    {
        /* a mesh of the test volume's level set, written as .vtp */
        wvol_mesh *m = NULL;
        const char *path = "wvol_consumer_mesh.vtp";
        wvol_status s = wvol_iso_extract(&m, v, 2.0, NULL, NULL, &err);
        EXPECT(s == WVOL_OK && m && m->ntris > 0, "marching cubes: %s", err.message);
        if (m) {
            s = wvol_mesh_save(m, path, &err);
            if (wvol_has_feature(WVOL_FEATURE_VTK)) {
                FILE *fp = fopen(path, "rb");
                EXPECT(s == WVOL_OK && fp, ".vtp mesh with VTK: %s", err.message);
                if (fp) fclose(fp);
            } else {
                EXPECT(s == WVOL_ERR_UNSUPPORTED && strstr(err.message, "no VTK support"), ".vtp without VTK: %s",
                       err.message);
            }
            remove(path);
        }
        wvol_mesh_destroy(m);
    }

    if (!wvol_has_feature(WVOL_FEATURE_PNG)) {
        float px[3] = {0.5f, 0.5f, 0.5f};
        EXPECT(wvol_png_write("never.png", 1, 1, 3, px, &err) == WVOL_ERR_UNSUPPORTED && strstr(err.message, "libpng"),
               "PNG without libpng: %s", err.message);
    }
    if (!wvol_has_feature(WVOL_FEATURE_OPENEXR)) {
        float *ch = NULL;
        int w, h;
        EXPECT(wvol_exr_read_channel(&ch, &w, &h, "never.exr", "R", &err) == WVOL_ERR_UNSUPPORTED &&
                   strstr(err.message, "OpenEXR"),
               "EXR without OpenEXR: %s", err.message);
    }
    if (!wvol_has_feature(WVOL_FEATURE_LAPACKE)) {
        wvol_features feat = {1, 1, 1, 1, 1, v->data};
        EXPECT(wvol_features_pca(&feat, 1.0, NULL, &err) == WVOL_ERR_UNSUPPORTED && strstr(err.message, "LAPACKE"),
               "PCA without LAPACKE: %s", err.message);
    }

    printf("wvol_consumer: libwvol %s, db2 round trip max error %.3g, png %d exr %d lapacke %d vtk %d openvdb %d: %s\n",
           wvol_version_string(), maxerr, wvol_has_feature(WVOL_FEATURE_PNG), wvol_has_feature(WVOL_FEATURE_OPENEXR),
           wvol_has_feature(WVOL_FEATURE_LAPACKE), wvol_has_feature(WVOL_FEATURE_VTK),
           wvol_has_feature(WVOL_FEATURE_OPENVDB), failed ? "FAILED" : "ok");
    wvol_volume_destroy(back);
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
    return failed ? 1 : 0;
}
