/* SPDX-License-Identifier: MIT */
/* wvol transform: forward 3D wavelet transform of a volume into a coefficient file. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "coeffs_file.h"
#include "wvol/io.h"
#include "wvol/wavelet.h"

const char wvol_cmd_transform_summary[] = "forward 3D wavelet transform into raw Mallat-layout coefficients";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output coefficients OUT.raw (sidecar OUT.json beside it)"},
    {"wavelet", 'w', 1, "filter: haar, db1..db10, coif1..coif5, bl3 (default db2)"},
    {"levels", 'l', 1, "levels 1..max (default min(3, max))"},
    {"pad", 0, 1, "padding to a multiple of 2^levels: edge (default), zero, periodic"},
    {"f64", 0, 0, "compute in float64 (coefficients are still stored as float32)"},
    CLI_LOAD_OPTS,
    CLI_THREADS_OPT,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

int wvol_cmd_transform(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *in = NULL, *outp = NULL, *wname = "db2", *padname = "edge";
    int r, json = 0, f64 = 0, max;
    long levels = 0;
    wvol_pad_mode pad = WVOL_PAD_EDGE;
    wvol_load_options lo;
    wvol_error err;
    wvol_volume *v = NULL;
    wvol_coeffs *c = NULL;
    const wvol_filter *f;
    double t0;

    wvol_load_options_default(&lo);
    cli_parser_init(&p, "transform", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input("transform", &in, val)) return CLI_USAGE;
        } else if (o->short_name == 'h') {
            cli_print_help("transform", "IN -o OUT.raw [--wavelet db2] [--levels 3] [--pad edge] [--f64]",
                           "Forward separable periodic 3D wavelet transform (non-standard, Mallat layout).\n"
                           "Sizes that are not multiples of 2^levels are padded; 1-voxel axes are not\n"
                           "transformed. OUT.raw: px*py*pz float32 little-endian, x fastest; OUT.json: the\n"
                           "sidecar (wavelet, levels, original and padded sizes; docs/wavelets.md).",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) {
            outp = val;
        } else if (!strcmp(o->name, "wavelet")) {
            wname = val;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long("transform", "levels", val, 1, 30, &levels)) return CLI_USAGE;
        } else if (!strcmp(o->name, "pad")) {
            padname = val;
            if (!strcmp(val, "edge")) pad = WVOL_PAD_EDGE;
            else if (!strcmp(val, "zero")) pad = WVOL_PAD_ZERO;
            else if (!strcmp(val, "periodic")) pad = WVOL_PAD_PERIODIC;
            else return cli_usage("transform", "--pad '%s': expected edge, zero or periodic", val);
        } else if (!strcmp(o->name, "f64")) {
            f64 = 1;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("transform", val, NULL)) return CLI_USAGE;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        } else if (cli_load_option("transform", o, val, &lo) == CLI_USAGE) {
            return CLI_USAGE;
        }
    }
    if (!in) return cli_usage("transform", "missing input file (see 'wvol transform --help')");
    if (!outp) return cli_usage("transform", "missing -o OUT.raw");
    /* headerless coefficients: a name that says a volume format would be read as one */
    if (!wvol_path_has_ext(outp, ".raw"))
        return cli_usage("transform", "-o %s: the coefficients are written as OUT.raw (and OUT.json)", outp);
    wvol_error_clear(&err);
    if (wvol_filter_get(&f, wname, &err) != WVOL_OK) return cli_usage("transform", "--wavelet: %s", err.message);
    if (cli_load_options_fit("transform", in, NULL) != CLI_OK) return CLI_USAGE;
    if (wvol_volume_load(&v, in, &lo, &err) != WVOL_OK) return cli_fail_err("transform", &err);
    max = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    if (levels == 0) levels = max < 3 ? max : 3;
    if (levels < 1 || levels > max) {
        size_t d[3] = {v->nx, v->ny, v->nz};
        wvol_volume_destroy(v);
        if (max == 0) return cli_usage("transform", "a 1 x 1 x 1 volume cannot be transformed");
        return cli_usage("transform", "--levels %ld: a %zu x %zu x %zu volume allows 1..%d", levels, d[0], d[1],
                         d[2], max);
    }
    t0 = cli_now();
    if (wvol_dwt3_ex(&c, v, f, (int)levels, pad, f64, &err) != WVOL_OK) {
        wvol_volume_destroy(v);
        return cli_fail_err("transform", &err);
    }
    t0 = cli_now() - t0;
    wvol_volume_destroy(v);
    if (coeffs_file_write(c, outp, padname, f64 ? "float64" : "float32", &err) != WVOL_OK) {
        wvol_coeffs_destroy(c);
        return cli_fail_err("transform", &err);
    }
    if (json) {
        cli_json_begin();
        cli_json_str("output", outp);
        cli_json_str("wavelet", f->name);
        cli_json_int("levels", levels);
        cli_json_size3("dims", c->nx, c->ny, c->nz);
        cli_json_size3("padded", c->px, c->py, c->pz);
        cli_json_num("seconds", t0);
        cli_json_end();
    } else {
        printf("%s: %s, %ld levels, %zu x %zu x %zu (padded %zu x %zu x %zu), %.3f s\n", outp, f->name, levels,
               c->nx, c->ny, c->nz, c->px, c->py, c->pz, t0);
    }
    wvol_coeffs_destroy(c);
    return CLI_OK;
}
