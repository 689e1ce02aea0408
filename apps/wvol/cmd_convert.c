/* SPDX-License-Identifier: MIT */
/* wvol convert: any readable volume format to any writable one (by extension). */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "volume_out.h"
#include "wvol/io.h"

const char wvol_cmd_convert_summary[] = "convert a volume between formats (raw, nrrd, vdb, vti, mha, nii, ...)";

static const cli_opt opts[] = {
    CLI_LOAD_OPTS,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

/* A short name of the format a path stands for. */
static const char *format_name(const char *path)
{
    static const struct { const char *ext, *name; } names[] = {
        {".raw", "raw"}, {".bin", "raw"}, {".nrrd", "NRRD"}, {".nhdr", "NRRD (detached)"},
        {".vdb", "OpenVDB"}, {".vti", "VTK XML image"}, {".vtk", "VTK legacy structured points"},
        {".mha", "MetaImage"}, {".mhd", "MetaImage (detached)"}, {".nii", "NIfTI"},
        {".nii.gz", "NIfTI (gzip)"}, {".wvc", "wvol .wvc, decoded"}};
    size_t i;
    for (i = 0; i < sizeof names / sizeof names[0]; i++)
        if (wvol_path_has_ext(path, names[i].ext)) return names[i].name;
    return "DICOM series";
}

int wvol_cmd_convert(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *in = NULL, *out = NULL;
    int r, json = 0;
    wvol_load_options lo;
    wvol_error err;
    wvol_volume *v = NULL;
    double t0;

    wvol_load_options_default(&lo);
    cli_parser_init(&p, "convert", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (!in) in = val;
            else if (!out) out = val;
            else return cli_usage("convert", "two files expected (IN OUT), got '%s' too", val);
        } else if (o->short_name == 'h') {
            cli_print_help("convert", "IN OUT [--dims NXxNYxNZ --type T] [--grid NAME] [--json]",
                           "Reads IN and writes OUT; the formats follow the extensions.\n"
                           "Readable: .raw .nrrd .nhdr .vdb .vti .vtk .mha .mhd .nii .nii.gz .wvc, a DICOM folder.\n"
                           "Writable: .raw (float32) .nrrd .vdb .vti .vtk .mha .nii .nii.gz.\n"
                           "Samples are float32 in between: integer input is converted exactly.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        } else if (cli_load_option("convert", o, val, &lo) == CLI_USAGE) {
            return CLI_USAGE;
        }
    }
    if (!in || !out) return cli_usage("convert", "expected IN and OUT files (see 'wvol convert --help')");
    if (cli_load_options_fit("convert", in, NULL) != CLI_OK) return CLI_USAGE;
    if (cli_data_file_not_input("convert", in, out) != CLI_OK) return CLI_USAGE;
    if (!wvol_format_supported(out, 1))
        return cli_usage("convert", "%s: cannot write this format (%s)", out, cli_write_hint(out));

    t0 = cli_now();
    wvol_error_clear(&err);
    if (wvol_volume_load(&v, in, &lo, &err) != WVOL_OK) return cli_fail_err("convert", &err);
    if (volume_out_claim(out, 0, &err) != WVOL_OK || wvol_volume_save(v, out, &err) != WVOL_OK) {
        wvol_volume_destroy(v);
        return cli_fail_err("convert", &err);
    }
    if (json) {
        const double dims[3] = {(double)v->nx, (double)v->ny, (double)v->nz};
        cli_json_begin();
        cli_json_str("input", in);
        cli_json_str("input_format", format_name(in));
        cli_json_str("output", out);
        cli_json_str("output_format", format_name(out));
        cli_json_num3("dims", dims);
        cli_json_num3("spacing", v->spacing);
        cli_json_num3("origin", v->origin);
        cli_json_num("seconds", cli_now() - t0);
        cli_json_end();
    } else {
        printf("converted %s (%s) -> %s (%s): %zu x %zu x %zu float32 voxels, spacing %.10g %.10g %.10g, "
               "origin %.10g %.10g %.10g, %.2f s\n",
               in, format_name(in), out, format_name(out), v->nx, v->ny, v->nz, v->spacing[0],
               v->spacing[1], v->spacing[2], v->origin[0], v->origin[1], v->origin[2], cli_now() - t0);
    }
    wvol_volume_destroy(v);
    return CLI_OK;
}
