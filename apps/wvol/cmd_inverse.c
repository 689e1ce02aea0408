/* SPDX-License-Identifier: MIT */
/* wvol inverse: reconstruct a volume (whole, coarser, or one brick) from a coefficient
 * file written by `wvol transform`. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "coeffs_file.h"
#include "volume_out.h"
#include "wvol/io.h"
#include "wvol/wavelet.h"

const char wvol_cmd_inverse_summary[] = "inverse 3D wavelet transform of a `wvol transform` coefficient file";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output volume (.raw, .nrrd, or any format wvol can write)"},
    {"level", 0, 1, "stop at this level: a coarser volume (0 = full, the default)"},
    {"brick", 0, 1, "reconstruct only the box X0,Y0,Z0,X1,Y1,Z1 (voxels [X0,X1) ...)"},
    {"f64", 0, 0, "compute in float64"},
    CLI_THREADS_OPT,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

static int parse_box(const char *s, size_t lo[3], size_t hi[3])
{
    unsigned long long v[6];
    int used = 0;
    if (sscanf(s, "%llu,%llu,%llu,%llu,%llu,%llu%n", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &used) != 6 ||
        s[used] != '\0')
        return 0;
    for (int a = 0; a < 3; a++) lo[a] = (size_t)v[a], hi[a] = (size_t)v[3 + a];
    return 1;
}

int wvol_cmd_inverse(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *in = NULL, *outp = NULL;
    int r, json = 0, f64 = 0, brick = 0;
    long level = 0;
    size_t lo[3], hi[3];
    wvol_error err;
    wvol_volume *v = NULL;
    wvol_coeffs *c = NULL;
    wvol_status st;
    double t0;

    cli_parser_init(&p, "inverse", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input("inverse", &in, val)) return CLI_USAGE;
        } else if (o->short_name == 'h') {
            cli_print_help("inverse", "COEFFS.raw -o OUT.(raw|nrrd) [--level S | --brick X0,Y0,Z0,X1,Y1,Z1] [--f64]",
                           "Inverse wavelet transform of COEFFS.raw, described by COEFFS.json (written by\n"
                           "'wvol transform'), cropped back to the original size. --level S stops at level S\n"
                           "(a volume 2^S times coarser, spacing and values rescaled); --brick reconstructs\n"
                           "one box of the full-resolution volume from the coefficients that reach it.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) {
            outp = val;
        } else if (!strcmp(o->name, "level")) {
            if (!cli_parse_long("inverse", "level", val, 0, 30, &level)) return CLI_USAGE;
        } else if (!strcmp(o->name, "brick")) {
            if (!parse_box(val, lo, hi))
                return cli_usage("inverse", "--brick '%s': expected X0,Y0,Z0,X1,Y1,Z1", val);
            brick = 1;
        } else if (!strcmp(o->name, "f64")) {
            f64 = 1;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("inverse", val, NULL)) return CLI_USAGE;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        }
    }
    if (!in) return cli_usage("inverse", "missing coefficient file (see 'wvol inverse --help')");
    if (!outp) return cli_usage("inverse", "missing -o OUT");
    if (brick && level) return cli_usage("inverse", "--brick and --level exclude each other");
    if (!wvol_format_supported(outp, 1))
        return cli_usage("inverse", "-o %s: cannot write this format (%s)", outp, cli_write_hint(outp));
    if (cli_data_file_not_input("inverse", in, outp) != CLI_OK) return CLI_USAGE;
    wvol_error_clear(&err);
    if (coeffs_file_read(&c, in, &err) != WVOL_OK) return cli_fail_err("inverse", &err);
    if (level > c->levels) {
        int L = c->levels;
        wvol_coeffs_destroy(c);
        return cli_usage("inverse", "--level %ld: the file has %d levels", level, L);
    }
    t0 = cli_now();
    if (brick) st = wvol_idwt3_brick(&v, c, lo, hi, &err);
    else if (level) st = wvol_idwt3_level(&v, c, (int)level, &err);
    else st = wvol_idwt3_ex(&v, c, f64, &err);
    t0 = cli_now() - t0;
    wvol_coeffs_destroy(c);
    if (st != WVOL_OK) return cli_fail_err("inverse", &err);
    if (volume_out_claim(outp, 0, &err) != WVOL_OK || wvol_volume_save(v, outp, &err) != WVOL_OK) {
        wvol_volume_destroy(v);
        return cli_fail_err("inverse", &err);
    }
    if (json) {
        cli_json_begin();
        cli_json_str("output", outp);
        volume_json_grid(v);
        cli_json_num("seconds", t0);
        cli_json_end();
    } else {
        printf("%s: %zu x %zu x %zu, %.3f s\n", outp, v->nx, v->ny, v->nz, t0);
    }
    wvol_volume_destroy(v);
    return CLI_OK;
}
