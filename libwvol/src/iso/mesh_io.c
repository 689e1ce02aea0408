/* SPDX-License-Identifier: MIT */
/* Mesh files: binary PLY (read and write), OBJ, binary STL, and VTK's .vtp
 * through the VTK adapter. Every writer goes through wvol_atomic_file, so a
 * failure never leaves a partial file. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/file_open.h"
#include "core/finite.h"
#include "io/adapters.h"
#include "core/status_internal.h"
#include "wvol/io.h"
#include "wvol/iso.h"

enum { CHUNK = 1 << 16 };

/* The .vtp writer is the VTK adapter's (io/adapters.h): the library always holds a definition,
 * the adapter module's forwarder or, in a build without VTK, a refusal (adapters_missing.c).
 * No weak stand-in here: it would satisfy the reference, and a program that links the static
 * library and writes only meshes would never link the forwarder in. */

static int host_is_le(void)
{
    const uint16_t one = 1;
    unsigned char b;
    memcpy(&b, &one, 1);
    return b == 1;
}

static void put_u32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16);
    p[3] = (unsigned char)(v >> 24);
}

static void put_f32(unsigned char *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32(p, v);
}

static uint32_t get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static wvol_status check_mesh(const wvol_mesh *m, const char *path, wvol_error *err)
{
    size_t i;
    WVOL_RETURN_IF(!m, err, WVOL_ERR_ARG, "%s: mesh is NULL", path ? path : "(null)");
    WVOL_RETURN_IF(!path || !*path, err, WVOL_ERR_ARG, "mesh output path is empty");
    WVOL_RETURN_IF((m->nverts && !m->verts) || (m->ntris && !m->tris), err, WVOL_ERR_ARG,
                   "%s: the mesh has %zu vertices and %zu triangles but no array for them", path, m->nverts, m->ntris);
    for (i = 0; i < 3 * m->ntris; i++)
        WVOL_RETURN_IF(m->tris[i] >= m->nverts, err, WVOL_ERR_ARG,
                       "%s: triangle %zu refers to vertex %u of %zu", path, i / 3, m->tris[i], m->nverts);
    WVOL_RETURN_IF(!wvol__all_finite(m->verts, 3 * m->nverts), err, WVOL_ERR_NONFINITE,
                   "%s: a vertex holds NaN or Inf: not written", path);
    WVOL_RETURN_IF(m->normals && !wvol__all_finite(m->normals, 3 * m->nverts), err, WVOL_ERR_NONFINITE,
                   "%s: a normal holds NaN or Inf: not written", path);
    return WVOL_OK;
}

static wvol_status write_buf(wvol_atomic_file *f, const void *buf, size_t n, wvol_error *err)
{
    if (n && fwrite(buf, 1, n, f->fp) != n) return wvol_atomic_fail(f, err);
    return WVOL_OK;
}

wvol_status wvol_mesh_write_ply(const wvol_mesh *m, const char *path, wvol_error *err)
{
    wvol_atomic_file f;
    char head[512];
    unsigned char *buf;
    size_t i, k, vsz, n;
    int nrm;
    WVOL_FORWARD(check_mesh(m, path, err));
    WVOL_RETURN_IF(m->nverts > 0x7fffffffu, err, WVOL_ERR_DIMS, "%s: %zu vertices exceed PLY int indices", path,
                   m->nverts);
    nrm = m->normals != NULL;
    n = (size_t)snprintf(head, sizeof head,
                         "ply\nformat binary_little_endian 1.0\ncomment written by libwvol\n"
                         "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n%s"
                         "element face %zu\nproperty list uchar int vertex_indices\nend_header\n",
                         m->nverts,
                         nrm ? "property float nx\nproperty float ny\nproperty float nz\n" : "", m->ntris);
    vsz = nrm ? 24 : 12;
    buf = malloc((size_t)CHUNK * 24);
    if (!buf) return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    if (wvol_atomic_open(&f, path, err) != WVOL_OK) {
        free(buf);
        return err ? err->status : WVOL_ERR_IO;
    }
    if (write_buf(&f, head, n, err) != WVOL_OK) goto fail;
    for (i = 0; i < m->nverts; i += k) {
        size_t q, cnt = m->nverts - i < CHUNK ? m->nverts - i : CHUNK;
        if (host_is_le() && !nrm) {
            if (write_buf(&f, m->verts + 3 * i, cnt * 12, err) != WVOL_OK) goto fail;
            k = cnt;
            continue;
        }
        for (q = 0; q < cnt; q++) {
            unsigned char *p = buf + q * vsz;
            int d;
            for (d = 0; d < 3; d++) put_f32(p + 4 * d, m->verts[3 * (i + q) + d]);
            if (nrm)
                for (d = 0; d < 3; d++) put_f32(p + 12 + 4 * d, m->normals[3 * (i + q) + d]);
        }
        if (write_buf(&f, buf, cnt * vsz, err) != WVOL_OK) goto fail;
        k = cnt;
    }
    for (i = 0; i < m->ntris; i += k) {
        size_t q, cnt = m->ntris - i < CHUNK ? m->ntris - i : CHUNK;
        for (q = 0; q < cnt; q++) {
            unsigned char *p = buf + q * 13;
            p[0] = 3;
            put_u32(p + 1, m->tris[3 * (i + q)]);
            put_u32(p + 5, m->tris[3 * (i + q) + 1]);
            put_u32(p + 9, m->tris[3 * (i + q) + 2]);
        }
        if (write_buf(&f, buf, cnt * 13, err) != WVOL_OK) goto fail;
        k = cnt;
    }
    free(buf);
    return wvol_atomic_commit(&f, err);
fail:
    free(buf);
    return err ? err->status : WVOL_ERR_IO;
}

wvol_status wvol_mesh_write_obj(const wvol_mesh *m, const char *path, wvol_error *err)
{
    wvol_atomic_file f;
    size_t i;
    int bad = 0;
    WVOL_FORWARD(check_mesh(m, path, err));
    WVOL_FORWARD(wvol_atomic_open(&f, path, err));
    if (fprintf(f.fp, "# written by libwvol: %zu vertices, %zu triangles\n", m->nverts, m->ntris) < 0) bad = 1;
    for (i = 0; i < m->nverts && !bad; i++)
        if (fprintf(f.fp, "v %.9g %.9g %.9g\n", m->verts[3 * i], m->verts[3 * i + 1], m->verts[3 * i + 2]) < 0)
            bad = 1;
    if (m->normals)
        for (i = 0; i < m->nverts && !bad; i++)
            if (fprintf(f.fp, "vn %.7g %.7g %.7g\n", m->normals[3 * i], m->normals[3 * i + 1],
                        m->normals[3 * i + 2]) < 0)
                bad = 1;
    for (i = 0; i < m->ntris && !bad; i++) {
        unsigned long a = m->tris[3 * i] + 1ul, b = m->tris[3 * i + 1] + 1ul, c = m->tris[3 * i + 2] + 1ul;
        int r = m->normals ? fprintf(f.fp, "f %lu//%lu %lu//%lu %lu//%lu\n", a, a, b, b, c, c)
                           : fprintf(f.fp, "f %lu %lu %lu\n", a, b, c);
        if (r < 0) bad = 1;
    }
    if (bad) return wvol_atomic_fail(&f, err);
    return wvol_atomic_commit(&f, err);
}

wvol_status wvol_mesh_write_stl(const wvol_mesh *m, const char *path, wvol_error *err)
{
    wvol_atomic_file f;
    unsigned char head[84], *buf;
    size_t i, k;
    WVOL_FORWARD(check_mesh(m, path, err));
    WVOL_RETURN_IF(m->ntris > 0xffffffffu, err, WVOL_ERR_DIMS, "%s: %zu triangles exceed binary STL's count",
                   path, m->ntris);
    memset(head, 0, sizeof head);
    snprintf((char *)head, 80, "binary STL written by libwvol");
    put_u32(head + 80, (uint32_t)m->ntris);
    buf = malloc((size_t)CHUNK * 50);
    if (!buf) return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    if (wvol_atomic_open(&f, path, err) != WVOL_OK) {
        free(buf);
        return err ? err->status : WVOL_ERR_IO;
    }
    if (write_buf(&f, head, sizeof head, err) != WVOL_OK) goto fail;
    for (i = 0; i < m->ntris; i += k) {
        size_t q, cnt = m->ntris - i < CHUNK ? m->ntris - i : CHUNK;
        for (q = 0; q < cnt; q++) {
            unsigned char *p = buf + q * 50;
            const float *a = m->verts + 3 * (size_t)m->tris[3 * (i + q)];
            const float *b = m->verts + 3 * (size_t)m->tris[3 * (i + q) + 1];
            const float *c = m->verts + 3 * (size_t)m->tris[3 * (i + q) + 2];
            double u[3], v[3], n[3], len;
            int d;
            for (d = 0; d < 3; d++) {
                u[d] = (double)b[d] - a[d];
                v[d] = (double)c[d] - a[d];
            }
            n[0] = u[1] * v[2] - u[2] * v[1];
            n[1] = u[2] * v[0] - u[0] * v[2];
            n[2] = u[0] * v[1] - u[1] * v[0];
            len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            for (d = 0; d < 3; d++) put_f32(p + 4 * d, len > 0 ? (float)(n[d] / len) : 0.0f);
            for (d = 0; d < 3; d++) {
                put_f32(p + 12 + 4 * d, a[d]);
                put_f32(p + 24 + 4 * d, b[d]);
                put_f32(p + 36 + 4 * d, c[d]);
            }
            p[48] = p[49] = 0;
        }
        if (write_buf(&f, buf, cnt * 50, err) != WVOL_OK) goto fail;
        k = cnt;
    }
    free(buf);
    return wvol_atomic_commit(&f, err);
fail:
    free(buf);
    return err ? err->status : WVOL_ERR_IO;
}

wvol_status wvol_mesh_write_vtp(const wvol_mesh *m, const char *path, wvol_error *err)
{
    WVOL_FORWARD(check_mesh(m, path, err));
    WVOL_RETURN_IF(m->nverts > 0xffffffffu, err, WVOL_ERR_DIMS, "%s: too many vertices", path);
    return wvol__vtk_write_mesh(path, m->verts, m->nverts, (const unsigned *)m->tris, m->ntris, m->normals, err);
}

wvol_status wvol_mesh_save(const wvol_mesh *m, const char *path, wvol_error *err)
{
    WVOL_RETURN_IF(!path, err, WVOL_ERR_ARG, "mesh output path is NULL");
    if (wvol_path_has_ext(path, ".ply")) return wvol_mesh_write_ply(m, path, err);
    if (wvol_path_has_ext(path, ".obj")) return wvol_mesh_write_obj(m, path, err);
    if (wvol_path_has_ext(path, ".stl")) return wvol_mesh_write_stl(m, path, err);
    if (wvol_path_has_ext(path, ".vtp")) return wvol_mesh_write_vtp(m, path, err);
    return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: unknown mesh format (use .ply, .obj, .stl or .vtp)",
                          path);
}

/* ---- PLY reader (the subset written above) ------------------------------------ */

wvol_status wvol_mesh_read_ply(wvol_mesh **out, const char *path, wvol_error *err)
{
    FILE *fp;
    char line[256];
    size_t nv = 0, nf = 0, i;
    int nprops = 0, in_vertex = 0, have_normals = 0, ok_face = 0, ok_format = 0;
    char names[8][8];
    wvol_mesh *m = NULL;
    wvol_status s = WVOL_OK;
    unsigned char rec[32];

    *out = NULL;
    WVOL_FORWARD(wvol__fopen_regular(&fp, path, err));
    if (!fgets(line, sizeof line, fp) || strncmp(line, "ply", 3) != 0) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: not a PLY file", path);
    }
    while (fgets(line, sizeof line, fp)) {
        char a[64], b[64], c[64], d[64];
        unsigned long long n;
        if (!strncmp(line, "end_header", 10)) break;
        if (sscanf(line, "format %63s", a) == 1) {
            ok_format = !strcmp(a, "binary_little_endian");
        } else if (sscanf(line, "element %63s %llu", a, &n) == 2) {
            in_vertex = !strcmp(a, "vertex");
            if (in_vertex) nv = (size_t)n;
            else if (!strcmp(a, "face")) nf = (size_t)n;
        } else if (sscanf(line, "property list %63s %63s %63s", a, b, c) == 3) {
            ok_face = !strcmp(a, "uchar") && (!strcmp(b, "int") || !strcmp(b, "uint"));
        } else if (sscanf(line, "property %63s %63s", a, d) == 2 && in_vertex) {
            if (strcmp(a, "float") || nprops >= 8) {
                fclose(fp);
                return wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: vertex property '%s %s' not supported",
                                      path, a, d);
            }
            snprintf(names[nprops], sizeof names[nprops], "%.7s", d);
            nprops++;
        }
    }
    if (!ok_format || !ok_face || (nprops != 3 && nprops != 6) || strcmp(names[0], "x")) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_UNSUPPORTED,
                              "%s: only binary little-endian PLY with float x y z [nx ny nz] and int faces",
                              path);
    }
    have_normals = nprops == 6;
    s = wvol_mesh_create(&m, nv, nf, have_normals, err);
    if (s != WVOL_OK) {
        fclose(fp);
        return s;
    }
    for (i = 0; i < nv; i++) {
        int q;
        if (fread(rec, 4, (size_t)nprops, fp) != (size_t)nprops) goto trunc;
        for (q = 0; q < nprops; q++) {
            uint32_t u = get_u32(rec + 4 * q);
            float x;
            memcpy(&x, &u, 4);
            if (q < 3) m->verts[3 * i + q] = x;
            else m->normals[3 * i + q - 3] = x;
        }
    }
    for (i = 0; i < nf; i++) {
        int q;
        if (fread(rec, 1, 13, fp) != 13) goto trunc;
        if (rec[0] != 3) {
            s = wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: face %zu has %d vertices (triangles only)", path,
                               i, rec[0]);
            goto fail;
        }
        for (q = 0; q < 3; q++) {
            uint32_t v = get_u32(rec + 1 + 4 * q);
            if (v >= nv) {
                s = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: face %zu uses vertex %u of %zu", path, i, v, nv);
                goto fail;
            }
            m->tris[3 * i + q] = v;
        }
    }
    fclose(fp);
    *out = m;
    return WVOL_OK;
trunc:
    s = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: truncated", path);
fail:
    fclose(fp);
    wvol_mesh_destroy(m);
    return s;
}
