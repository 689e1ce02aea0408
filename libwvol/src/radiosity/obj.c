/* SPDX-License-Identifier: MIT
 * Radiosity scenes from Wavefront OBJ + MTL: the file is read by tinyobjloader (io's OBJ
 * adapter); this turns its quads and their materials (Kd reflectance, Ke exitance) into a
 * scene, refusing any face that is not a quad or has no material, naming the face. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/adapters.h"
#include "radiosity_internal.h"

static void free_labels(char **labels, size_t n)
{
    for (size_t i = 0; labels && i < n; i++) free(labels[i]);
    free(labels);
}

wvol_status wvol_radiosity_scene_load_obj(wvol_radiosity_scene **out, const char *path, wvol_error *err)
{
    wvol__obj o;
    wvol_radiosity_quad *q = NULL;
    char **labels = NULL;
    size_t f, n = 0;
    wvol_status s;
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "radiosity OBJ: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol__obj_read(&o, path, err));
    s = WVOL_OK;
    if (!o.nfaces) s = wvol_error_set(err, WVOL_ERR_ARG, "%s: empty scene (no faces)", path);
    if (s == WVOL_OK) {
        q = calloc(o.nfaces, sizeof *q);
        labels = calloc(o.nfaces, sizeof *labels);
        if (!q || !labels) s = wvol_error_set(err, WVOL_ERR_NOMEM, "%s: faces", path);
    }
    for (f = 0; s == WVOL_OK && f < o.nfaces; f++) {
        const long *vi = o.face_v + o.face_first[f];
        int m = o.face_mtl[f];
        char label[300];
        if (o.face_nv[f] != 4) {
            s = wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: face %zu has %d vertices (quads only)", path, f + 1,
                               o.face_nv[f]);
            break;
        }
        if (m < 0 || (size_t)m >= o.nmtl) {
            s = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: face %zu has no material (usemtl)", path, f + 1);
            break;
        }
        for (int k = 0; k < 4; k++) {
            if (vi[k] < 0 || (size_t)vi[k] >= o.nv) {
                s = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: face %zu: vertex %ld does not exist", path, f + 1,
                                   vi[k] + 1);
                break;
            }
            memcpy(q[n].p[k], o.v + 3 * vi[k], sizeof q[n].p[k]);
        }
        if (s != WVOL_OK) break;
        memcpy(q[n].emission, o.ke[m], sizeof q[n].emission);
        memcpy(q[n].reflectance, o.kd[m], sizeof q[n].reflectance);
        snprintf(label, sizeof label, "%s: face %zu (material %s)", path, f + 1, o.mtl_name[m]);
        if (!(labels[n] = strdup(label))) s = wvol_error_set(err, WVOL_ERR_NOMEM, "%s: faces", path);
        n++;
    }
    if (s == WVOL_OK) s = wvol__rad_scene_build(out, q, n, (const char *const *)labels, err);
    free_labels(labels, n);
    free(q);
    wvol__obj_free(&o);
    return s;
}
