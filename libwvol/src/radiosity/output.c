/* SPDX-License-Identifier: MIT
 * Radiosity output: images rendered straight from the basis functions (no Gouraud smoothing) and
 * meshes with per-cell radiosity (PLY with unshared vertices, VTP with CellData), written atomically. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/io.h"
#include "radiosity_internal.h"

wvol_status wvol_radiosity_render(const wvol_radiosity *r, wvol_image *img, const wvol_camera *cam, wvol_error *err)
{
    WVOL_RETURN_IF(!r || !img || !cam, err, WVOL_ERR_ARG, "radiosity render: NULL argument");
    WVOL_FORWARD(wvol_camera_check(cam, err));
    WVOL_RETURN_IF(img->width != cam->width || img->height != cam->height, err, WVOL_ERR_DIMS,
                   "radiosity render: image %dx%d, camera %dx%d", img->width, img->height, cam->width, cam->height);
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            double o[3], d[3], u, v, rgb[3];
            float *px = img->rgba + 4 * ((size_t)y * img->width + x);
            long hit;
            wvol_camera_ray(cam, x + 0.5, y + 0.5, o, d);
            /* orthographic rays are whole lines: the scene may lie behind the image plane */
            hit = wvol__rad_hit(r->scene, o, d, cam->projection == WVOL_PROJECTION_PERSPECTIVE ? 0 : -INFINITY, &u, &v);
            if (hit < 0) {
                px[0] = px[1] = px[2] = px[3] = 0;
                continue;
            }
            wvol_radiosity_eval(r, (size_t)hit, 1, (const double[2]){u, v}, rgb, NULL);
            px[0] = (float)rgb[0], px[1] = (float)rgb[1], px[2] = (float)rgb[2], px[3] = 1;
        }
    return WVOL_OK;
}

static void put_f32(FILE *fp, float f)
{
    uint32_t u;
    unsigned char b[4];
    memcpy(&u, &f, 4);
    for (int k = 0; k < 4; k++) b[k] = (unsigned char)(u >> (8 * k));
    fwrite(b, 1, 4, fp);
}

static void put_u32(FILE *fp, uint32_t u)
{
    unsigned char b[4];
    for (int k = 0; k < 4; k++) b[k] = (unsigned char)(u >> (8 * k));
    fwrite(b, 1, 4, fp);
}

static unsigned char to_byte(double v)
{
    double s = wvol_linear_to_srgb(fmin(fmax(v, 0), 1));
    return (unsigned char)lrint(255 * s);
}

/* Corner (cu, cv) of cell (iu, iv) of patch i on a res x res grid. */
static void grid_point(const wvol_radiosity *r, size_t i, int res, int iu, int iv, double x[3])
{
    wvol__rad_point(&r->scene->p[i], (double)iu / res, (double)iv / res, x);
}

static void write_ply(FILE *fp, const wvol_radiosity *r, int res, const double *rgb)
{
    size_t n = r->scene->n, cells = n * (size_t)res * res;
    static const int corner[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    fprintf(fp,
            "ply\nformat binary_little_endian 1.0\ncomment libwvol radiosity: unshared vertices, one cell's "
            "value on its four corners\nelement vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
            "property float radiosity_r\nproperty float radiosity_g\nproperty float radiosity_b\n"
            "property uchar red\nproperty uchar green\nproperty uchar blue\n"
            "element face %zu\nproperty list uchar uint vertex_indices\nend_header\n",
            4 * cells, cells);
    for (size_t i = 0; i < n; i++)
        for (int iv = 0; iv < res; iv++)
            for (int iu = 0; iu < res; iu++) {
                const double *c = rgb + ((i * (size_t)res + iv) * res + iu) * 3;
                for (int k = 0; k < 4; k++) {
                    double x[3];
                    unsigned char col[3] = {to_byte(c[0]), to_byte(c[1]), to_byte(c[2])};
                    grid_point(r, i, res, iu + corner[k][0], iv + corner[k][1], x);
                    for (int a = 0; a < 3; a++) put_f32(fp, (float)x[a]);
                    for (int a = 0; a < 3; a++) put_f32(fp, (float)c[a]);
                    fwrite(col, 1, 3, fp);
                }
            }
    for (size_t f = 0; f < cells; f++) {
        fputc(4, fp);
        for (int k = 0; k < 4; k++) put_u32(fp, (uint32_t)(4 * f + k));
    }
}

static void write_vtp(FILE *fp, const wvol_radiosity *r, int res, const double *rgb)
{
    size_t n = r->scene->n, cells = n * (size_t)res * res, npts = n * (size_t)(res + 1) * (res + 1);
    fprintf(fp, "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
                "<PolyData>\n<Piece NumberOfPoints=\"%zu\" NumberOfPolys=\"%zu\">\n<Points>\n"
                "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">\n",
            npts, cells);
    for (size_t i = 0; i < n; i++)
        for (int iv = 0; iv <= res; iv++)
            for (int iu = 0; iu <= res; iu++) {
                double x[3];
                grid_point(r, i, res, iu, iv, x);
                fprintf(fp, "%.9g %.9g %.9g\n", x[0], x[1], x[2]);
            }
    fprintf(fp, "</DataArray>\n</Points>\n<Polys>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n");
    for (size_t i = 0; i < n; i++)
        for (int iv = 0; iv < res; iv++)
            for (int iu = 0; iu < res; iu++) {
                size_t b = i * (size_t)(res + 1) * (res + 1), w = (size_t)res + 1;
                fprintf(fp, "%zu %zu %zu %zu\n", b + iv * w + iu, b + iv * w + iu + 1, b + (iv + 1) * w + iu + 1,
                        b + (iv + 1) * w + iu);
            }
    fprintf(fp, "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n");
    for (size_t f = 0; f < cells; f++) fprintf(fp, "%zu\n", 4 * (f + 1));
    fprintf(fp, "</DataArray>\n</Polys>\n<CellData Scalars=\"radiosity\">\n"
                "<DataArray type=\"Float32\" Name=\"radiosity\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for (size_t f = 0; f < cells; f++) fprintf(fp, "%.9g %.9g %.9g\n", rgb[3 * f], rgb[3 * f + 1], rgb[3 * f + 2]);
    fprintf(fp, "</DataArray>\n<DataArray type=\"Int32\" Name=\"patch\" format=\"ascii\">\n");
    for (size_t f = 0; f < cells; f++) fprintf(fp, "%zu\n", f / ((size_t)res * res));
    fprintf(fp, "</DataArray>\n</CellData>\n</Piece>\n</PolyData>\n</VTKFile>\n");
}

wvol_status wvol_radiosity_write_mesh(const wvol_radiosity *r, const char *path, int res, wvol_error *err)
{
    wvol_atomic_file af;
    double *rgb;
    int ply;
    wvol_status s;
    WVOL_RETURN_IF(!r || !path, err, WVOL_ERR_ARG, "radiosity mesh: NULL argument");
    WVOL_RETURN_IF(res < 1 || res > 4096, err, WVOL_ERR_ARG, "radiosity mesh: res = %d must be in 1..4096", res);
    ply = wvol_path_has_ext(path, ".ply");
    WVOL_RETURN_IF(!ply && !wvol_path_has_ext(path, ".vtp"), err, WVOL_ERR_UNSUPPORTED,
                   "%s: radiosity meshes are .ply or .vtp", path);
    rgb = malloc(r->scene->n * (size_t)res * res * 3 * sizeof *rgb);
    WVOL_RETURN_IF(!rgb, err, WVOL_ERR_NOMEM, "%s: %zu patches at %d x %d", path, r->scene->n, res, res);
    s = wvol_radiosity_sample(r, res, rgb, err);
    if (s == WVOL_OK) s = wvol_atomic_open(&af, path, err);
    if (s == WVOL_OK) {
        if (ply)
            write_ply(af.fp, r, res, rgb);
        else
            write_vtp(af.fp, r, res, rgb);
        if (ferror(af.fp)) {
            s = wvol_atomic_fail(&af, err);
        } else {
            s = wvol_atomic_commit(&af, err);
        }
    }
    free(rgb);
    return s;
}
