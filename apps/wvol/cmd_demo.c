/* SPDX-License-Identifier: MIT */
/* wvol demo: the main job, run as a sequence of stages. Each stage is one
 * function that reads and fills the shared demo state, prints what it did (text
 * mode) and records its JSON fields; a new stage is one more row of the table. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "output_set.h"
#include "volume_out.h"
#include "wvol/compress.h"
#include "wvol/image.h"
#include "wvol/io.h"
#include "wvol/iso.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"
#include "wvol/render.h"
#include "wvol/wvc.h"
#include "wvol_synth.h"

const char wvol_cmd_demo_summary[] = "run the main job on a skull phantom and say what it made";

static const cli_opt opts[] = {
    {"out", 0, 1, "output folder (default out/demo)"},
    {"size", 0, 1, "phantom size N or NXxNYxNZ (default 128)"},
    {"seed", 0, 1, "phantom seed (default 1)"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

typedef struct demo {
    /* options */
    const char *out_dir;
    size_t dims[3];
    uint64_t seed;
    int json;
    /* results, filled by the stages */
    wvol_volume *phantom;
    double range[3]; /* min, max, mean */
    volume_out phantom_file;
    const char *wavelet;
    int levels;
    double keep;                 /* fraction of coefficients kept */
    wvol_compressed kept;         /* transform, selection and store of the kept coefficients */
    char image_path[4096], xray_path[4096];
    wvol_render_stats render_stats, xray_stats;
    char wvc_path[4096];         /* the kept coefficients, quantised and coded */
    size_t wvc_bytes;
    double wvc_step, wvc_pred_psnr, wvc_rmse, wvc_psnr, wvc_max, wvc_encode_s, wvc_decode_s;
    double bone_iso;             /* HU of the bone isosurface */
    char mesh_path[4096];
    size_t mesh_tris, bricks_total, bricks_skipped;
    double mesh_area;
} demo;

typedef struct demo_stage {
    const char *name;
    int (*run)(demo *d);              /* returns CLI_OK or an exit code (message printed) */
    void (*json)(const demo *d);      /* the stage's JSON fields; may be NULL */
} demo_stage;

/* ---- stage: phantom ------------------------------------------------------- */

static void progress(void *user, double f)
{
    (void)user;
    cli_progress("phantom", f);
}

static int stage_phantom(demo *d)
{
    wvol_synth_params p;
    wvol_error err;
    wvol_synth_params_default(&p);
    memcpy(p.dims, d->dims, sizeof p.dims);
    p.seed = d->seed;
    p.progress = progress;
    wvol_error_clear(&err);
    if (wvol_synth_skull(&d->phantom, NULL, &p, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    cli_progress_done();
    wvol_volume_range(d->phantom, &d->range[0], &d->range[1], &d->range[2]);
    if (!d->json)
        printf("phantom  skull %zu x %zu x %zu, spacing %g mm, values %g .. %g HU\n", d->phantom->nx,
               d->phantom->ny, d->phantom->nz, d->phantom->spacing[0], d->range[0], d->range[1]);
    return CLI_OK;
}

static void json_phantom(const demo *d)
{
    cli_json_str("kind", "skull");
    cli_json_size3("dims", d->phantom->nx, d->phantom->ny, d->phantom->nz);
    cli_json_num3("spacing", d->phantom->spacing);
    cli_json_num("min", d->range[0]);
    cli_json_num("max", d->range[1]);
    cli_json_num("mean", d->range[2]);
}

/* ---- stage: write ----------------------------------------------------------- */

static int stage_write(demo *d)
{
    char path[4096];
    wvol_error err;
    if ((size_t)snprintf(path, sizeof path, "%s/skull.nrrd", d->out_dir) >= sizeof path)
        return cli_fail("demo", "--out %s: path too long", d->out_dir);
    wvol_error_clear(&err);
    if (volume_out_save(&d->phantom_file, d->phantom, path, 0, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    if (!d->json) printf("wrote    %s (%llu bytes, NRRD)\n", path, d->phantom_file.bytes);
    return CLI_OK;
}

static void json_write(const demo *d)
{
    cli_json_str("file", d->phantom_file.path);
    cli_json_int("bytes", (long long)d->phantom_file.bytes);
}

/* ---- stage: select (the library's pipeline: transform, selection, store) -------- */

static int stage_select(demo *d)
{
    wvol_compress_params prm;
    wvol_error err;
    const wvol_select_report *r = &d->kept.report;
    wvol_compress_params_default(&prm);
    prm.wavelet = d->wavelet;
    prm.levels = d->levels;
    prm.select.mode = WVOL_SELECT_FRACTION;
    prm.select.fraction = d->keep;
    prm.select.measure = 1;
    wvol_error_clear(&err);
    if (wvol_compress(&d->kept, d->phantom, &prm, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    if (!d->json) {
        printf("transform %s, %d levels: %zu x %zu x %zu coefficients (Mallat layout)\n", d->kept.coeffs->filter->name,
               d->kept.levels, d->kept.coeffs->px, d->kept.coeffs->py, d->kept.coeffs->pz);
        printf("select   kept %zu of %zu coefficients (%.2f%%), energy kept %.6f%%\n", r->kept, r->total,
               100.0 * (double)r->kept / (double)r->total, 100.0 * r->energy_kept / r->energy_total);
        printf("error    predicted (Parseval): RMSE %.4g HU, PSNR %.2f dB\n", r->predicted_rmse, r->predicted_psnr);
        printf("         measured:             RMSE %.4g HU, PSNR %.2f dB, max %.4g HU\n", r->measured_rmse,
               r->measured_psnr, r->measured_max);
    }
    return CLI_OK;
}

static void json_select(const demo *d)
{
    const wvol_select_report *r = &d->kept.report;
    cli_json_str("wavelet", d->kept.coeffs->filter->name);
    cli_json_int("levels", d->kept.levels);
    cli_json_num("keep", d->keep);
    cli_json_int("kept", (long long)r->kept);
    cli_json_int("total", (long long)r->total);
    cli_json_num("predicted_rmse", r->predicted_rmse);
    cli_json_num("predicted_psnr", r->predicted_psnr);
    cli_json_num("measured_rmse", r->measured_rmse);
    cli_json_num("measured_psnr", r->measured_psnr);
    cli_json_num("measured_max", r->measured_max);
}

/* ---- stage: render ----------------------------------------------------------- */

static int stage_render(demo *d)
{
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_image *img = NULL;
    wvol_render_params p;
    wvol_render_source src;
    wvol_error err;
    wvol_status s;
    wvol_error_clear(&err);
    if ((size_t)snprintf(d->image_path, sizeof d->image_path, "%s/skull.png", d->out_dir) >= sizeof d->image_path)
        return cli_fail("demo", "--out %s: path too long", d->out_dir);
    if (output_set_add(d->image_path, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    wvol_geometry_of_volume(&g, d->phantom);
    wvol_render_params_default(&p);
    p.shading = 1;
    p.step = 0.25; /* thin bone at high opacity: a finer step keeps sampling rings faint */
    src = wvol_render_source_volume(d->phantom);
    s = wvol_camera_parse(&cam, "persp dir=0.35,1,-0.3 fov=30 zoom=1.5", &g, 512, 512, &err);
    if (s == WVOL_OK) s = wvol_tf_preset(&tf, "ct-bone", 0, 0, &err);
    if (s == WVOL_OK) s = wvol_image_create(&img, 512, 512, &err);
    if (s == WVOL_OK) s = wvol_render(img, &src, &cam, &tf, &p, &d->render_stats, &err);
    if (s == WVOL_OK) s = wvol_image_write_png(img, d->image_path, NULL, 1.0, &err);
    wvol_image_destroy(img);
    img = NULL;
    if (s != WVOL_OK) return cli_fail_err("demo", &err);
    if (!d->json)
        printf("render   %s (512 x 512, ct-bone, reference caster, %.2f s)\n", d->image_path, d->render_stats.seconds);

    /* an X-ray from the kept coefficients alone: the store (the library picks the axis fast
     * path where it applies) */
    if ((size_t)snprintf(d->xray_path, sizeof d->xray_path, "%s/skull_xray.png", d->out_dir) >= sizeof d->xray_path)
        return cli_fail("demo", "--out %s: path too long", d->out_dir);
    if (output_set_add(d->xray_path, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    wvol_render_params_default(&p);
    p.mode = WVOL_RENDER_MODE_XRAY;
    src = wvol_render_source_store(d->kept.store);
    s = wvol_camera_parse(&cam, "-y", &g, 512, 512, &err);
    if (s == WVOL_OK) s = wvol_image_create(&img, 512, 512, &err);
    if (s == WVOL_OK) s = wvol_render(img, &src, &cam, NULL, &p, &d->xray_stats, &err);
    if (s == WVOL_OK) {
        size_t i, n = (size_t)512 * 512;
        double lo = INFINITY, hi = -INFINITY;
        /* window the projection to its own range: air is negative in HU */
        for (i = 0; i < n; i++) lo = fmin(lo, img->rgba[4 * i]), hi = fmax(hi, img->rgba[4 * i]);
        for (i = 0; i < n; i++)
            for (int c = 0; c < 3; c++)
                img->rgba[4 * i + c] = hi > lo ? (float)((img->rgba[4 * i + c] - lo) / (hi - lo)) : 0.0f;
        s = wvol_image_write_png(img, d->xray_path, NULL, 1.0, &err);
    }
    wvol_image_destroy(img);
    if (s != WVOL_OK) return cli_fail_err("demo", &err);
    if (!d->json)
        printf("render   %s (512 x 512, X-ray from the %.0f%% store alone, %s, %.3f s)\n", d->xray_path,
               100.0 * d->keep, wvol_render_method_name(d->xray_stats.method), d->xray_stats.seconds);
    return CLI_OK;
}

static void json_render(const demo *d)
{
    cli_json_str("image", d->image_path);
    cli_json_str("method", "reference");
    cli_json_num("render_seconds", d->render_stats.seconds);
    cli_json_str("xray_image", d->xray_path);
    cli_json_str("xray_method", wvol_render_method_name(d->xray_stats.method));
    cli_json_num("xray_seconds", d->xray_stats.seconds);
}

/* ---- stage: compress (the kept coefficients into a .wvc file, decoded back) ----- */

static int stage_compress(demo *d)
{
    wvol_coeffs *back = NULL;
    wvol_volume *rec = NULL;
    wvol_compress_params prm;
    wvol_wvc_report wr;
    wvol_error err;
    void *buf = NULL;
    size_t n = 0, nvox = wvol_volume_count(d->phantom);
    double sse = 0, t0;
    int code = CLI_OK;
    wvol_error_clear(&err);
    if ((size_t)snprintf(d->wvc_path, sizeof d->wvc_path, "%s/skull.wvc", d->out_dir) >= sizeof d->wvc_path)
        return cli_fail("demo", "--out %s: path too long", d->out_dir);
    if (output_set_add(d->wvc_path, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    /* the library's quantiser rule: 2% of the energy the selection dropped (RMSE +1%) */
    wvol_compress_params_default(&prm);
    t0 = cli_now();
    if (wvol_compress_encode(&buf, &n, &d->kept, &prm, &wr, &err) != WVOL_OK ||
        wvol_wvc_save(d->wvc_path, buf, n, &err) != WVOL_OK) {
        code = cli_fail_err("demo", &err);
        goto done;
    }
    d->wvc_encode_s = cli_now() - t0;
    t0 = cli_now();
    if (wvol_wvc_read(&back, d->wvc_path, NULL, NULL, &err) != WVOL_OK || wvol_idwt3(&rec, back, &err) != WVOL_OK ||
        wvol_wvc_compare(&sse, &d->wvc_max, d->phantom, rec, &err) != WVOL_OK) {
        code = cli_fail_err("demo", &err);
        goto done;
    }
    d->wvc_decode_s = cli_now() - t0;
    d->wvc_bytes = n;
    d->wvc_step = wr.step;
    d->wvc_pred_psnr =
        wvol_wvc_psnr(d->kept.report.energy_dropped + wr.sse_quant, (double)nvox, d->range[0], d->range[1]);
    d->wvc_rmse = sqrt(sse / (double)nvox);
    d->wvc_psnr = wvol_wvc_psnr(sse, (double)nvox, d->range[0], d->range[1]);
    if (!d->json) {
        printf("compress wrote %s: %zu bytes, ratio %.1f, %.3f bits/voxel (step %.4g, encode %.2f s)\n", d->wvc_path, n,
               4.0 * (double)nvox / (double)n, 8.0 * (double)n / (double)nvox, wr.step, d->wvc_encode_s);
        printf("         decoded: predicted PSNR %.2f dB; measured RMSE %.4g HU, PSNR %.2f dB, max %.4g HU\n",
               d->wvc_pred_psnr, d->wvc_rmse, d->wvc_psnr, d->wvc_max);
    }
done:
    free(buf);
    wvol_volume_destroy(rec);
    wvol_coeffs_destroy(back);
    return code;
}

static void json_compress(const demo *d)
{
    size_t nvox = wvol_volume_count(d->phantom);
    cli_json_str("file", d->wvc_path);
    cli_json_int("bytes", (long long)d->wvc_bytes);
    cli_json_num("ratio", 4.0 * (double)nvox / (double)d->wvc_bytes);
    cli_json_num("bits_per_voxel", 8.0 * (double)d->wvc_bytes / (double)nvox);
    cli_json_num("step", d->wvc_step);
    cli_json_num("predicted_psnr", d->wvc_pred_psnr);
    cli_json_num("measured_rmse", d->wvc_rmse);
    cli_json_num("measured_psnr", d->wvc_psnr);
    cli_json_num("measured_max", d->wvc_max);
    cli_json_num("encode_seconds", d->wvc_encode_s);
    cli_json_num("decode_seconds", d->wvc_decode_s);
}

/* ---- stage: mesh (bone isosurface from the kept coefficients) ---------------- */

static int stage_mesh(demo *d)
{
    wvol_mesh *mesh = NULL;
    wvol_iso_params prm;
    wvol_iso_stats st;
    wvol_error err;
    int code = CLI_OK;
    wvol_error_clear(&err);
    if ((size_t)snprintf(d->mesh_path, sizeof d->mesh_path, "%s/bone.ply", d->out_dir) >= sizeof d->mesh_path)
        return cli_fail("demo", "--out %s: path too long", d->out_dir);
    if (output_set_add(d->mesh_path, &err) != WVOL_OK) return cli_fail_err("demo", &err);
    wvol_iso_params_default(&prm);
    /* marching cubes brick by brick on the 5% reconstruction: only bricks whose
     * coefficient bound straddles the iso-value are reconstructed */
    if (wvol_iso_extract_store(&mesh, d->kept.store, d->bone_iso, &prm, &st, &err) != WVOL_OK ||
        wvol_mesh_save(mesh, d->mesh_path, &err) != WVOL_OK) {
        code = cli_fail_err("demo", &err);
    } else {
        d->mesh_tris = mesh->ntris;
        d->mesh_area = wvol_mesh_area(mesh);
        d->bricks_total = st.bricks_total;
        d->bricks_skipped = st.bricks_skipped;
        if (!d->json)
            printf("mesh     bone at %g HU from the 5%% store: %zu triangles, area %.0f mm^2, "
                   "%zu of %zu bricks skipped\n         wrote %s\n",
                   d->bone_iso, mesh->ntris, d->mesh_area, st.bricks_skipped, st.bricks_total, d->mesh_path);
    }
    wvol_mesh_destroy(mesh);
    return code;
}

static void json_mesh(const demo *d)
{
    cli_json_num("iso", d->bone_iso);
    cli_json_str("file", d->mesh_path);
    cli_json_int("triangles", (long long)d->mesh_tris);
    cli_json_num("area", d->mesh_area);
    cli_json_int("bricks_total", (long long)d->bricks_total);
    cli_json_int("bricks_skipped", (long long)d->bricks_skipped);
}

/* ---- the sequence ------------------------------------------------------------ */

static const demo_stage stages[] = {
    {"phantom", stage_phantom, json_phantom},
    {"write", stage_write, json_write},
    {"select", stage_select, json_select},
    {"render", stage_render, json_render},
    {"compress", stage_compress, json_compress},
    {"mesh", stage_mesh, json_mesh},
};
enum { STAGE_COUNT = sizeof stages / sizeof stages[0] };

static void demo_free(demo *d)
{
    wvol_compressed_free(&d->kept);
    wvol_volume_destroy(d->phantom);
}

int wvol_cmd_demo(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val;
    int r, s, e, code = CLI_OK;
    demo d;
    double t_start, t[STAGE_COUNT];

    memset(&d, 0, sizeof d);
    d.out_dir = "out/demo";
    d.dims[0] = d.dims[1] = d.dims[2] = 128;
    d.seed = 1;
    d.wavelet = "db2";
    d.levels = 3;
    d.keep = 0.05;
    d.bone_iso = 400.0;
    cli_parser_init(&p, "demo", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) return cli_usage("demo", "unexpected argument '%s' (see 'wvol demo --help')", val);
        if (o->short_name == 'h') {
            cli_print_help("demo", "[--out DIR] [--size N] [--seed S] [--json]",
                           "The main job: makes a skull-like CT phantom and writes it as NRRD, transforms it\n"
                           "(db2, 3 levels), keeps 5% of the coefficients and prints the predicted and\n"
                           "measured error, quantises and codes the kept coefficients into skull.wvc and\n"
                           "measures what the file decodes to, "
                           "printing what each stage made and how long it took.", opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "json")) {
            d.json = 1;
        } else if (!strcmp(o->name, "out")) {
            if (!*val) return cli_usage("demo", "--out: empty folder name");
            d.out_dir = val;
        } else if (!strcmp(o->name, "size")) {
            size_t bytes;
            if (!cli_parse_dims("demo", "size", val, d.dims)) return CLI_USAGE;
            if (!wvol_size_mul3(d.dims[0], d.dims[1], d.dims[2], sizeof(float), &bytes) || bytes > ((size_t)-1 >> 1))
                return cli_usage("demo", "--size %s: the voxel count overflows the address space", val);
            /* refused before any stage runs: the transform's levels need the size */
            if (wvol_dwt_max_levels(d.dims[0], d.dims[1], d.dims[2]) < d.levels)
                return cli_usage("demo", "--size %s: too small for the demo's %d wavelet levels (at least %d per axis)",
                                 val, d.levels, 1 << d.levels);
        } else if (!strcmp(o->name, "seed")) {
            if (!parse_seed("demo", val, &d.seed)) return CLI_USAGE;
        }
    }
    if ((e = cli_make_dirs(d.out_dir)) != 0) return cli_fail("demo", "cannot create output folder %s: %s", d.out_dir, strerror(e));

    t_start = cli_now();
    for (s = 0; s < STAGE_COUNT && code == CLI_OK; s++) {
        double t0 = cli_now();
        code = stages[s].run(&d);
        t[s] = cli_now() - t0;
    }
    if (code != CLI_OK) {
        demo_free(&d);
        return code;
    }
    if (d.json) {
        cli_json_begin();
        cli_json_str("command", "demo");
        cli_json_str("out", d.out_dir);
        cli_json_open("stages", '[');
        for (s = 0; s < STAGE_COUNT; s++) {
            cli_json_open(NULL, '{');
            cli_json_str("name", stages[s].name);
            cli_json_num("seconds", t[s]);
            if (stages[s].json) stages[s].json(&d);
            cli_json_close('}');
        }
        cli_json_close(']');
        cli_json_num("seconds", cli_now() - t_start);
        cli_json_end();
    } else {
        printf("timings ");
        for (s = 0; s < STAGE_COUNT; s++) printf(" %s %.2f s,", stages[s].name, t[s]);
        printf(" total %.2f s\nresults  %s/\n", cli_now() - t_start, d.out_dir);
    }
    demo_free(&d);
    return CLI_OK;
}
