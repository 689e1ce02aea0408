/* SPDX-License-Identifier: MIT
 * The marching-cubes + Embree peer of the iso caster (bench/bench_iso.py --cast): reads a mesh
 * (PLY, as wvol iso writes it), builds Embree's BVH and traces the primary rays of the same
 * wvol camera (wvol_camera_parse + wvol_camera_ray: the caster's rays, bit for bit), with
 * `threads` threads. Writes the depth (float32, w*h, +inf on a miss; world distance along the
 * unit ray, as the caster's Z) and prints JSON: BVH build and trace seconds, hits, the camera.
 * Usage: iso_embree MESH.ply VOLUME "CAMERA" WxH THREADS DEPTH.raw
 * (VOLUME only places the camera: its geometry frames the view as for wvol iso.) */
#include <embree3/rtcore.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/wvol.h"

static double now(void)
{
    return omp_get_wtime();
}

int main(int argc, char **argv)
{
    wvol_mesh *m = NULL;
    wvol_volume *v = NULL;
    wvol_geometry g;
    wvol_camera cam;
    wvol_error err;
    int w, h, threads, hits = 0;
    char cfg[64];
    float *depth;
    double t0, t_build, t_trace, D;
    RTCDevice dev;
    RTCScene scene;
    RTCGeometry geo;
    if (argc != 7 || sscanf(argv[4], "%dx%d", &w, &h) != 2 || (threads = atoi(argv[5])) < 1) {
        fprintf(stderr, "usage: iso_embree MESH.ply VOLUME \"CAMERA\" WxH THREADS DEPTH.raw\n");
        return 2;
    }
    if (wvol_mesh_read_ply(&m, argv[1], &err) != WVOL_OK || wvol_volume_load(&v, argv[2], NULL, &err) != WVOL_OK) {
        fprintf(stderr, "iso_embree: %s\n", err.message);
        return 1;
    }
    wvol_geometry_of_volume(&g, v);
    if (wvol_camera_parse(&cam, argv[3], &g, w, h, &err) != WVOL_OK) {
        fprintf(stderr, "iso_embree: %s\n", err.message);
        return 1;
    }
    /* orthographic rays are whole lines: start them far behind and subtract the offset */
    D = 4.0 * (g.dims[0] * g.spacing[0] + g.dims[1] * g.spacing[1] + g.dims[2] * g.spacing[2]);
    depth = malloc((size_t)w * (size_t)h * sizeof *depth);
    snprintf(cfg, sizeof cfg, "threads=%d", threads);
    omp_set_num_threads(threads);
    t0 = now();
    dev = rtcNewDevice(cfg);
    scene = rtcNewScene(dev);
    geo = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, m->verts, 0, 3 * sizeof(float),
                               m->nverts);
    rtcSetSharedGeometryBuffer(geo, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m->tris, 0, 3 * sizeof(uint32_t),
                               m->ntris);
    rtcCommitGeometry(geo);
    rtcAttachGeometry(scene, geo);
    rtcReleaseGeometry(geo);
    rtcCommitScene(scene);
    t_build = now() - t0;
    t0 = now();
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : hits)
    for (int y = 0; y < h; y++) {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (int x = 0; x < w; x++) {
            double o[3], d[3];
            double off = cam.projection == WVOL_PROJECTION_ORTHOGRAPHIC ? D : 0.0;
            struct RTCRayHit rh;
            wvol_camera_ray(&cam, x + 0.5, y + 0.5, o, d);
            rh.ray.org_x = (float)(o[0] - off * d[0]);
            rh.ray.org_y = (float)(o[1] - off * d[1]);
            rh.ray.org_z = (float)(o[2] - off * d[2]);
            rh.ray.dir_x = (float)d[0], rh.ray.dir_y = (float)d[1], rh.ray.dir_z = (float)d[2];
            rh.ray.tnear = 0.0f;
            rh.ray.tfar = INFINITY;
            rh.ray.mask = 0xFFFFFFFFu;
            rh.ray.flags = 0;
            rh.ray.time = 0.0f;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &ctx, &rh);
            if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
                depth[(size_t)y * (size_t)w + (size_t)x] = (float)(rh.ray.tfar - off);
                hits++;
            } else {
                depth[(size_t)y * (size_t)w + (size_t)x] = INFINITY;
            }
        }
    }
    t_trace = now() - t0;
    {
        FILE *f = fopen(argv[6], "wb");
        if (!f || fwrite(depth, sizeof *depth, (size_t)w * (size_t)h, f) != (size_t)w * (size_t)h) {
            fprintf(stderr, "iso_embree: cannot write %s\n", argv[6]);
            return 1;
        }
        fclose(f);
    }
    printf("{\"triangles\":%zu,\"build_seconds\":%.9g,\"trace_seconds\":%.9g,\"rays\":%d,\"hits\":%d,"
           "\"camera\":{\"projection\":\"%s\",\"eye\":[%.17g,%.17g,%.17g],\"center\":[%.17g,%.17g,%.17g],"
           "\"up\":[%.17g,%.17g,%.17g],\"fov_y\":%.17g,\"view_height\":%.17g}}\n",
           m->ntris, t_build, t_trace, w * h, hits, cam.projection == WVOL_PROJECTION_PERSPECTIVE ? "persp" : "ortho",
           cam.eye[0], cam.eye[1], cam.eye[2], cam.center[0], cam.center[1], cam.center[2], cam.up[0], cam.up[1],
           cam.up[2], cam.fov_y, cam.view_height);
    rtcReleaseScene(scene);
    rtcReleaseDevice(dev);
    free(depth);
    wvol_mesh_destroy(m);
    wvol_volume_destroy(v);
    return 0;
}
