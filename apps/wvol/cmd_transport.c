/* SPDX-License-Identifier: MIT */
/* wvol transport: the stained-glass experiment of Lewis & Fournier 2002 (§7.3): light through a
 * window onto a floor by wavelet radiative transfer in Nusselt coordinates; writes the pictures
 * of the paper's Figs. 13-16 and reports the work done. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "output_set.h"
#include "wvol/image.h"
#include "wvol/transport.h"

const char wvol_cmd_transport_summary[] = "wavelet radiative transfer: light through a window onto a floor";

static const cli_opt opts[] = {
    {"window", 0, 1, "window image: an RGB PNG (default: the built-in stained glass)"},
    {"quadrature", 'q', 1, "trapezoid romberg1 romberg2 romberg3 monte-carlo stratified halton hammersley"},
    {"samples", 0, 1, "integrand evaluations per transport coefficient (default 16)"},
    {"levels", 'l', 1, "Haar levels: 2^L cells per axis of (u, v, k, l), 1..5 (default 3)"},
    {"keep", 0, 1, "fraction of coefficients the compressed result keeps (default 5%)"},
    {"size", 0, 1, "floor frames WxH (default 320x240)"},
    {"threads", 't', 1, "threads (default: all cores, or OMP_NUM_THREADS)"},
    {"output", 'o', 1, "output folder (required)"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

typedef struct outputs {
    const char *dir;
    char path[4200];
    wvol_error err;
} outputs;

static const char *out_path(outputs *o, const char *name)
{
    snprintf(o->path, sizeof o->path, "%s/%s", o->dir, name);
    return o->path;
}

/* 1 / the largest cell value (of any channel): the pictures' exposure */
static double exposure_of(const wvol_transport_tree *t)
{
    size_t n = 3 * wvol_transport_cells_count(wvol_transport_tree_levels(t));
    float *c = malloc(n * sizeof *c);
    double mx = 0;
    if (c && wvol_transport_tree_to_cells(c, n, t, NULL) == WVOL_OK)
        for (size_t i = 0; i < n; i++) mx = fmax(mx, c[i]);
    free(c);
    return mx > 0 ? 1 / mx : 1;
}

/* relative L2 distance between two trees' cells */
static double tree_distance(const wvol_transport_tree *a, const wvol_transport_tree *b)
{
    size_t n = 3 * wvol_transport_cells_count(wvol_transport_tree_levels(a));
    float *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
    double num = 0, den = 0;
    if (x && y && wvol_transport_tree_to_cells(x, n, a, NULL) == WVOL_OK &&
        wvol_transport_tree_to_cells(y, n, b, NULL) == WVOL_OK)
        for (size_t i = 0; i < n; i++) num += (x[i] - y[i]) * (double)(x[i] - y[i]), den += (double)x[i] * x[i];
    free(x);
    free(y);
    return den > 0 ? sqrt(num / den) : 0;
}

static int write_image(outputs *o, wvol_image *img, const char *stem, int exr)
{
    char name[256];
    wvol_status s;
    snprintf(name, sizeof name, "%s.png", stem);
    s = output_set_add(out_path(o, name), &o->err);
    if (s == WVOL_OK) s = wvol_image_write_png(img, o->path, NULL, 1, &o->err);
    if (s == WVOL_OK && exr) {
        snprintf(name, sizeof name, "%s.exr", stem);
        s = output_set_add(out_path(o, name), &o->err);
        if (s == WVOL_OK) s = wvol_image_write_exr(img, o->path, NULL, &o->err);
    }
    wvol_image_destroy(img);
    return s == WVOL_OK ? 0 : -1;
}

int wvol_cmd_transport(int argc, char **argv)
{
    static const double eyes[4][3] = {{1, -2.6, 2.2}, {4.2, 0.5, 1.6}, {-2.2, 2.8, 2.0}, {1.0, 0.45, 4.5}};
    const double center[3] = {1, 0.5, 0};
    cli_parser p;
    const cli_opt *o;
    const char *val, *window_path = NULL;
    int r, json = 0, code = CLI_FAILED;
    long lv, ns, fw = 320, fh = 240;
    double keep = 0.05, t0, exp_in, exp_out, dist = 0;
    size_t kept = 0, before;
    wvol_transport_params tp;
    wvol_transport_scene sc;
    wvol_transport_window win = {0};
    wvol_transport_scene_result res = {0};
    wvol_transport_tree *comp = NULL;
    wvol_image *img = NULL;
    outputs out = {0};
    wvol_status s;
    double pw_src[3], pw_in[3], pw_out[3];

    wvol_transport_params_default(&tp);
    wvol_transport_scene_default(&sc);
    cli_parser_init(&p, "transport", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) return cli_usage("transport", "unexpected argument '%s'", val);
        if (o->short_name == 'h') {
            cli_print_help("transport", "[--window PNG] [--quadrature RULE] [--levels L] -o OUTDIR [--json]",
                           "Light shining down through a square stained-glass window onto a floor, computed as\n"
                           "4D Haar radiance in Nusselt coordinates (Lewis & Fournier 2002, docs/transport.md).\n"
                           "Writes window.png; incident.png/.exr (Fig. 14: one floor image per direction cell),\n"
                           "detail.png (Fig. 15), incident_keep.png (the result with only --keep of its\n"
                           "coefficients), reflected.png, and floor_0..3.png/.exr (Fig. 16: the floor from four\n"
                           "view points, sampled from the reflected wavelet representation).",
                           opts);
            return CLI_OK;
        }
        if (!strcmp(o->name, "json")) json = 1;
        else if (!strcmp(o->name, "window")) window_path = val;
        else if (!strcmp(o->name, "output")) out.dir = val;
        else if (!strcmp(o->name, "quadrature")) {
            int q = wvol_transport_quadrature_find(val);
            if (q < 0) return cli_usage("transport", "--quadrature: unknown rule '%s'", val);
            tp.quadrature = (wvol_transport_quadrature)q;
        } else if (!strcmp(o->name, "samples")) {
            if (!cli_parse_long("transport", "samples", val, 1, 1 << 20, &ns)) return CLI_USAGE;
            tp.samples = (int)ns;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long("transport", "levels", val, 1, 5, &lv)) return CLI_USAGE;
            tp.levels = (int)lv;
        } else if (!strcmp(o->name, "keep")) {
            if (!cli_parse_fraction("transport", "keep", val, &keep)) return CLI_USAGE;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("transport", val, &tp.threads)) return CLI_USAGE;
        } else if (!strcmp(o->name, "size")) {
            if (!cli_parse_size("transport", "size", val, &fw, &fh)) return CLI_USAGE;
        }
    }
    if (!out.dir) return cli_usage("transport", "an output folder is required (-o OUTDIR)");
    t0 = cli_now();
    /* the input first: a window that cannot be read leaves no output folder behind */
    s = window_path ? wvol_transport_window_read_png(&win, window_path, &out.err)
                    : wvol_transport_window_synthetic(&win, 256, &out.err);
    if (s != WVOL_OK) goto fail;
    if ((r = cli_make_dirs(out.dir)) != 0) {
        code = cli_fail("transport", "cannot create output folder %s: %s", out.dir, strerror(r));
        goto done;
    }
    if (output_set_add(out_path(&out, "window.png"), &out.err) != WVOL_OK ||
        wvol_png_write(out.path, win.width, win.height, 3, win.rgb, &out.err) != WVOL_OK)
        goto fail;
    if (wvol_transport_scene_run(&res, &sc, &win, &tp, &out.err) != WVOL_OK) goto fail;
    exp_in = exposure_of(res.incident);
    exp_out = exposure_of(res.reflected);
    if (wvol_transport_grid_image(&img, res.incident, 4, exp_in, &out.err) != WVOL_OK ||
        write_image(&out, img, "incident", 1))
        goto fail;
    if (wvol_transport_detail_image(&img, res.incident, 32, exp_in, &out.err) != WVOL_OK ||
        write_image(&out, img, "detail", 0))
        goto fail;
    if (wvol_transport_grid_image(&img, res.reflected, 4, exp_out, &out.err) != WVOL_OK ||
        write_image(&out, img, "reflected", 0))
        goto fail;
    /* the result with 95% (by default) of its coefficients dropped */
    {
        size_t nc = 3 * wvol_transport_cells_count(tp.levels);
        float *cells = malloc(nc * sizeof *cells);
        if (!cells) {
            wvol_error_set(&out.err, WVOL_ERR_NOMEM, "out of memory");
            goto fail;
        }
        s = wvol_transport_tree_to_cells(cells, nc, res.incident, &out.err);
        if (s == WVOL_OK) s = wvol_transport_tree_from_cells(&comp, cells, tp.levels, 0, &out.err);
        free(cells);
        if (s != WVOL_OK) goto fail;
        before = wvol_transport_tree_coefficients(comp);
        if (wvol_transport_tree_compress(comp, keep, &kept, &out.err) != WVOL_OK) goto fail;
        dist = tree_distance(res.incident, comp);
        if (wvol_transport_grid_image(&img, comp, 4, exp_in, &out.err) != WVOL_OK ||
            write_image(&out, img, "incident_keep", 0))
            goto fail;
    }
    for (int v = 0; v < 4; v++) {
        char stem[32];
        snprintf(stem, sizeof stem, "floor_%d", v);
        if (wvol_transport_floor_image(&img, res.reflected, &sc.floor, eyes[v], center, 40, (int)fw, (int)fh,
                                       2 * exp_out, &out.err) != WVOL_OK ||
            write_image(&out, img, stem, 1))
            goto fail;
    }
    wvol_transport_tree_power_emitted(pw_src, res.source, &sc.window, NULL);
    wvol_transport_tree_power(pw_in, res.incident, &sc.floor, NULL);
    wvol_transport_tree_power(pw_out, res.reflected, &sc.floor, NULL);
    if (json) {
        cli_json_begin();
        cli_json_str("quadrature", wvol_transport_quadrature_name(tp.quadrature));
        cli_json_int("levels", tp.levels);
        cli_json_int("samples", tp.samples);
        cli_json_str("window", window_path ? window_path : "synthetic");
        cli_json_int("source_nodes", (long long)wvol_transport_tree_nodes(res.source));
        cli_json_int("incident_coefficients", (long long)wvol_transport_tree_coefficients(res.incident));
        cli_json_int("coefficients_evaluated", (long long)res.transport.evaluated);
        cli_json_int("oracle_zero", (long long)res.transport.oracle_zero);
        cli_json_int("oracle_exact", (long long)res.transport.oracle_exact);
        cli_json_int("integrand_samples", (long long)res.transport.samples);
        cli_json_num("transport_seconds", res.transport.seconds);
        cli_json_num("reflect_seconds", res.seconds_reflect);
        cli_json_num3("power_window", pw_src);
        cli_json_num3("power_floor_in", pw_in);
        cli_json_num3("power_floor_out", pw_out);
        cli_json_num("keep", keep);
        cli_json_int("kept_coefficients", (long long)kept);
        cli_json_int("coefficients_before", (long long)before);
        cli_json_num("kept_relative_l2_error", dist);
        cli_json_num("seconds", cli_now() - t0);
        cli_json_str("output", out.dir);
        cli_json_end();
    } else {
        printf("transport %s, %d samples, %d levels: %zu coefficients integrated, oracle %zu zero / %zu exact, "
               "%.2f s\n",
               wvol_transport_quadrature_name(tp.quadrature), tp.samples, tp.levels, res.transport.evaluated,
               res.transport.oracle_zero, res.transport.oracle_exact, res.transport.seconds);
        printf("power (RGB): window %.4g %.4g %.4g, floor receives %.4g %.4g %.4g, reflects %.4g %.4g %.4g\n",
               pw_src[0], pw_src[1], pw_src[2], pw_in[0], pw_in[1], pw_in[2], pw_out[0], pw_out[1], pw_out[2]);
        printf("keeping %.3g%%: %zu of %zu coefficients, relative L2 error %.3g\n", 100 * keep, kept, before, dist);
        printf("wrote %s/{window,incident,detail,reflected,incident_keep,floor_0..3}.png (+ .exr)\n", out.dir);
    }
    code = CLI_OK;
    goto done;
fail:
    code = cli_fail_err("transport", &out.err);
done:
    wvol_transport_tree_destroy(comp);
    wvol_transport_scene_result_free(&res);
    wvol_transport_window_free(&win);
    return code;
}
