/* SPDX-License-Identifier: MIT */
/* wvol iso: isosurface of a volume as a mesh (marching cubes on the samples or,
 * with --wavelet, brick by brick from kept wavelet coefficients) or as an image
 * (guaranteed ray tracing of the wavelet model f^ = iso). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
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
    {"method", 0, 1, "mc (default), raytrace (image of f^ = theta) or hybrid (surface behind the volume)"},
    {"camera", 0, 1, "raytrace/hybrid: camera, as for wvol render (default +z)"},
    {"size", 0, 1, "raytrace/hybrid: image size WxH (default 512x512)"},
    {"tf", 0, 1, "hybrid: transfer function of the volume in front (default gaussian)"},
    {"tolerance", 0, 1, "raytrace/hybrid: depth tolerance in voxels (default 0.001)"},
    {"spline-j", 0, 1, "raytrace/hybrid: basis splines with 2^J knots per unit (default 4)"},
    {"chunk", 0, 1, "raytrace/hybrid: ray segment built at a time, voxels (default 16)"},
    {"threads", 0, 1, "threads (default: all)"},
    {"normals", 0, 1, "gradient (default) or none"},
    {"repeat", 0, 1, "extract N times and report the fastest (benchmarking)"},
    {"wavelet", 0, 1, "mesh the reconstruction of kept wavelet coefficients (haar, db2, coif1, bl3, ...);\n"
                      "raytrace/hybrid: the store's wavelet (default db2)"},
    {"levels", 0, 1, "wavelet levels (default 3)"},
    {"keep", 0, 1, "kept fraction of the coefficients, e.g. 5% (default 100%)"},
    {"brick", 0, 1, "cells per brick edge for --wavelet (default 32; 0: full inverse, then dense MC)"},
    CLI_MEMORY_OPT,
    CLI_LOAD_OPTS,
    CLI_PLACE_OPTS,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

typedef struct iso_args {
    const char *in, *out;
    double iso;
    int have_iso, json, threads, repeat, levels, brick, spline_j;
    long width, height;
    double keep, tolerance, chunk;
    const char *method, *wavelet, *camera, *tf;
    wvol_iso_normals normals;
    wvol_load_options lo;
    size_t memory;  /* .wvc input: budget of the file-backed store (0: default) */
} iso_args;

static void report(const iso_args *a, int levels, const wvol_mesh *m, const wvol_iso_stats *st, double best,
                   double t_load, double t_save)
{
    wvol_mesh_topo topo;
    double area = wvol_mesh_area(m), vol = wvol_mesh_volume(m);
    int have_topo = wvol_mesh_topology(m, &topo, NULL) == WVOL_OK;
    if (a->json) {
        cli_json_begin();
        cli_json_str("input", a->in);
        if (a->out) cli_json_str("output", a->out);
        cli_json_str("method", a->wavelet ? "mc-bricks" : "mc");
        if (a->wavelet) {
            cli_json_str("wavelet", a->wavelet);
            cli_json_int("levels", levels);
            cli_json_num("keep", a->keep);
            cli_json_int("brick", a->brick);
            cli_json_int("bricks_meshed", (long long)st->bricks_meshed);
            cli_json_num("seconds_bounds", st->seconds_bounds);
            cli_json_num("seconds_reconstruct_mesh", st->seconds_reconstruct);
        }
        cli_json_num("iso", a->iso);
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
        cli_json_open("seconds", '{');
        cli_json_num("load", t_load);
        cli_json_num("extract", best);
        cli_json_num("classify", st->seconds[0]);
        cli_json_num("count", st->seconds[1]);
        cli_json_num("generate", st->seconds[2]);
        cli_json_num("save", t_save);
        cli_json_close('}');
        cli_json_int("threads", a->threads);
        cli_json_int("repeat", a->repeat);
        cli_json_end();
    } else {
        if (st->empty) printf("note: %s\n", st->message);
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
            printf("bricks     %zu of %zu skipped (%d^3 cells each; bounds %.3f ms, reconstruct + mesh %.3f ms)\n",
                   st->bricks_skipped, st->bricks_total, a->brick, st->seconds_bounds * 1e3,
                   st->seconds_reconstruct * 1e3);
    }
}

/* The library's pipeline for --wavelet and the tracer: transform, selection of --keep, and
 * the store. --levels beyond what the volume allows is refused for meshes and capped for
 * images. */
static int prepare_kept(const iso_args *a, const wvol_volume *v, int for_image, wvol_compressed *out,
                        wvol_error *err)
{
    wvol_compress_params cp;
    int maxl = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    wvol_compress_params_default(&cp);
    if (a->wavelet) cp.wavelet = a->wavelet;
    cp.levels = a->levels;
    if (a->levels > maxl) {
        if (!for_image) return cli_usage("iso", "--levels %d: this volume allows 1..%d", a->levels, maxl);
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
    wvol_volume *v = NULL;
    wvol_compressed kept;
    wvol_mesh *m = NULL;
    wvol_iso_params p;
    wvol_iso_stats st, best_st;
    double t0, t_load, best = INFINITY, t_save = 0.0;
    int r, rc = CLI_OK;

    wvol_error_clear(&err);
    t0 = cli_now();
    memset(&kept, 0, sizeof kept);
    if (wvol_path_has_ext(a->in, ".wvc") && a->brick != 0 && a->keep >= 1.0) {
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
    if (a->wavelet && v) {
        rc = prepare_kept(a, v, 0, &kept, &err);
        if (rc != CLI_OK) goto done;
        if (a->brick != 0) { /* the brick path reads the store; only --brick 0 needs the dense coefficients */
            wvol_coeffs_destroy(kept.coeffs);
            kept.coeffs = NULL;
        }
    }
    for (r = 0; r < a->repeat; r++) {
        double t1 = cli_now(), dt;
        wvol_status s;
        wvol_mesh_destroy(m);
        m = NULL;
        if (kept.store && a->brick == 0) { /* the peer of the brick path: whole inverse, then dense MC */
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
        if (dt < best) {
            best = dt;
            best_st = st;
        }
    }
    if (a->out) {
        double t1 = cli_now();
        if (wvol_mesh_save(m, a->out, &err) != WVOL_OK) {
            rc = cli_fail_err("iso", &err);
            goto done;
        }
        t_save = cli_now() - t1;
    }
    if (best_st.empty && !a->json) fprintf(stderr, "wvol iso: %s\n", best_st.message);
    if (!v && (rc = cli_check_wvc_store("iso", &kept, 0)) != CLI_OK) goto done;
    report(a, kept.levels, m, &best_st, best, t_load, t_save);
done:
    wvol_mesh_destroy(m);
    wvol_compressed_free(&kept);
    wvol_volume_destroy(v);
    return rc;
}

/* --method raytrace | hybrid: an image of f^ = theta traced from a store of the kept
 * coefficients (never reconstructing the volume), alone or behind the volume in front. */
static int run_image(const iso_args *a)
{
    wvol_error err;
    wvol_volume *v = NULL;
    wvol_compressed kept;
    const wvol_store *st = NULL;
    wvol_image *img = NULL;
    float *depth = NULL;
    wvol_camera cam;
    wvol_geometry g;
    wvol_tf tf;
    wvol_iso_trace_params tp;
    wvol_iso_trace_stats ts;
    wvol_render_stats rs;
    double t0 = cli_now(), t_prep, vmin = 0, vmax = 1;
    int hybrid = !strcmp(a->method, "hybrid"), rc = CLI_FAILED;

    wvol_error_clear(&err);
    memset(&rs, 0, sizeof rs);
    memset(&kept, 0, sizeof kept);
    if (wvol_volume_load(&v, a->in, &a->lo, &err) != WVOL_OK) return cli_fail_err("iso", &err);
    wvol_volume_range(v, &vmin, &vmax, NULL);
    wvol_geometry_of_volume(&g, v);
    if (wvol_camera_parse(&cam, a->camera, &g, (int)a->width, (int)a->height, &err) != WVOL_OK) {
        rc = cli_usage("iso", "--camera: %s", err.message);
        goto done;
    }
    if (hybrid && (rc = cli_load_tf("iso", a->tf, vmin, vmax, &tf)) != CLI_OK) goto done;
    rc = CLI_FAILED;
    if ((rc = prepare_kept(a, v, 1, &kept, &err)) != CLI_OK) goto done;
    rc = CLI_FAILED;
    st = kept.store;
    wvol_coeffs_destroy(kept.coeffs);
    kept.coeffs = NULL;
    wvol_volume_destroy(v); /* the tracer never touches the dense volume */
    v = NULL;
    if (wvol_image_create(&img, (int)a->width, (int)a->height, &err) != WVOL_OK) goto fail;
    depth = malloc((size_t)a->width * (size_t)a->height * sizeof *depth);
    if (!depth) {
        rc = cli_fail("iso", "out of memory for the depth buffer");
        goto done;
    }
    wvol_iso_trace_params_default(&tp);
    tp.threads = a->threads;
    tp.tolerance = a->tolerance * fmin(g.spacing[0], fmin(g.spacing[1], g.spacing[2]));
    if (a->chunk > 0) tp.chunk = a->chunk;
    t_prep = cli_now() - t0;
    if (hybrid) {
        wvol_render_params rp;
        wvol_render_params_default(&rp);
        rp.threads = a->threads;
        if (wvol_iso_render_hybrid(img, depth, st, &cam, &tf, a->iso, &rp, &tp, &ts, &rs, &err) != WVOL_OK) goto fail;
    } else if (wvol_iso_raytrace(img, depth, NULL, st, &cam, a->iso, &tp, &ts, &err) != WVOL_OK) {
        goto fail;
    }
    if (a->out) {
        wvol_status s = wvol_path_has_ext(a->out, ".exr") ? wvol_image_write_exr(img, a->out, depth, &err)
                                                          : wvol_image_write_png(img, a->out, NULL, 1.0, &err);
        if (s != WVOL_OK) goto fail;
    }
    if (ts.message[0] && !a->json) fprintf(stderr, "wvol iso: note: %s\n", ts.message);
    if (a->json) {
        cli_json_begin();
        cli_json_str("input", a->in);
        if (a->out) cli_json_str("output", a->out);
        cli_json_str("method", a->method);
        cli_json_str("wavelet", wvol_store_basis(st)->filter->name);
        cli_json_int("levels", kept.levels);
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
    free(depth);
    wvol_image_destroy(img);
    wvol_compressed_free(&kept);
    wvol_volume_destroy(v);
    return rc;
}

int wvol_cmd_iso(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val;
    int r;
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
            cli_print_help("iso", "IN -o OUT.(ply|obj|stl|vtp|exr|png) --iso THETA [--method mc|raytrace|hybrid] [--json]",
                           "Extracts the isosurface f = THETA. Marching cubes writes a mesh in world\n"
                           "coordinates with normals from the gradient; it prints triangle and vertex\n"
                           "counts, area, enclosed volume, topology and timings. An iso-value outside\n"
                           "the data range gives an empty mesh and a note, not an error.\n"
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
            if (strcmp(val, "mc") && strcmp(val, "raytrace") && strcmp(val, "hybrid"))
                return cli_usage("iso", "--method '%s': expected mc, raytrace or hybrid", val);
            a.method = val;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_parse_long("iso", "threads", val, 1, 4096, &lv)) return CLI_USAGE;
            a.threads = (int)lv;
        } else if (!strcmp(o->name, "repeat")) {
            if (!cli_parse_long("iso", "repeat", val, 1, 1000, &lv)) return CLI_USAGE;
            a.repeat = (int)lv;
        } else if (!strcmp(o->name, "wavelet")) {
            a.wavelet = val;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long("iso", "levels", val, 1, 30, &lv)) return CLI_USAGE;
            a.levels = (int)lv;
        } else if (!strcmp(o->name, "keep")) {
            if (!cli_parse_fraction("iso", "keep", val, &a.keep)) return CLI_USAGE;
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
    if (strcmp(a.method, "mc")) {
        if (a.out && !wvol_path_has_ext(a.out, ".exr") && !wvol_path_has_ext(a.out, ".png"))
            return cli_usage("iso", "-o '%s': --method %s writes an image: .exr (with Z depth) or .png", a.out,
                             a.method);
        return run_image(&a);
    }
    if (a.out && !wvol_path_has_ext(a.out, ".ply") && !wvol_path_has_ext(a.out, ".obj") &&
        !wvol_path_has_ext(a.out, ".stl") && !wvol_path_has_ext(a.out, ".vtp"))
        return cli_usage("iso", "-o '%s': mesh output must end in .ply, .obj, .stl or .vtp", a.out);
    return run_mc(&a);
}
