/* SPDX-License-Identifier: MIT */
/* wvol decompress: .wvc -> volume (.raw, .nrrd, or any format the build writes),
 * optionally stopping after a coarser level. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "wvol/io.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

const char wvol_cmd_decompress_summary[] = "decode a .wvc file into a volume (optionally a coarser level)";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output volume OUT.raw, OUT.nrrd (or another format this build writes)"},
    {"level", 0, 1, "stop after this level: 0 = full resolution (default), m = the level-m low-pass volume"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

int wvol_cmd_decompress(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *in = NULL, *outp = NULL;
    int r, json = 0, rc = CLI_FAILED;
    long level = 0;
    wvol_error err;
    wvol_wvc_read_options ro;
    wvol_wvc_info *info = NULL;
    wvol_coeffs *c = NULL;
    wvol_volume *v = NULL;
    double t0, t_read, t_inv, t_write;

    cli_parser_init(&p, "decompress", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input("decompress", &in, val)) return CLI_USAGE;
        } else if (o->short_name == 'h') {
            cli_print_help("decompress", "IN.wvc -o OUT.(raw|nrrd) [--level m] [--json]",
                           "Decodes a .wvc file and reconstructs the volume. With --level m only the levels\n"
                           "coarser than m are read (the file is read up to there) and the result is the\n"
                           "level-m low-pass volume: 2^m times coarser, spacing 2^m times larger.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) {
            outp = val;
        } else if (!strcmp(o->name, "level")) {
            if (!cli_parse_long("decompress", "level", val, 0, 30, &level)) return CLI_USAGE;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        }
    }
    if (!in) return cli_usage("decompress", "missing input file (see 'wvol decompress --help')");
    if (!outp) return cli_usage("decompress", "missing -o OUT.raw or OUT.nrrd");
    if (!wvol_format_supported(outp, 1))
        return cli_usage("decompress", "-o %s: this build cannot write that format", outp);
    wvol_error_clear(&err);
    info = malloc(sizeof *info);
    if (!info) return cli_fail("decompress", "out of memory");
    if (wvol_wvc_read_info(info, in, &err) != WVOL_OK) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    if (level > info->levels) {
        rc = cli_usage("decompress", "--level %ld: %s has levels 0..%d", level, in, info->levels);
        goto done;
    }
    wvol_wvc_read_options_default(&ro);
    ro.stop_level = (int)level;
    t0 = cli_now();
    if (wvol_wvc_read(&c, in, &ro, info, &err) != WVOL_OK) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    t_read = cli_now() - t0;
    t0 = cli_now();
    if ((level ? wvol_idwt3_level(&v, c, (int)level, &err) : wvol_idwt3(&v, c, &err)) != WVOL_OK) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    t_inv = cli_now() - t0;
    t0 = cli_now();
    if (wvol_volume_save(v, outp, &err) != WVOL_OK) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    t_write = cli_now() - t0;
    if (json) {
        cli_json_begin();
        cli_json_str("input", in);
        cli_json_str("output", outp);
        cli_json_int("level", level);
        cli_json_size3("dims", v->nx, v->ny, v->nz);
        cli_json_num3("spacing", v->spacing);
        cli_json_open("seconds", '{');
        cli_json_num("read_decode", t_read);
        cli_json_num("inverse_transform", t_inv);
        cli_json_num("write", t_write);
        cli_json_close('}');
        cli_json_end();
    } else {
        printf("%s -> %s: %zu x %zu x %zu%s (decode %.3f s, inverse %.3f s, write %.3f s)\n", in, outp, v->nx,
               v->ny, v->nz, level ? " (coarser level)" : "", t_read, t_inv, t_write);
    }
    rc = CLI_OK;
done:
    free(info);
    wvol_volume_destroy(v);
    wvol_coeffs_destroy(c);
    return rc;
}
