/* SPDX-License-Identifier: MIT */
/* wvol filters: the QMF filters of every family (taps, support, vanishing moments,
 * orthonormality defect, centre). */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "wvol/wavelet.h"

const char wvol_cmd_filters_summary[] = "list the wavelet filters (taps, support, moments, defect)";

static const cli_opt opts[] = {
    {"taps", 0, 0, "text output: print every tap too"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

int wvol_cmd_filters(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val;
    int r, json = 0, taps = 0, i, n, count;

    cli_parser_init(&p, "filters", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) return cli_usage("filters", "unexpected argument '%s'", val);
        if (o->short_name == 'h') {
            cli_print_help("filters", "[--taps] [--json]",
                           "Lists every wavelet filter: h is the low-pass of the two-scale relation\n"
                           "phi(t) = sqrt2 sum h[n] phi(2t-n) (PyWavelets' rec_lo), g[n] = (-1)^n h[L-1-n];\n"
                           "support [0, L-1]; defect = max_k |sum h[n]h[n+2k] - delta_k|;\n"
                           "centre = integral of x phi(x) dx.",
                           opts);
            return CLI_OK;
        }
        if (!strcmp(o->name, "json")) json = 1;
        if (!strcmp(o->name, "taps")) taps = 1;
    }
    count = wvol_filter_count();
    if (json) {
        cli_json_begin();
        cli_json_open("filters", '[');
        for (i = 0; i < count; i++) {
            const wvol_filter *f = wvol_filter_at(i);
            cli_json_open(NULL, '{');
            cli_json_str("name", f->name);
            cli_json_str("family", wvol_family_name(f->family));
            cli_json_int("order", f->order);
            cli_json_int("length", f->length);
            cli_json_open("support", '[');
            cli_json_int(NULL, 0);
            cli_json_int(NULL, f->length - 1);
            cli_json_close(']');
            cli_json_int("vanishing_moments", f->vanishing_moments);
            cli_json_num("defect", f->defect);
            cli_json_num("center", f->center);
            cli_json_open("h", '[');
            for (n = 0; n < f->length; n++) cli_json_num(NULL, f->h[n]);
            cli_json_close(']');
            cli_json_open("g", '[');
            for (n = 0; n < f->length; n++) cli_json_num(NULL, f->g[n]);
            cli_json_close(']');
            cli_json_close('}');
        }
        cli_json_close(']');
        cli_json_end();
        return CLI_OK;
    }
    printf("%-7s %-15s %5s %-9s %4s %10s %9s\n", "name", "family", "taps", "support", "vm", "defect",
           "centre");
    for (i = 0; i < count; i++) {
        const wvol_filter *f = wvol_filter_at(i);
        char sup[24];
        snprintf(sup, sizeof sup, "[0,%d]", f->length - 1);
        printf("%-7s %-15s %5d %-9s %4d %10.2e %9.6f\n", f->name, wvol_family_name(f->family), f->length, sup,
               f->vanishing_moments, f->defect, f->center);
        if (taps)
            for (n = 0; n < f->length; n++) printf("    h[%d] = % .17g\n", n, f->h[n]);
    }
    return CLI_OK;
}
