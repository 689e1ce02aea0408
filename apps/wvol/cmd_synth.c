/* SPDX-License-Identifier: MIT */
/* wvol synth: writes a synthetic volume (datasets-synth) in the format its
 * extension names, optionally with its label map. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "volume_out.h"
#include "wvol/io.h"
#include "wvol_synth.h"

const char wvol_cmd_synth_summary[] = "make a synthetic volume (gaussian, blobs, skull, textures, shepp-logan, turbulence)";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output file; the extension picks the format (.raw .nrrd .nhdr ...)"},
    {"size", 0, 1, "N or NXxNYxNZ (default: 32 gaussian, 64 blobs, 128 skull, shepp-logan and turbulence, 256x256x1 textures)"},
    {"spacing", 0, 1, "voxel size X,Y,Z or one number (default 1; skull: 240 mm / largest size)"},
    {"seed", 0, 1, "seed, 0 to 18446744073709551615 (default 1)"},
    {"noise", 0, 1, "sigma of added Gaussian noise, in the volume's units (default 0)"},
    {"sigma", 0, 1, "gaussian: width in normalised units (default 0.25)"},
    {"count", 0, 1, "blobs: number of Gaussians (default 5); textures: regions (default 4)"},
    {"variant", 0, 1, "textures: gratings|frequencies|dots|mixed; shepp-logan: kak-slaney|yu-ye-wang; skull: head|ct (with a patient table)"},
    {"labels", 0, 1, "also write the label map (skull, textures) to this file"},
    {"gzip", 0, 0, "NRRD output: gzip encoding instead of raw"},
    {"slab", 0, 1, "Z0,NZ: write only slices Z0 .. Z0+NZ-1 of the volume (raw or NRRD; origin moved to slice Z0)"},
    {"list", 0, 0, "list the generators and exit"},
    CLI_THREADS_OPT,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

static void progress(void *user, double f)
{
    (void)user;
    cli_progress("synth", f);
}

/* Slices per slab: about 64 MiB of samples, at least one slice. */
static size_t slab_slices(const size_t dims[3])
{
    size_t slice = dims[0] * dims[1] * sizeof(float), k = ((size_t)64 << 20) / (slice ? slice : 1);
    return k < 1 ? 1 : k > dims[2] ? dims[2] : k;
}

/* Generates slab by slab into the output files (and the label file), with the range and
 * mean of the values; v and lab (may be NULL) get the geometry only (data NULL). */
static wvol_status synth_stream(wvol_volume *v, wvol_volume *lab, volume_out files[2], const wvol_synth_params *sp,
                                const char *kind, const char *out, const char *labels_out, int gzip,
                                const size_t slab[2], double *vmin, double *vmax, double *mean, double *lab_max,
                                double *t_gen, wvol_error *err)
{
    wvol_synth_gen *g = NULL;
    wvol_slab_writer *w[2] = {NULL, NULL};
    float *buf = NULL, *lbuf = NULL;
    size_t dims[3], S, slice;
    double lo = INFINITY, hi = -INFINITY, sum = 0, lmax = 0, gen = 0;
    unsigned long long bytes[2] = {0, 0};
    wvol_status s;
    const char *paths[2] = {out, labels_out};

    if ((s = wvol_synth_gen_open(&g, kind, sp, err)) != WVOL_OK) return s;
    memset(v, 0, sizeof *v);
    wvol_synth_gen_geometry(g, dims, v->spacing, v->origin);
    if (slab[1]) {
        /* slices slab[0] .. slab[0] + slab[1] - 1 of the whole volume, where they lie in it */
        if (slab[0] >= dims[2] || slab[1] > dims[2] - slab[0]) {
            wvol_synth_gen_close(g);
            return wvol_error_set(err, WVOL_ERR_ARG, "--slab %zu,%zu: the volume has %zu slices", slab[0], slab[1],
                                  dims[2]);
        }
        v->origin[2] += (double)slab[0] * v->spacing[2];
        dims[2] = slab[1];
    }
    v->nx = dims[0], v->ny = dims[1], v->nz = dims[2];
    if (lab) *lab = *v;
    S = slab_slices(dims);
    slice = dims[0] * dims[1];
    buf = malloc(S * slice * sizeof *buf);
    if (lab) lbuf = malloc(S * slice * sizeof *lbuf);
    s = !buf || (lab && !lbuf) ? wvol_error_set(err, WVOL_ERR_NOMEM, "out of memory for a slab of %zu slices of %zu x %zu", S, dims[0], dims[1])
                               : WVOL_OK;
    for (int f = 0; f < (lab ? 2 : 1) && !s; f++) {
        memset(&files[f], 0, sizeof files[f]);
        snprintf(files[f].path, sizeof files[f].path, "%s", paths[f]);
        int nrrd = wvol_path_has_ext(paths[f], ".nrrd") || wvol_path_has_ext(paths[f], ".nhdr");
        if (wvol_path_has_ext(paths[f], ".nhdr"))
            wvol_nrrd_data_path(files[f].data_path, sizeof files[f].data_path, paths[f], gzip);
        if ((s = volume_out_claim(paths[f], gzip && nrrd, err)) != WVOL_OK) break;
        s = wvol_slab_writer_open(&w[f], paths[f], dims, v->spacing, v->origin, gzip && nrrd ? 6 : 0, err);
    }
    for (size_t z0 = 0; z0 < dims[2] && !s; z0 += S) {
        size_t nz = dims[2] - z0 < S ? dims[2] - z0 : S, n = nz * slice;
        double t = cli_now();
        s = wvol_synth_gen_slab(g, buf, lbuf, slab[0] + z0, nz, err);
        gen += cli_now() - t;
        if (s) break;
        for (size_t i = 0; i < n; i++) {
            double x = buf[i];
            lo = x < lo ? x : lo;
            hi = x > hi ? x : hi;
            sum += x;
        }
        if (lbuf)
            for (size_t i = 0; i < n; i++) lmax = lbuf[i] > lmax ? lbuf[i] : lmax;
        s = wvol_slab_writer_put(w[0], buf, nz, err);
        if (!s && w[1]) s = wvol_slab_writer_put(w[1], lbuf, nz, err);
        cli_progress("synth", (double)(z0 + nz) / (double)dims[2]);
    }
    cli_progress_done();
    if (!s) {
        s = wvol_slab_writer_commit(w[0], &bytes[0], err);
        w[0] = NULL;
        if (!s && w[1]) {
            s = wvol_slab_writer_commit(w[1], &bytes[1], err);
            w[1] = NULL;
        }
    }
    wvol_slab_writer_abort(w[0]);
    wvol_slab_writer_abort(w[1]);
    free(buf);
    free(lbuf);
    wvol_synth_gen_close(g);
    files[0].bytes = bytes[0];
    files[1].bytes = bytes[1];
    *vmin = lo, *vmax = hi, *mean = sum / ((double)slice * (double)dims[2]);
    *lab_max = lmax;
    *t_gen = gen;
    return s;
}

int wvol_cmd_synth(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *kind_name = NULL, *out = NULL, *labels_out = NULL;
    int r, json = 0, gzip = 0, kind, have_size = 0;
    long count;
    size_t bytes, slab[2] = {0, 0};
    wvol_synth_params sp;
    wvol_volume *v = NULL, *lab = NULL;
    wvol_error err;
    volume_out files[2];
    double t0, t1 = 0, vmin, vmax, mean, lab_max = 0;
    wvol_volume vhead, lhead; /* the streamed volume's geometry (no samples held) */
    int streamed;

    wvol_synth_params_default(&sp);
    cli_parser_init(&p, "synth", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (kind_name) return cli_usage("synth", "one generator expected, got '%s' too", val);
            kind_name = val;
        } else if (o->short_name == 'h') {
            cli_print_help("synth", "KIND -o OUT [--size N|NXxNYxNZ] [--spacing X,Y,Z] [--seed S] [--noise SIGMA]\n"
                                    "       [--sigma S] [--count N] [--labels OUT] [--variant NAME] [--gzip]\n"
                                    "       [--slab Z0,NZ] [--json]",
                           "Makes a deterministic synthetic volume (same parameters and seed, same bytes)\n"
                           "and writes it in the format its extension names. Generators (--list):\n"
                           "gaussian, blobs, skull, textures, shepp-logan, turbulence. docs/datasets.md describes them.\n"
                           "Raw and NRRD outputs are written slab by slab: the volume is never held whole.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "list")) {
            for (int i = 0; i < wvol_synth_kind_count(); i++)
                printf("%-12s %s\n", wvol_synth_kind_name(i), wvol_synth_kind_about(i));
            return CLI_OK;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("synth", val, NULL)) return CLI_USAGE;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        } else if (!strcmp(o->name, "gzip")) {
            gzip = 1;
        } else if (!strcmp(o->name, "output")) {
            out = val;
        } else if (!strcmp(o->name, "labels")) {
            labels_out = val;
        } else if (!strcmp(o->name, "size")) {
            if (!cli_parse_dims("synth", "size", val, sp.dims)) return CLI_USAGE;
            have_size = 1;
        } else if (!strcmp(o->name, "spacing")) {
            if (!cli_parse_double3("synth", "spacing", val, sp.spacing)) return CLI_USAGE;
            for (int a = 0; a < 3; a++)
                if (!(sp.spacing[a] > 0))
                    return cli_usage("synth", "--spacing '%s': each spacing must be positive", val);
        } else if (!strcmp(o->name, "seed")) {
            if (!parse_seed("synth", val, &sp.seed)) return CLI_USAGE;
        } else if (!strcmp(o->name, "noise")) {
            if (!cli_parse_double("synth", "noise", val, &sp.noise)) return CLI_USAGE;
            if (sp.noise < 0) return cli_usage("synth", "--noise '%s': sigma must be >= 0", val);
        } else if (!strcmp(o->name, "sigma")) {
            if (!cli_parse_double("synth", "sigma", val, &sp.sigma)) return CLI_USAGE;
            if (!(sp.sigma > 0)) return cli_usage("synth", "--sigma '%s': must be positive", val);
        } else if (!strcmp(o->name, "count")) {
            if (!cli_parse_long("synth", "count", val, 1, 64, &count)) return CLI_USAGE;
            sp.count = (int)count;
        } else if (!strcmp(o->name, "variant")) {
            sp.variant = val;
        } else if (!strcmp(o->name, "slab")) {
            unsigned long long a, b;
            int used = 0;
            if (sscanf(val, "%llu,%llu%n", &a, &b, &used) != 2 || val[used] || val[0] == '-' || strchr(val, '-') ||
                b == 0)
                return cli_usage("synth", "--slab '%s': expected Z0,NZ (first slice and a count >= 1)", val);
            slab[0] = (size_t)a, slab[1] = (size_t)b;
        }
    }
    if (!kind_name) return cli_usage("synth", "missing generator (one of: gaussian, blobs, skull, textures, shepp-logan, turbulence)");
    kind = wvol_synth_kind_find(kind_name);
    if (kind < 0)
        return cli_usage("synth", "unknown generator '%s' (known: gaussian, blobs, skull, textures, shepp-logan, turbulence)",
                         kind_name);
    if (!out) return cli_usage("synth", "missing output file (-o OUT.raw, OUT.nrrd or OUT.nhdr)");
    if (!wvol_format_supported(out, 1))
        return cli_usage("synth", "%s: cannot write this format (use .raw, .nrrd or .nhdr)", out);
    if (gzip && !wvol_path_has_ext(out, ".nrrd") && !wvol_path_has_ext(out, ".nhdr"))
        return cli_usage("synth", "--gzip needs a .nrrd or .nhdr output, not %s", out);
    if (labels_out) {
        if (!wvol_synth_kind_has_labels(kind))
            return cli_usage("synth", "--labels: the %s generator makes no label map (skull and textures do)",
                             wvol_synth_kind_name(kind));
        if (!wvol_format_supported(labels_out, 1))
            return cli_usage("synth", "%s: cannot write this format (use .raw, .nrrd or .nhdr)", labels_out);
        const char *outs[2] = {out, labels_out}, *same = cli_same_output(outs, 2);
        if (same) return cli_usage("synth", "--labels and -o would write the same file (%s)", same);
    }
    if (!have_size) wvol_synth_kind_default_dims(kind, sp.dims);
    if (!wvol_size_mul3(sp.dims[0], sp.dims[1], sp.dims[2], sizeof(float), &bytes) || bytes > ((size_t)-1 >> 1))
        return cli_usage("synth", "--size %zux%zux%zu: the voxel count overflows the address space", sp.dims[0],
                         sp.dims[1], sp.dims[2]);
    sp.progress = progress;
    /* raw and NRRD are written slab by slab: the volume is never held */
    streamed = (wvol_path_has_ext(out, ".raw") || wvol_path_has_ext(out, ".nrrd") || wvol_path_has_ext(out, ".nhdr")) &&
               (!labels_out || wvol_path_has_ext(labels_out, ".raw") || wvol_path_has_ext(labels_out, ".nrrd") ||
                wvol_path_has_ext(labels_out, ".nhdr"));

    if (slab[1] && !streamed)
        return cli_usage("synth", "--slab needs raw or NRRD outputs (written slab by slab)");
    wvol_error_clear(&err);
    t0 = cli_now();
    if (streamed) {
        if (synth_stream(&vhead, labels_out ? &lhead : NULL, files, &sp, wvol_synth_kind_name(kind), out,
                         labels_out, gzip, slab, &vmin, &vmax, &mean, &lab_max, &t1, &err) != WVOL_OK)
            return cli_fail_err("synth", &err);
        t1 += t0; /* generation time, from the start */
        v = &vhead;
        lab = labels_out ? &lhead : NULL;
    } else {
        if (wvol_synth_make(&v, labels_out ? &lab : NULL, wvol_synth_kind_name(kind), &sp, &err) != WVOL_OK)
            return cli_fail_err("synth", &err);
        cli_progress_done();
        t1 = cli_now();
        if (volume_out_save(&files[0], v, out, gzip, &err) != WVOL_OK) {
            wvol_volume_destroy(v);
            wvol_volume_destroy(lab);
            return cli_fail_err("synth", &err);
        }
        if (lab && volume_out_save(&files[1], lab, labels_out, gzip, &err) != WVOL_OK) {
            wvol_volume_destroy(v);
            wvol_volume_destroy(lab);
            return cli_fail_err("synth", &err);
        }
        wvol_volume_range(v, &vmin, &vmax, &mean);
        if (lab) wvol_volume_range(lab, NULL, &lab_max, NULL);
    }
    if (json) {
        cli_json_begin();
        cli_json_str("command", "synth");
        cli_json_str("kind", wvol_synth_kind_name(kind));
        volume_out_json(&files[0], v);
        cli_json_key("seed");
        printf("%llu", (unsigned long long)sp.seed);
        cli_json_num("noise", sp.noise);
        if (sp.variant) cli_json_str("variant", sp.variant);
        cli_json_num("min", vmin);
        cli_json_num("max", vmax);
        cli_json_num("mean", mean);
        cli_json_num("seconds_generate", t1 - t0);
        cli_json_num("seconds", cli_now() - t0);
        if (lab) {
            double lmax = lab_max;
            cli_json_open("labels", '{');
            cli_json_str("file", files[1].path);
            cli_json_int("bytes", (long long)files[1].bytes);
            cli_json_int("classes", (long long)lmax + 1);
            cli_json_close('}');
        }
        cli_json_end();
    } else {
        printf("%-8s %zu x %zu x %zu voxels, seed %llu, noise %g%s%s\n", wvol_synth_kind_name(kind), v->nx, v->ny,
               v->nz, (unsigned long long)sp.seed, sp.noise, sp.variant ? ", variant " : "",
               sp.variant ? sp.variant : "");
        printf("spacing  %g %g %g   origin %g %g %g\n", v->spacing[0], v->spacing[1], v->spacing[2], v->origin[0],
               v->origin[1], v->origin[2]);
        printf("range    %g .. %g (mean %g)\n", vmin, vmax, mean);
        printf("wrote    %s (%llu bytes%s) in %.2f s (generate %.2f s)\n", files[0].path,
               (unsigned long long)files[0].bytes, files[0].data_path[0] ? ", with its data file" : "",
               cli_now() - t0, t1 - t0);
        if (lab) {
            double lmax = lab_max;
            printf("labels   %s (%llu bytes), classes 0..%d\n", files[1].path, (unsigned long long)files[1].bytes,
                   (int)lmax);
        }
    }
    if (!streamed) {
        wvol_volume_destroy(v);
        wvol_volume_destroy(lab);
    }
    return CLI_OK;
}
