/* SPDX-License-Identifier: MIT */
/* wvol iso: isosurface of a volume as a mesh (marching cubes on the samples or,
 * with --wavelet, brick by brick from kept wavelet coefficients) or as an image
 * (guaranteed ray tracing of the wavelet model f^ = iso). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "output_set.h"
#include "wvol/compress.h"
#include "wvol/image.h"
#include "wvol/io.h"
#include "wvol/iso.h"
#include "wvol/render.h"
#include "wvol/store.h"

const char wvol_cmd_iso_summary[] = "isosurface: marching cubes mesh (.ply .obj .stl .vtp) or ray-traced image";

static const cli_opt opts[] = {
    {"output", 'o', 1, "mesh file (.ply .obj .stl .vtp); raytrace and hybrid: image (.exr with Z depth, .png)"},
    {"iso", 0, 1, "iso-value theta (required)"},
    {"method", 0, 1, "mc (default), cast (image of the trilinear interpolant's surface, bricked),\n"
                     "raytrace (image of f^ = theta, exact model) or hybrid (surface behind the volume)"},
    {"model-bound", 0, 0, "cast from a store: also bound |f^ - interp| per brick (reported)"},
    {"surface", 0, 1, "hybrid: the surface from exact (f^, default) or cast (the interpolant)"},
    {"camera", 0, 1, "raytrace/hybrid: camera, as for wvol render (default +z)"},
    {"size", 0, 1, "raytrace/hybrid: image size WxH (default 512x512)"},
    {"tf", 0, 1, "hybrid: transfer function of the volume in front (default gaussian)"},
    {"tolerance", 0, 1, "image methods: depth tolerance in voxels (default 0.001; cast 0.00001)"},
    {"spline-j", 0, 1, "raytrace/hybrid: basis splines with 2^J knots per unit (default 4)"},
    {"chunk", 0, 1, "raytrace/hybrid: ray segment built at a time, voxels (default 16)"},
    CLI_THREADS_OPT,
    {"normals", 0, 1, "gradient (default) or none"},
    {"repeat", 0, 1, "extract N times and report the fastest (benchmarking; --json adds the first, extract_first)"},
    {"wavelet", 0, 1, "mesh the reconstruction of kept wavelet coefficients (haar, db2, coif1, bl3, ...);\n"
                      "raytrace/hybrid: the store's wavelet (default db2)"},
    {"levels", 0, 1, "wavelet levels (default 3)"},
    {"keep", 0, 1, "kept fraction of the coefficients, e.g. 5% (default 100%)"},
    {"level", 0, 1, "mc: mesh the coarser grid of wavelet level L (0 = full resolution, default): from a .wvc\n"
                    "only the levels above L are decoded; a volume is transformed with --wavelet (db2)"},
    {"brick", 0, 1, "cells per brick edge for --wavelet and cast (default 32; mc: 0 is a full inverse,\n"
                    "then dense MC)"},
    CLI_MEMORY_OPT,
    CLI_LOAD_OPTS,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

/* --method's names, in the order of the bits of method_rules */
static const char *const method_names[] = {"mc", "cast", "raytrace", "hybrid"};
enum { METHOD_COUNT = sizeof method_names / sizeof *method_names };
enum { M_MC = 1, M_CAST = 2, M_RAYTRACE = 4, M_HYBRID = 8, M_IMAGES = M_CAST | M_RAYTRACE | M_HYBRID };
static const cli_method_rule method_rules[] = {
    {"model-bound", M_CAST, "cast"},
    {"surface", M_HYBRID, "hybrid"},
    {"camera", M_IMAGES, "cast, raytrace or hybrid"},
    {"size", M_IMAGES, "cast, raytrace or hybrid"},
    {"tolerance", M_IMAGES, "cast, raytrace or hybrid"},
    {"tf", M_HYBRID, "hybrid"},
    {"spline-j", M_IMAGES, "cast, raytrace or hybrid"},
    {"chunk", M_RAYTRACE | M_HYBRID, "raytrace or hybrid"},
    {"normals", M_MC, "mc"},
    {"repeat", M_MC, "mc"},
    {"level", M_MC, "mc"},
    {"memory", M_MC, "mc"},
    {"brick", M_MC | M_CAST, "mc or cast"},
    {NULL, 0, NULL}};

typedef struct iso_args {
    const char *in, *out;
    double iso;
    int have_iso, json, threads, repeat, levels, brick, spline_j, have_keep, have_tol, surface_cast, model_bound;
    int levels_given; /* --levels said: refused beyond the volume's, not capped */
    int level;      /* mc --level: the coarser grid of this wavelet level (0: full resolution) */
    long width, height;
    double keep, tolerance, chunk;
    const char *method, *wavelet, *camera, *tf;
    wvol_iso_normals normals;
    wvol_load_options lo;
    size_t memory;  /* .wvc input: budget of the file-backed store (0: default) */
} iso_args;

/* A store of kept coefficients is made (the library's pipeline) when --wavelet or --keep says
 * which: for the mesh and the cast image alike. */
static int from_store(const iso_args *a)
{
    return a->wavelet || a->have_keep;
}

static void report(const iso_args *a, const wvol_compressed *kept, const wvol_mesh *m, const wvol_iso_stats *st, double best, double first,
                   const double cpu[2], double t_load, double t_save, const wvol_volume *coarse, double level_energy, double t_level)
{
    wvol_mesh_topo topo;
    double area = wvol_mesh_area(m), vol = wvol_mesh_volume(m), t_topo = cli_now();
    int have_topo = wvol_mesh_topology(m, &topo, NULL) == WVOL_OK;
    t_topo = cli_now() - t_topo;
    if (a->json) {
        cli_json_begin();
        cli_json_str("input", a->in);
        if (a->out) cli_json_str("output", a->out);
        cli_json_str("method", from_store(a) ? "mc-bricks" : "mc");
        if (from_store(a)) {
            cli_json_str("wavelet", wvol_store_basis(kept->store)->filter->name);
            cli_json_int("levels", kept->levels);
            cli_json_num("keep", a->keep);
        }
        if (st->bricks_total) { /* the brick path: from a store, or from a .wvc's file store */
            cli_json_int("brick", a->brick);
            cli_json_int("bricks_meshed", (long long)st->bricks_meshed);
            cli_json_num("seconds_bounds", st->seconds_bounds);
            cli_json_num("seconds_reconstruct_mesh", st->seconds_reconstruct);
        }
        cli_json_num("iso", a->iso);
        if (coarse) {
            cli_json_int("level", a->level);
            cli_json_size3("level_dims", coarse->nx, coarse->ny, coarse->nz);
            cli_json_num3("level_spacing", coarse->spacing);
            cli_json_num3("level_origin", coarse->origin);
            cli_json_num("level_energy", level_energy);
            cli_json_num("level_seconds", t_level);
        }
        cli_json_int("vertices", (long long)m->nverts);
        cli_json_int("triangles", (long long)m->ntris);
        cli_json_num("area", area);
        cli_json_num("enclosed_volume", fabs(vol));
        cli_json_num("signed_volume", vol);
        if (have_topo) {
            cli_json_int("watertight", topo.watertight);
            cli_json_int("boundary_edges", (long long)topo.boundary_edges);
            cli_json_int("euler", topo.euler);
            cli_json_int("components", (long long)topo.components);
        }
        cli_json_int("empty", st->empty);
        if (st->empty) cli_json_str("message", st->message);
        cli_json_int("cells_active", (long long)st->cells_active);
        cli_json_int("bricks_total", (long long)st->bricks_total);
        cli_json_int("bricks_skipped", (long long)st->bricks_skipped);
        if (st->bricks_total) cli_json_int("whole_inverse", st->whole_inverse);
        cli_json_open("seconds", '{');
        cli_json_num("load", t_load);
        cli_json_num("extract", best);
        cli_json_num("extract_first", first); /* a store's block view and bounds are made here */
        cli_json_num("extract_cpu", cpu[0]);  /* the least process CPU seconds of an extraction */
        cli_json_num("extract_first_cpu", cpu[1]);
        cli_json_num("classify", st->seconds[0]);
        cli_json_num("count", st->seconds[1]);
        cli_json_num("generate", st->seconds[2]);
        cli_json_num("save", t_save);
        cli_json_num("topology", t_topo); /* the mesh checks reported above */
        cli_json_close('}');
        cli_json_int("threads", a->threads);
        cli_json_int("repeat", a->repeat);
        cli_json_end();
    } else {
        if (st->empty) printf("note: %s\n", st->message);
        if (coarse)
            printf("level      %d: %zu x %zu x %zu grid, spacing %.4g %.4g %.4g (dropped detail energy %.6g; %.3f s)\n",
                   a->level, coarse->nx, coarse->ny, coarse->nz, coarse->spacing[0], coarse->spacing[1],
                   coarse->spacing[2], level_energy, t_level);
        printf("triangles  %zu\nvertices   %zu\n", m->ntris, m->nverts);
        printf("area       %.9g\nvolume     %.9g (enclosed, %s)\n", area, fabs(vol),
               have_topo && topo.watertight ? "closed surface" : "surface is open: volume is approximate");
        if (have_topo)
            printf("topology   %s, %zu component%s, Euler characteristic %lld\n",
                   topo.watertight ? "watertight" : "open", topo.components, topo.components == 1 ? "" : "s",
                   topo.euler);
        printf("time       extract %.3f ms (classify %.3f, count %.3f, generate %.3f), load %.3f s, save %.3f s\n",
               best * 1e3, st->seconds[0] * 1e3, st->seconds[1] * 1e3, st->seconds[2] * 1e3, t_load, t_save);
        if (st->bricks_total)
            printf("bricks     %zu of %zu skipped (%d^3 cells each; bounds %.3f ms, %s + mesh %.3f ms)\n",
                   st->bricks_skipped, st->bricks_total, a->brick, st->seconds_bounds * 1e3,
                   st->whole_inverse ? "whole inverse transform" : "reconstruct", st->seconds_reconstruct * 1e3);
    }
}

/* The library's pipeline for --wavelet and the tracer: transform, selection of --keep, and
 * the store. --levels beyond what the volume allows is refused when given; an image's default
 * (3) is capped to a small volume's levels. */
static int prepare_kept(const iso_args *a, const wvol_volume *v, int for_image, wvol_compressed *out,
                        wvol_error *err)
{
    wvol_compress_params cp;
    int maxl = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    wvol_compress_params_default(&cp);
    if (a->wavelet) cp.wavelet = a->wavelet;
    cp.levels = a->levels;
    if (a->levels > maxl) {
        if (!for_image || a->levels_given)
            return cli_usage("iso", "--levels %d: this volume allows 1..%d", a->levels, maxl);
        cp.levels = maxl;
    }
    if (a->spline_j) cp.store.spline_J = a->spline_j;
    if (a->keep < 1.0) {
        cp.select.mode = WVOL_SELECT_FRACTION;
        cp.select.fraction = a->keep;
    }
    if (wvol_compress(out, v, &cp, err) != WVOL_OK) return cli_fail_err("iso", err);
    return CLI_OK;
}

static int run_mc(const iso_args *a)
{
    wvol_error err;
    wvol_volume *v = NULL, *coarse = NULL;
    wvol_compressed kept;
    wvol_mesh *m = NULL;
    double level_energy = 0.0, t_level = 0.0;
    wvol_iso_params p;
    wvol_iso_stats st, best_st;
    double t0, t_load, best = INFINITY, first = 0.0, t_save = 0.0, cpu[2] = {INFINITY, 0.0};
    int r, rc = CLI_OK;

    wvol_error_clear(&err);
    t0 = cli_now();
    memset(&kept, 0, sizeof kept);
    if (wvol_path_has_ext(a->in, ".wvc") && ((a->brick != 0 && a->keep >= 1.0) || a->level > 0)) {
        /* a .wvc file: brick by brick from the file-backed store, within --memory */
        if (cli_open_wvc_store("iso", a->in, a->memory, &kept) != CLI_OK) return CLI_FAILED;
    } else if (wvol_volume_load(&v, a->in, &a->lo, &err) != WVOL_OK) {
        return cli_fail_err("iso", &err);
    }
    t_load = cli_now() - t0;
    wvol_iso_params_default(&p);
    p.threads = a->threads;
    p.normals = a->normals;
    p.brick = a->brick > 0 ? a->brick : 32;
    memset(&best_st, 0, sizeof best_st);
    if (from_store(a) && v) {
        rc = prepare_kept(a, v, 0, &kept, &err);
        if (rc != CLI_OK) goto done;
        if (a->brick != 0) { /* the brick path reads the store; only --brick 0 needs the dense coefficients */
            wvol_coeffs_destroy(kept.coeffs);
            kept.coeffs = NULL;
        }
    }
    if (a->level > 0) {
        /* the coarser grid once (the level's volume, as `wvol decompress --level` writes it),
         * then marching cubes on it */
        wvol_status s;
        double t1 = cli_now();
        if (kept.store) {
            s = wvol_store_level_volume(&coarse, kept.store, a->level, &err);
            if (s == WVOL_OK) s = wvol_store_level_energy(kept.store, a->level, &level_energy, &err);
        } else {
            const wvol_filter *f = NULL;
            s = wvol_filter_get(&f, a->wavelet ? a->wavelet : "db2", &err);
            if (s == WVOL_OK) s = wvol_volume_level(&coarse, v, f, a->level, &level_energy, &err);
        }
        if (s != WVOL_OK) {
            rc = cli_fail_err("iso", &err);
            goto done;
        }
        t_level = cli_now() - t1;
    }
    if (kept.store && v) {
        /* the store holds what the extraction reads: the volume's memory goes back before it */
        wvol_volume_destroy(v);
        v = NULL;
    }
    for (r = 0; r < a->repeat; r++) {
        double t1 = cli_now(), c1 = cli_cpu_now(), dt, dc;
        wvol_status s;
        wvol_mesh_destroy(m);
        m = NULL;
        if (coarse) {
            s = wvol_iso_extract(&m, coarse, a->iso, &p, &st, &err);
        } else if (kept.store && a->brick == 0) { /* the peer of the brick path: whole inverse, then dense MC */
            wvol_volume *rec = NULL;
            s = wvol_idwt3(&rec, kept.coeffs, &err);
            if (s == WVOL_OK) s = wvol_iso_extract(&m, rec, a->iso, &p, &st, &err);
            wvol_volume_destroy(rec);
        } else {
            s = kept.store ? wvol_iso_extract_store(&m, kept.store, a->iso, &p, &st, &err)
                           : wvol_iso_extract(&m, v, a->iso, &p, &st, &err);
        }
        if (s != WVOL_OK) {
            rc = cli_fail_err("iso", &err);
            goto done;
        }
        dt = cli_now() - t1;
        dc = cli_cpu_now() - c1;
        if (r == 0) first = dt, cpu[1] = dc;
        if (dc < cpu[0]) cpu[0] = dc;
        if (dt < best) {
            best = dt;
            best_st = st;
        }
    }
    /* a chunk of a .wvc found damaged, or a budget exceeded, while meshing fails the command
     * before any output */
    if (!v && (rc = cli_check_wvc_store("iso", &kept, 0)) != CLI_OK) goto done;
    if (a->out) {
        double t1 = cli_now();
        if (output_set_add(a->out, &err) != WVOL_OK || wvol_mesh_save(m, a->out, &err) != WVOL_OK) {
            rc = cli_fail_err("iso", &err);
            goto done;
        }
        t_save = cli_now() - t1;
    }
    if (best_st.empty && !a->json) fprintf(stderr, "wvol iso: %s\n", best_st.message);
    report(a, &kept, m, &best_st, best, first, cpu, t_load, t_save, coarse, level_energy, t_level);
done:
    wvol_volume_destroy(coarse);
    wvol_mesh_destroy(m);
    wvol_compressed_free(&kept);
    wvol_volume_destroy(v);
    return rc;
}

/* What the image methods share: the volume (or, once a store is made, nothing of it), the
 * store, the camera and the image with its depth. */
typedef struct image_job {
    wvol_volume *v;
    wvol_compressed kept;
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img;
    float *depth;
    double vmin, vmax;
} image_job;

/* Loads the input, places the camera, makes the store when `store` (then frees the dense
 * coefficients and the volume: the image methods read the store) and the image. CLI_OK, or the
 * exit code after the message. */
static int image_open(const iso_args *a, int store, image_job *j, wvol_error *err)
{
    int rc;
    memset(j, 0, sizeof *j);
    if (wvol_volume_load(&j->v, a->in, &a->lo, err) != WVOL_OK) return cli_fail_err("iso", err);
    wvol_volume_range(j->v, &j->vmin, &j->vmax, NULL);
    wvol_geometry_of_volume(&j->g, j->v);
    if (wvol_camera_parse(&j->cam, a->camera, &j->g, (int)a->width, (int)a->height, err) != WVOL_OK)
        return cli_usage("iso", "%s", err->message);
    if (store) {
        if ((rc = prepare_kept(a, j->v, 1, &j->kept, err)) != CLI_OK) return rc;
        wvol_coeffs_destroy(j->kept.coeffs);
        j->kept.coeffs = NULL;
        wvol_volume_destroy(j->v);
        j->v = NULL;
    }
    if (wvol_image_create(&j->img, (int)a->width, (int)a->height, err) != WVOL_OK) return cli_fail_err("iso", err);
    j->depth = malloc((size_t)a->width * (size_t)a->height * sizeof *j->depth);
    if (!j->depth) return cli_fail("iso", "out of memory for the depth buffer");
    return CLI_OK;
}

static void image_close(image_job *j)
{
    free(j->depth);
    wvol_image_destroy(j->img);
    wvol_compressed_free(&j->kept);
    wvol_volume_destroy(j->v);
}

/* The image and its depth to -o (.exr with Z, or .png). */
static wvol_status save_image(const char *out, const wvol_image *img, const float *depth, wvol_error *err)
{
    wvol_status s = output_set_add(out, err);
    if (!out || s) return s;
    return wvol_path_has_ext(out, ".exr") ? wvol_image_write_exr(img, out, depth, err)
                                          : wvol_image_write_png(img, out, NULL, 1.0, err);
}

/* --method cast: the surface of the trilinear interpolant, cast brick by brick from the
 * volume, or from a store of its kept coefficients when --wavelet or --keep is given. */
static int run_cast(const iso_args *a)
{
    wvol_error err;
    image_job j;
    wvol_render_source src;
    wvol_iso_cast_params cp;
    wvol_iso_cast_stats cs;
    double t0 = cli_now(), t_prep;
    int rc;

    wvol_error_clear(&err);
    if ((rc = image_open(a, from_store(a), &j, &err)) != CLI_OK) goto done;
    rc = CLI_FAILED;
    src = from_store(a) ? wvol_render_source_store(j.kept.store) : wvol_render_source_volume(j.v);
    wvol_iso_cast_params_default(&cp);
    cp.threads = a->threads;
    cp.brick = a->brick > 0 ? a->brick : 32;
    if (a->have_tol) cp.tolerance = a->tolerance;
    cp.model_bound = a->model_bound;
    t_prep = cli_now() - t0;
    if (wvol_iso_cast(j.img, j.depth, NULL, &src, &j.cam, a->iso, &cp, &cs, &err) != WVOL_OK ||
        save_image(a->out, j.img, j.depth, &err) != WVOL_OK) {
        rc = cli_fail_err("iso", &err);
        goto done;
    }
    if (cs.message[0] && !a->json) fprintf(stderr, "wvol iso: note: %s\n", cs.message);
    if (a->json) {
        cli_json_begin();
        cli_json_str("input", a->in);
        if (a->out) cli_json_str("output", a->out);
        cli_json_str("method", "cast");
        cli_json_str("source", from_store(a) ? "store" : "volume");
        if (from_store(a)) {
            cli_json_str("wavelet", wvol_store_basis(j.kept.store)->filter->name);
            cli_json_int("levels", j.kept.levels);
            cli_json_num("keep", a->keep);
        }
        cli_json_num("iso", a->iso);
        cli_json_int("width", a->width);
        cli_json_int("height", a->height);
        cli_json_int("threads", a->threads);
        cli_json_int("brick", cp.brick);
        cli_json_num("tolerance_voxels", cp.tolerance);
        cli_json_int("rays", (long long)cs.rays);
        cli_json_int("hits", (long long)cs.hits);
        cli_json_int("bricks_total", (long long)cs.bricks_total);
        cli_json_int("bricks_bound", (long long)cs.bricks_bound);
        cli_json_int("bricks_built", (long long)cs.bricks_built);
        cli_json_int("cells_tested", (long long)cs.cells_tested);
        cli_json_int("bytes", (long long)cs.bytes);
        if (a->model_bound) {
            cli_json_num("fhat_bound_max", cs.fhat_bound_max);
            cli_json_num("fhat_bound_mean", cs.fhat_bound_mean);
            cli_json_int("fhat_bound_bricks", (long long)cs.fhat_bound_bricks);
            cli_json_int("fhat_bound_faces", (long long)cs.fhat_bound_faces);
        }
        cli_json_num("prepare_seconds", t_prep);
        cli_json_num("seconds", cs.seconds);
        cli_json_num("seconds_bounds", cs.seconds_bounds);
        cli_json_num("thread_seconds_build", cs.seconds_build);
        cli_json_num("cpu_seconds", cs.cpu_seconds);
        cli_json_num("rays_per_second", cs.seconds > 0 ? (double)cs.rays / cs.seconds : 0);
        cli_json_int("empty", cs.hits == 0);
        if (cs.message[0]) cli_json_str("message", cs.message);
        cli_json_end();
    } else {
        printf("hits       %zu of %zu rays\n", cs.hits, cs.rays);
        printf("bricks     %zu of %zu built on demand, %zu decided by their bound (%d^3 cells each)\n",
               cs.bricks_built, cs.bricks_total, cs.bricks_bound, cp.brick);
        if (a->model_bound && cs.fhat_bound_bricks)
            printf("model      |f^ - interp| <= %.6g (mean %.6g) over %zu bricks; %zu at faces unbounded\n",
                   cs.fhat_bound_max, cs.fhat_bound_mean, cs.fhat_bound_bricks, cs.fhat_bound_faces);
        printf("time       %.3f s (bounds %.3f s; %.0f rays/s), preparation %.3f s\n", cs.seconds, cs.seconds_bounds,
               cs.seconds > 0 ? (double)cs.rays / cs.seconds : 0.0, t_prep);
        if (a->out) printf("wrote      %s\n", a->out);
    }
    rc = CLI_OK;
done:
    image_close(&j);
    return rc;
}

/* --method raytrace | hybrid: an image of f^ = theta traced from a store of the kept
 * coefficients (never reconstructing the volume), alone or behind the volume in front. */
static int run_image(const iso_args *a)
{
    wvol_error err;
    image_job j;
    const wvol_store *st;
    wvol_tf tf;
    wvol_iso_trace_params tp;
    wvol_iso_trace_stats ts;
    wvol_render_stats rs;
    double t0 = cli_now(), t_prep;
    int hybrid = !strcmp(a->method, "hybrid"), rc;

    wvol_error_clear(&err);
    memset(&rs, 0, sizeof rs);
    if ((rc = image_open(a, 1, &j, &err)) != CLI_OK) goto done;
    if (hybrid && (rc = cli_load_tf("iso", a->tf, j.vmin, j.vmax, &tf)) != CLI_OK) goto done;
    rc = CLI_FAILED;
    st = j.kept.store;
    wvol_iso_trace_params_default(&tp);
    tp.threads = a->threads;
    tp.tolerance = a->tolerance * fmin(j.g.spacing[0], fmin(j.g.spacing[1], j.g.spacing[2]));
    if (a->chunk > 0) tp.chunk = a->chunk;
    tp.surface = a->surface_cast ? WVOL_ISO_SURFACE_CAST : WVOL_ISO_SURFACE_EXACT;
    t_prep = cli_now() - t0;
    if (hybrid) {
        wvol_render_params rp;
        wvol_render_params_default(&rp);
        rp.threads = a->threads;
        if (wvol_iso_render_hybrid(j.img, j.depth, st, &j.cam, &tf, a->iso, &rp, &tp, &ts, &rs, &err) != WVOL_OK) goto fail;
    } else if (wvol_iso_raytrace(j.img, j.depth, NULL, st, &j.cam, a->iso, &tp, &ts, &err) != WVOL_OK) {
        goto fail;
    }
    if (save_image(a->out, j.img, j.depth, &err) != WVOL_OK) goto fail;
    if (ts.message[0] && !a->json) fprintf(stderr, "wvol iso: note: %s\n", ts.message);
    if (a->json) {
        cli_json_begin();
        cli_json_str("input", a->in);
        if (a->out) cli_json_str("output", a->out);
        cli_json_str("method", a->method);
        cli_json_str("wavelet", wvol_store_basis(st)->filter->name);
        cli_json_int("levels", j.kept.levels);
        cli_json_num("keep", a->keep);
        cli_json_int("spline_j", a->spline_j ? a->spline_j : wvol_store_basis(st)->J);
        cli_json_num("iso", a->iso);
        cli_json_int("width", a->width);
        cli_json_int("height", a->height);
        cli_json_int("threads", a->threads);
        cli_json_int("rays", (long long)ts.rays);
        cli_json_int("hits", (long long)ts.hits);
        cli_json_int("functions", (long long)ts.functions);
        cli_json_int("pieces", (long long)ts.pieces);
        cli_json_int("refined", (long long)ts.refined);
        cli_json_int("intervals", (long long)ts.intervals);
        cli_json_int("evals", (long long)ts.evals);
        cli_json_int("grazes", (long long)ts.grazes);
        cli_json_num("prepare_seconds", t_prep);
        cli_json_num("trace_seconds", ts.seconds);
        cli_json_num("trace_cpu_seconds", ts.cpu_seconds);
        cli_json_num("cells_seconds", ts.seconds_cells);
        cli_json_int("cells", (long long)ts.cells);
        cli_json_int("cells_undecided", (long long)ts.cells_undecided);
        cli_json_num("us_per_ray", ts.rays ? 1e6 * ts.seconds / (double)ts.rays : 0);
        if (hybrid) cli_json_num("volume_seconds", rs.seconds);
        cli_json_int("empty", ts.hits == 0);
        if (ts.message[0]) cli_json_str("message", ts.message);
        cli_json_end();
    } else {
        printf("hits       %zu of %zu rays (%zu grazes)\n", ts.hits, ts.rays, ts.grazes);
        printf("work       %.0f functions, %.0f pieces, %.1f refined, %.1f intervals per ray\n",
               (double)ts.functions / (double)ts.rays, (double)ts.pieces / (double)ts.rays, (double)ts.refined / (double)ts.rays,
               (double)ts.intervals / (double)ts.rays);
        printf("time       trace %.3f s (%.1f us per ray; cell grid %.3f s), preparation %.3f s\n", ts.seconds,
               1e6 * ts.seconds / (double)ts.rays, ts.seconds_cells, t_prep);
        if (hybrid) printf("volume     %.3f s (spline integrator up to the surface)\n", rs.seconds);
        if (a->out) printf("wrote      %s\n", a->out);
    }
    rc = CLI_OK;
    goto done;
fail:
    rc = cli_fail_err("iso", &err);
done:
    image_close(&j);
    return rc;
}

int wvol_cmd_iso(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val;
    int r, method = 0; /* index in method_names */
    long lv;
    iso_args a;

    memset(&a, 0, sizeof a);
    a.method = "mc";
    a.normals = WVOL_ISO_NORMALS_GRADIENT;
    a.repeat = 1;
    a.keep = 1.0;
    a.brick = 32;
    a.width = a.height = 512;
    a.tolerance = 1e-3;
    a.camera = "+z";
    a.tf = "gaussian";
    wvol_load_options_default(&a.lo);
    cli_parser_init(&p, "iso", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (a.in) return cli_usage("iso", "one input expected, got '%s' too", val);
            a.in = val;
        } else if (o->short_name == 'h') {
            cli_print_help("iso", "IN -o OUT.(ply|obj|stl|vtp|exr|png) --iso THETA [--method mc|cast|raytrace|hybrid] [--json]",
                           "Extracts the isosurface f = THETA. Marching cubes writes a mesh in world\n"
                           "coordinates with normals from the gradient; it prints triangle and vertex\n"
                           "counts, area, enclosed volume, topology and timings. An iso-value outside\n"
                           "the data range gives an empty mesh and a note, not an error.\n"
                           "cast draws the surface of the trilinear interpolant of the samples (or of\n"
                           "the store's reconstruction with --wavelet/--keep, bricks rebuilt on demand),\n"
                           "exact first crossing per cell; writes colour, alpha and depth (EXR Z).\n"
                           "raytrace traces f^ = THETA of the wavelet model from a store of the kept\n"
                           "coefficients (--wavelet, --levels, --keep) with no missed hit and writes\n"
                           "colour, alpha and depth (EXR channel Z); hybrid puts the surface behind the\n"
                           "translucent volume in front of it (--tf). See docs/iso.md.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) {
            a.out = val;
        } else if (!strcmp(o->name, "iso")) {
            if (!cli_parse_double("iso", "iso", val, &a.iso)) return CLI_USAGE;
            a.have_iso = 1;
        } else if (!strcmp(o->name, "method")) {
            for (method = 0; method < METHOD_COUNT && strcmp(val, method_names[method]); method++) {
            }
            if (method == METHOD_COUNT)
                return cli_usage("iso", "--method '%s': expected mc, cast, raytrace or hybrid", val);
            a.method = method_names[method];
        } else if (!strcmp(o->name, "model-bound")) {
            a.model_bound = 1;
        } else if (!strcmp(o->name, "surface")) {
            if (strcmp(val, "exact") && strcmp(val, "cast"))
                return cli_usage("iso", "--surface '%s': expected exact or cast", val);
            a.surface_cast = !strcmp(val, "cast");
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("iso", val, &a.threads)) return CLI_USAGE;
        } else if (!strcmp(o->name, "repeat")) {
            if (!cli_parse_long("iso", "repeat", val, 1, 1000, &lv)) return CLI_USAGE;
            a.repeat = (int)lv;
        } else if (!strcmp(o->name, "wavelet")) {
            a.wavelet = val;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long("iso", "levels", val, 1, 30, &lv)) return CLI_USAGE;
            a.levels = (int)lv;
            a.levels_given = 1;
        } else if (!strcmp(o->name, "keep")) {
            if (!cli_parse_fraction("iso", "keep", val, &a.keep)) return CLI_USAGE;
            a.have_keep = 1;
        } else if (!strcmp(o->name, "level")) {
            if (!cli_parse_long("iso", "level", val, 0, 30, &lv)) return CLI_USAGE;
            a.level = (int)lv;
        } else if (!strcmp(o->name, "brick")) {
            if (!cli_parse_long("iso", "brick", val, 0, 4096, &lv)) return CLI_USAGE;
            if (lv == 1) return cli_usage("iso", "--brick 1: bricks need at least 2 cells per edge");
            a.brick = (int)lv;
        } else if (!strcmp(o->name, "normals")) {
            if (!strcmp(val, "none")) a.normals = WVOL_ISO_NORMALS_NONE;
            else if (!strcmp(val, "gradient")) a.normals = WVOL_ISO_NORMALS_GRADIENT;
            else return cli_usage("iso", "--normals '%s': expected gradient or none", val);
        } else if (!strcmp(o->name, "json")) {
            a.json = 1;
        } else if (!strcmp(o->name, "camera")) {
            a.camera = val;
        } else if (!strcmp(o->name, "size")) {
            if (!cli_parse_size("iso", "size", val, &a.width, &a.height)) return CLI_USAGE;
        } else if (!strcmp(o->name, "tf")) {
            a.tf = val;
        } else if (!strcmp(o->name, "tolerance")) {
            if (!cli_parse_double("iso", "tolerance", val, &a.tolerance)) return CLI_USAGE;
            if (!(a.tolerance > 0)) return cli_usage("iso", "--tolerance %g: must be > 0", a.tolerance);
            a.have_tol = 1;
        } else if (!strcmp(o->name, "chunk")) {
            if (!cli_parse_double("iso", "chunk", val, &a.chunk)) return CLI_USAGE;
            if (!(a.chunk > 0)) return cli_usage("iso", "--chunk %g: must be > 0", a.chunk);
        } else if (!strcmp(o->name, "memory")) {
            if (!cli_parse_bytes("iso", "memory", val, &a.memory)) return CLI_USAGE;
        } else if (!strcmp(o->name, "spline-j")) {
            if (!cli_parse_long("iso", "spline-j", val, 1, 12, &lv)) return CLI_USAGE;
            a.spline_j = (int)lv;
        } else if ((r = cli_load_option("iso", o, val, &a.lo)) != -1) {
            if (r != CLI_OK) return r;
        }
    }
    if (!a.in) return cli_usage("iso", "missing input volume (see 'wvol iso --help')");
    if (!a.have_iso) return cli_usage("iso", "missing --iso THETA");
    if (cli_load_options_fit("iso", a.in, NULL) != CLI_OK) return CLI_USAGE;
    if ((r = cli_method_rules(&p, method_rules, method, a.method)) != CLI_OK) return r;
    if (cli_given(&p, "levels") && !from_store(&a) && ((1u << method) & (M_MC | M_CAST)))
        return cli_usage("iso", "--levels sets the levels of a store: add --wavelet or --keep (method %s)", a.method);
    if (strcmp(a.method, "mc")) {
        if (a.out && !wvol_path_has_ext(a.out, ".exr") && !wvol_path_has_ext(a.out, ".png"))
            return cli_usage("iso", "-o '%s': --method %s writes an image: .exr (with Z depth) or .png", a.out,
                             a.method);
        return !strcmp(a.method, "cast") ? run_cast(&a) : run_image(&a);
    }
    if (a.out && !wvol_path_has_ext(a.out, ".ply") && !wvol_path_has_ext(a.out, ".obj") &&
        !wvol_path_has_ext(a.out, ".stl") && !wvol_path_has_ext(a.out, ".vtp"))
        return cli_usage("iso", "-o '%s': mesh output must end in .ply, .obj, .stl or .vtp", a.out);
    return run_mc(&a);
}
