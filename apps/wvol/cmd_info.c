/* SPDX-License-Identifier: MIT */
/* wvol info: what a volume file (any supported format) or a .wvc store holds. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "info_wvc.h"
#include "volume_out.h"
#include "wvol/io.h"

const char wvol_cmd_info_summary[] = "describe a volume file or a .wvc store";

static const cli_opt opts[] = {
    CLI_LOAD_OPTS,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

/* Histogram summary: percentiles from a 1024-bin histogram of the range. */
static void percentiles(const wvol_volume *v, double lo, double hi, const double *q, double *out, int nq)
{
    enum { BINS = 1024 };
    size_t *hist = calloc(BINS, sizeof *hist), n = wvol_volume_count(v), i, acc = 0;
    int b, k = 0;
    double w = hi > lo ? (hi - lo) / BINS : 1.0;
    if (!hist) {
        for (k = 0; k < nq; k++) out[k] = NAN;
        return;
    }
    for (i = 0; i < n; i++) {
        b = (int)((v->data[i] - lo) / w);
        hist[b < 0 ? 0 : b >= BINS ? BINS - 1 : b]++;
    }
    for (b = 0; b < BINS && k < nq; b++) {
        acc += hist[b];
        /* a bin's upper edge, never past the maximum (a constant volume has one bin of width 0) */
        while (k < nq && (double)acc >= q[k] * (double)n) out[k++] = hi > lo ? fmin(lo + (b + 1) * w, hi) : hi;
    }
    for (; k < nq; k++) out[k] = hi;
    free(hist);
}

int wvol_cmd_info(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *path = NULL;
    int r, json = 0;
    wvol_load_options lo;
    wvol_error err;
    wvol_volume *v = NULL;
    double vmin, vmax, mean, pct[5];
    static const double q[5] = {0.01, 0.25, 0.5, 0.75, 0.99};

    wvol_load_options_default(&lo);
    cli_parser_init(&p, "info", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input("info", &path, val)) return CLI_USAGE;
        } else if (o->short_name == 'h') {
            cli_print_help("info", "FILE [--dims NXxNYxNZ --type T [--spacing X,Y,Z]] [--grid NAME] [--json]",
                           "Prints type, dimensions, spacing, origin, range and a histogram summary\n"
                           "of a volume, or the contents of a .wvc store.", opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        } else if (cli_load_option("info", o, val, &lo) == CLI_USAGE) {
            return CLI_USAGE;
        }
    }
    if (!path) return cli_usage("info", "missing input file (see 'wvol info --help')");
    if (cli_load_options_fit("info", path, NULL) != CLI_OK) return CLI_USAGE;
    if (wvol_path_has_ext(path, ".wvc")) return wvol_cli_info_wvc(path, json);

    wvol_error_clear(&err);
    if (wvol_volume_load(&v, path, &lo, &err) != WVOL_OK) return cli_fail_err("info", &err);
    wvol_volume_range(v, &vmin, &vmax, &mean);
    percentiles(v, vmin, vmax, q, pct, 5);
    if (json) {
        cli_json_begin();
        cli_json_str("file", path);
        cli_json_str("type", "float32");
        volume_json_grid(v);
        cli_json_num("min", vmin);
        cli_json_num("max", vmax);
        cli_json_num("mean", mean);
        cli_json_open("percentiles", '{');
        cli_json_num("p1", pct[0]);
        cli_json_num("p25", pct[1]);
        cli_json_num("p50", pct[2]);
        cli_json_num("p75", pct[3]);
        cli_json_num("p99", pct[4]);
        cli_json_close('}');
        cli_json_end();
    } else {
        printf("file     %s\n", path);
        printf("type     float32 samples\n");
        printf("dims     %zu x %zu x %zu (%zu voxels)\n", v->nx, v->ny, v->nz, wvol_volume_count(v));
        printf("spacing  %g %g %g\n", v->spacing[0], v->spacing[1], v->spacing[2]);
        printf("origin   %g %g %g\n", v->origin[0], v->origin[1], v->origin[2]);
        printf("range    %g .. %g (mean %g)\n", vmin, vmax, mean);
        printf("histogram percentiles  1%%: %g  25%%: %g  50%%: %g  75%%: %g  99%%: %g\n", pct[0],
               pct[1], pct[2], pct[3], pct[4]);
    }
    wvol_volume_destroy(v);
    return CLI_OK;
}
