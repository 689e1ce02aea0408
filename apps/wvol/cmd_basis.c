/* SPDX-License-Identifier: MIT */
/* wvol basis: the basis-function tables per family and J (cubic splines through
 * the cascade values) and their checks: integrals, orthonormality, spline error. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "wvol/io.h"
#include "wvol/wavelet.h"

const char wvol_cmd_basis_summary[] = "basis-function spline tables per family and J, with their checks";

static const cli_opt opts[] = {
    {"wavelet", 'w', 1, "family: haar, db1..db10, coif1..coif5, bl3 (default: all)"},
    {"J", 'J', 1, "knots per unit 2^J: J (1..12) or a range A:B (default 6)"},
    {"csv", 0, 1, "write the tables of one family and one J to this CSV file"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

static int parse_jrange(const char *s, int *j0, int *j1)
{
    char *end;
    long a = strtol(s, &end, 10), b = a;
    if (end == s) return 0;
    if (*end == ':') {
        const char *t = end + 1;
        b = strtol(t, &end, 10);
        if (end == t) return 0;
    }
    if (*end || a < WVOL_BASIS_J_MIN || b > WVOL_BASIS_J_MAX || a > b) return 0;
    *j0 = (int)a, *j1 = (int)b;
    return 1;
}

static void json_basis(const wvol_basis *b, double seconds)
{
    cli_json_open(NULL, '{');
    cli_json_str("wavelet", b->filter->name);
    cli_json_int("J", b->J);
    cli_json_int("exact", b->exact);
    cli_json_int("degree", b->degree);
    cli_json_int("length", b->length);
    cli_json_num("support", b->support);
    cli_json_int("pieces_per_unit", b->per_unit);
    cli_json_int("pieces", b->pieces);
    cli_json_num("center", b->center);
    cli_json_num("center_spline", b->center_spline);
    cli_json_num("phi_integral", b->phi_integral);
    cli_json_num("psi_integral", b->psi_integral);
    cli_json_num("ortho_error", b->ortho_error);
    cli_json_num("ortho_error_psi", b->ortho_error_psi);
    cli_json_num("spline_error", b->spline_error);
    cli_json_num("spline_error_phi", b->spline_error_phi);
    cli_json_num("spline_error_psi", b->spline_error_psi);
    cli_json_num("phi_max", b->vmax[WVOL_BASIS_PHI]);
    cli_json_num("psi_max", b->vmax[WVOL_BASIS_PSI]);
    cli_json_num("dphi_max", b->dmax[WVOL_BASIS_PHI]);
    cli_json_num("dpsi_max", b->dmax[WVOL_BASIS_PSI]);
    cli_json_num("phi_abs_integral", b->abs_integral[WVOL_BASIS_PHI]);
    cli_json_num("psi_abs_integral", b->abs_integral[WVOL_BASIS_PSI]);
    cli_json_num("phi_end_slope", b->end_slope[WVOL_BASIS_PHI]);
    cli_json_num("psi_end_slope", b->end_slope[WVOL_BASIS_PSI]);
    cli_json_num("build_seconds", seconds);
    cli_json_close('}');
}

static void text_basis(const wvol_basis *b)
{
    printf("%-6s %3d %6d %8d %10.2e %10.2e %10.2e %10.2e %10.2e %10.2e%s\n", b->filter->name, b->J, b->per_unit,
           b->pieces, b->phi_integral - 1.0, b->psi_integral, b->ortho_error, b->ortho_error_psi,
           b->spline_error_phi, b->spline_error_psi, b->exact ? "  (exact)" : "");
}

static int write_csv(const char *path, const wvol_basis *b, wvol_error *err)
{
    /* The column groups of a row, in the order of the header: function, polynomial, coefficients. */
    static const struct {
        int which;
        wvol_basis_kind kind;
        int n;
    } groups[] = {{WVOL_BASIS_PHI, WVOL_BASIS_VALUE, 4},     {WVOL_BASIS_PSI, WVOL_BASIS_VALUE, 4},
                  {WVOL_BASIS_PHI, WVOL_BASIS_DERIV, 3},     {WVOL_BASIS_PSI, WVOL_BASIS_DERIV, 3},
                  {WVOL_BASIS_PHI, WVOL_BASIS_PRIMITIVE, 5}, {WVOL_BASIS_PSI, WVOL_BASIS_PRIMITIVE, 5}};
    wvol_atomic_file af;
    int i, k;
    if (wvol_atomic_open(&af, path, err) != WVOL_OK) return 0;
    fprintf(af.fp, "# wvol basis %s J=%d: piece i covers [x0, x0 + %.17g); u = x - x0; value = sum c_k u^k\n",
            b->filter->name, b->J, b->h);
    fprintf(af.fp, "piece,x0,phi_c0,phi_c1,phi_c2,phi_c3,psi_c0,psi_c1,psi_c2,psi_c3,"
                   "dphi_c0,dphi_c1,dphi_c2,dpsi_c0,dpsi_c1,dpsi_c2,"
                   "phi_int_c0,phi_int_c1,phi_int_c2,phi_int_c3,phi_int_c4,"
                   "psi_int_c0,psi_int_c1,psi_int_c2,psi_int_c3,psi_int_c4\n");
    for (i = 0; i < b->pieces; i++) {
        fprintf(af.fp, "%d,%.17g", i, i * b->h);
        for (size_t g = 0; g < sizeof groups / sizeof groups[0]; g++) {
            const double *t = wvol_basis_coeffs(b, groups[g].which, groups[g].kind, i);
            for (k = 0; k < groups[g].n; k++) fprintf(af.fp, ",%.17g", t[k]);
        }
        fputc('\n', af.fp);
    }
    return wvol_atomic_commit(&af, err) == WVOL_OK;
}

int wvol_cmd_basis(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *name = NULL, *csv = NULL;
    int r, json = 0, j0 = 6, j1 = 6, J, i, count;
    wvol_error err;
    const wvol_filter *one = NULL;
    int nsum = 0, sum_J[WVOL_BASIS_J_MAX], sum_pu[WVOL_BASIS_J_MAX];
    double sum_err[WVOL_BASIS_J_MAX];

    cli_parser_init(&p, "basis", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) return cli_usage("basis", "unexpected argument '%s'", val);
        if (o->short_name == 'h') {
            cli_print_help("basis", "[--wavelet NAME] [-J N|A:B] [--json] [--csv OUT.csv]",
                           "Builds the basis-function tables (DESIGN.md section 7): phi and psi by the\n"
                           "cascade algorithm at x = n/2^J, a cubic spline per interval of width 2^-J\n"
                           "(periodic end conditions: exact partition of unity; Haar exact), and\n"
                           "prints the checks from the\n"
                           "spline form: int phi - 1, int psi, max_k |<phi(.-k),phi> - delta_k|, the same\n"
                           "for psi (and phi against psi), and the spline's max error against the\n"
                           "cascade at J+2. 'per unit' is the number of pieces per unit of x (a ray\n"
                           "crosses that many per voxel per axis at the finest level): the speed side\n"
                           "of the J knob, the spline error its accuracy side. --csv writes one\n"
                           "family's tables (monomial coefficients per piece).",
                           opts);
            return CLI_OK;
        }
        if (!strcmp(o->name, "json")) json = 1;
        else if (!strcmp(o->name, "wavelet")) name = val;
        else if (!strcmp(o->name, "csv")) csv = val;
        else if (!strcmp(o->name, "J")) {
            if (!parse_jrange(val, &j0, &j1))
                return cli_usage("basis", "-J '%s': expected J or A:B with %d <= A <= B <= %d", val,
                                 WVOL_BASIS_J_MIN, WVOL_BASIS_J_MAX);
        }
    }
    if (name && wvol_filter_get(&one, name, &err) != WVOL_OK) return cli_usage("basis", "%s", err.message);
    if (csv && (!one || j0 != j1)) return cli_usage("basis", "--csv needs one --wavelet and one -J value");
    count = one ? 1 : wvol_filter_count();

    if (json) {
        cli_json_begin();
        cli_json_open("bases", '[');
    } else {
        printf("%-6s %3s %6s %8s %10s %10s %10s %10s %10s %10s\n", "name", "J", "/unit", "pieces", "int-1",
               "int_psi", "ortho", "ortho_psi", "err_phi", "err_psi");
    }
    for (i = 0; i < count; i++) {
        const wvol_filter *f = one ? one : wvol_filter_at(i);
        for (J = j0; J <= j1; J++) {
            wvol_basis *b = NULL;
            double t0 = cli_now(), dt;
            if (wvol_basis_create(&b, f, J, &err) != WVOL_OK) {
                if (json) cli_json_close(']'), cli_json_end();
                return cli_fail_err("basis", &err);
            }
            dt = cli_now() - t0;
            if (json) json_basis(b, dt);
            else text_basis(b);
            if (nsum < WVOL_BASIS_J_MAX) sum_J[nsum] = b->J, sum_pu[nsum] = b->per_unit, sum_err[nsum++] = b->spline_error;
            if (csv && !write_csv(csv, b, &err)) {
                wvol_basis_destroy(b);
                if (json) cli_json_close(']'), cli_json_end();
                return cli_fail_err("basis", &err);
            }
            wvol_basis_destroy(b);
            if (f->length == 2) break; /* exact: J does not matter */
        }
    }
    if (json) {
        cli_json_close(']');
        cli_json_end();
    } else if (one) {
        /* one line per J for the run-time-against-error plot */
        for (i = 0; i < nsum; i++)
            printf("%s J=%d: %d pieces per unit, spline error %.3e\n", one->name, sum_J[i], sum_pu[i], sum_err[i]);
    }
    return CLI_OK;
}
