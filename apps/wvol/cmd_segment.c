/* SPDX-License-Identifier: MIT */
/* wvol segment: wavelet features -> PCA -> 3D Kohonen map -> labels and colours. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "output_set.h"
#include "volume_out.h"
#include "wvol/analysis.h"
#include "wvol/io.h"

const char wvol_cmd_segment_summary[] = "segment textures with wavelet features and a 3D Kohonen map";

static const cli_opt opts[] = {
    {"output", 'o', 1, "label volume to write (.raw .nrrd ...): winner neuron (or class with --train-box)"},
    {"colors", 0, 1, "colour volume to write: interleaved RGB float32 .raw"},
    {"features-out", 0, 1, "write the normalised PCA features: planar float32 .raw, one plane per component"},
    {"wavelet", 0, 1, "filter (default db2)"},
    {"levels", 0, 1, "pyramid depth (default 3)"},
    {"smooth", 0, 1, "box average radius of |d| per band, in coarse samples (default 1)"},
    {"variance", 0, 1, "PCA: keep components explaining this share (default 1 = all)"},
    {"som", 0, 1, "Kohonen lattice AxBxC (default 4x4x4)"},
    {"iters", 0, 1, "training samples (default 20000)"},
    {"seed", 0, 1, "random seed (default 1)"},
    {"truth", 0, 1, "ground-truth label volume: report misclassification (majority mapping)"},
    {"train-box", 0, 1, "supervised: label neurons from truth inside x0,y0,z0,x1,y1,z1 (voxels, half-open)"},
    {"boundary", 0, 1, "radius (voxels) defining 'away from boundaries' in the score (default 2^levels)"},
    CLI_LOAD_OPTS,
    CLI_THREADS_OPT,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

static int write_colors(const char *path, const float *rgb, size_t n, wvol_error *err)
{
    wvol_atomic_file f;
    if (wvol_atomic_open(&f, path, err)) return err->status;
    if (fwrite(rgb, 3 * sizeof(float), n, f.fp) != n) return wvol_atomic_fail(&f, err);
    return wvol_atomic_commit(&f, err);
}

static int load_labels(int32_t **out, const char *path, const wvol_volume *like, const wvol_load_options *lo,
                       wvol_error *err)
{
    wvol_volume *t = NULL;
    size_t n;
    if (wvol_volume_load(&t, path, lo, err)) return err->status;
    if (t->nx != like->nx || t->ny != like->ny || t->nz != like->nz) {
        /* two files that do not match: bad input (exit 1), as docs/cli.md has it */
        wvol_error_set(err, WVOL_ERR_FORMAT, "%s: truth is %zux%zux%zu but the volume is %zux%zux%zu", path,
                       t->nx, t->ny, t->nz, like->nx, like->ny, like->nz);
        wvol_volume_destroy(t);
        return err->status;
    }
    n = wvol_volume_count(t);
    *out = malloc(n * sizeof **out);
    if (!*out) {
        wvol_volume_destroy(t);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "out of memory");
    }
    for (size_t i = 0; i < n; i++) {
        float v = t->data[i];
        if (!(v >= 0 && v <= 65535) || v != floorf(v)) {
            wvol_error_set(err, WVOL_ERR_FORMAT, "%s: voxel %zu holds %g; labels must be integers 0..65535",
                           path, i, (double)v);
            free(*out);
            *out = NULL;
            wvol_volume_destroy(t);
            return err->status;
        }
        (*out)[i] = (int32_t)v;
    }
    wvol_volume_destroy(t);
    return WVOL_OK;
}

int wvol_cmd_segment(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *in = NULL, *outp = NULL, *colors = NULL, *truth_path = NULL, *wname = "db2",
               *features_out = NULL;
    volume_out labels_file;
    int r, json = 0, have_box = 0, rc = CLI_FAILED;
    long lv, boundary = -1;
    double box[6] = {0}, variance = 1.0;
    wvol_load_options lo;
    wvol_feature_params fp;
    wvol_som_params sp;
    wvol_error err;
    wvol_volume *v = NULL;
    wvol_features *feat = NULL;
    wvol_som *som = NULL;
    const wvol_filter *filt;
    int32_t *labels = NULL, *truth = NULL;
    float *rgb = NULL;
    uint8_t *mask = NULL;
    double t0 = cli_now(), t_feat, t_pca, t_som, t_class;

    wvol_load_options_default(&lo);
    wvol_feature_params_default(&fp);
    wvol_som_params_default(&sp);
    wvol_error_clear(&err);
    cli_parser_init(&p, "segment", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (in) return cli_usage("segment", "one input volume expected, got '%s' too", val);
            in = val;
        } else if (o->short_name == 'h') {
            cli_print_help("segment", "IN -o LABELS [--colors RGB.raw] [--wavelet W --levels M --som AxBxC] [--truth T]",
                           "Per-voxel wavelet features (detail magnitudes and low-pass per level),\n"
                           "PCA, min-max normalisation and a 3D Kohonen map: a label volume and a colour\n"
                           "volume. With --truth, reports the misclassification rate after mapping each\n"
                           "cluster to its majority class; with --train-box, labels neurons from the truth\n"
                           "inside the box and classifies the rest (supervised).", opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) outp = val;
        else if (!strcmp(o->name, "colors")) colors = val;
        else if (!strcmp(o->name, "features-out")) features_out = val;
        else if (!strcmp(o->name, "wavelet")) wname = val;
        else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long("segment", "levels", val, 1, 30, &lv)) return CLI_USAGE;
            fp.levels = (int)lv;
        } else if (!strcmp(o->name, "smooth")) {
            if (!cli_parse_long("segment", "smooth", val, 0, 16, &lv)) return CLI_USAGE;
            fp.smooth = (int)lv;
        } else if (!strcmp(o->name, "variance")) {
            if (!cli_parse_fraction("segment", "variance", val, &variance)) return CLI_USAGE;
        } else if (!strcmp(o->name, "som")) {
            size_t d[3];
            if (!cli_parse_dims("segment", "som", val, d)) return CLI_USAGE;
            if (d[0] > 64 || d[1] > 64 || d[2] > 64) return cli_usage("segment", "--som %s: at most 64 per axis", val);
            for (int a = 0; a < 3; a++) sp.dims[a] = (int)d[a];
        } else if (!strcmp(o->name, "iters")) {
            if (!cli_parse_long("segment", "iters", val, 1, 100000000, &sp.iterations)) return CLI_USAGE;
        } else if (!strcmp(o->name, "seed")) {
            if (!cli_parse_long("segment", "seed", val, 0, 2147483647, &lv)) return CLI_USAGE;
            sp.seed = (uint64_t)lv;
        } else if (!strcmp(o->name, "truth")) truth_path = val;
        else if (!strcmp(o->name, "train-box")) {
            char *end;
            const char *s = val;
            for (int a = 0; a < 6; a++) {
                box[a] = strtod(s, &end);
                if (end == s || (a < 5 && *end != ',') || (a == 5 && *end) || box[a] < 0)
                    return cli_usage("segment", "--train-box '%s': expected x0,y0,z0,x1,y1,z1 (voxels >= 0)", val);
                s = end + 1;
            }
            have_box = 1;
        } else if (!strcmp(o->name, "boundary")) {
            if (!cli_parse_long("segment", "boundary", val, 0, 64, &boundary)) return CLI_USAGE;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("segment", val, NULL)) return CLI_USAGE;
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        } else if (cli_load_option("segment", o, val, &lo) == CLI_USAGE) {
            return CLI_USAGE;
        }
    }
    if (!in) return cli_usage("segment", "missing input volume (see 'wvol segment --help')");
    if (!outp && !colors && !truth_path && !features_out) return cli_usage("segment", "nothing to do: give -o, --colors or --truth");
    {
        const char *outs[3] = {outp, colors, features_out}, *same = cli_same_output(outs, 3);
        if (same) return cli_usage("segment", "two outputs would write the same file (%s)", same);
        if (cli_data_file_not_input("segment", in, outp) != CLI_OK) return CLI_USAGE;
    }
    if (features_out && !wvol_path_has_ext(features_out, ".raw"))
        return cli_usage("segment", "--features-out %s: only .raw is written", features_out);
    if (colors && !wvol_path_has_ext(colors, ".raw"))
        return cli_usage("segment", "--colors %s: only .raw (interleaved RGB float32) is written", colors);
    if (have_box && !truth_path) return cli_usage("segment", "--train-box needs --truth");
    if (boundary >= 0 && !truth_path) return cli_usage("segment", "--boundary shapes the score against --truth: add --truth");
    if (wvol_filter_get(&filt, wname, &err)) return cli_usage("segment", "--wavelet: %s", err.message);
    if (cli_load_options_fit("segment", in, truth_path) != CLI_OK) return CLI_USAGE;

    if (wvol_volume_load(&v, in, &lo, &err)) return cli_fail_err("segment", &err);
    size_t n = wvol_volume_count(v);
    if (truth_path && load_labels(&truth, truth_path, v, &lo, &err)) goto fail;
    if (wvol_features_compute(&feat, v, filt, &fp, &err)) goto fail;
    int raw_features = feat->count;
    t_feat = cli_now();
    if (wvol_features_pca(feat, variance, NULL, &err)) goto fail;
    t_pca = cli_now();
    if (features_out) {
        wvol_volume planes = {v->nx, v->ny, v->nz * (size_t)feat->count, {1, 1, 1}, {0, 0, 0}, feat->data, 0};
        if (output_set_add(features_out, &err) || wvol_raw_write(&planes, features_out, &err)) goto fail;
    }
    if (wvol_som_train(&som, feat, &sp, &err)) goto fail;
    t_som = cli_now();
    labels = malloc(n * sizeof *labels);
    rgb = colors ? malloc(3 * n * sizeof *rgb) : NULL;
    if (!labels || (colors && !rgb)) {
        wvol_error_set(&err, WVOL_ERR_NOMEM, "out of memory");
        goto fail;
    }
    if (wvol_som_classify(labels, rgb, som, feat, &err)) goto fail;
    if (have_box) {
        mask = calloc(n, 1);
        if (!mask) { wvol_error_set(&err, WVOL_ERR_NOMEM, "out of memory"); goto fail; }
        size_t cnt = 0;
        for (size_t k = 0; k < v->nz; k++)
            for (size_t j = 0; j < v->ny; j++)
                for (size_t i = 0; i < v->nx; i++)
                    if (i >= box[0] && j >= box[1] && k >= box[2] && i < box[3] && j < box[4] && k < box[5]) {
                        mask[i + v->nx * (j + v->ny * k)] = 1;
                        cnt++;
                    }
        if (!cnt) { rc = cli_usage("segment", "--train-box selects no voxel of the %zux%zux%zu volume", v->nx, v->ny, v->nz); goto out; }
        if (wvol_som_label(som, feat, truth, mask, &err)) goto fail;
        wvol_som_apply_classes(labels, labels, n, som);
    }
    t_class = cli_now();

    wvol_seg_score score = {0, 0, 0};
    int rad = 0;
    if (truth) {
        rad = boundary >= 0 ? (int)boundary : 1 << fp.levels;
        if (wvol_segmentation_score(&score, labels, truth, v->nx, v->ny, v->nz, rad, &err)) goto fail;
    }
    if (outp) {
        for (size_t i = 0; i < n; i++) v->data[i] = (float)labels[i];
        if (volume_out_save(&labels_file, v, outp, 0, &err)) goto fail;
    }
    if (colors && (output_set_add(colors, &err) || write_colors(colors, rgb, n, &err))) goto fail;

    if (json) {
        cli_json_begin();
        cli_json_str("input", in);
        cli_json_str("wavelet", filt->name);
        cli_json_int("levels", fp.levels);
        cli_json_int("features", raw_features);
        cli_json_int("components", feat->count);
        cli_json_int("neurons", som->neurons);
        if (truth) {
            cli_json_num("error_all", score.error_all);
            cli_json_num("error_interior", score.error_interior);
            cli_json_int("interior_voxels", (long long)score.interior);
        }
        cli_json_num("seconds_features", t_feat - t0);
        cli_json_num("seconds_pca", t_pca - t_feat);
        cli_json_num("seconds_som", t_som - t_pca);
        cli_json_num("seconds_classify", t_class - t_som);
        cli_json_end();
    } else {
        printf("segmented %s (%zux%zux%zu) with %s, %d levels: %d features -> %d PCA components -> %d neurons\n",
               in, v->nx, v->ny, v->nz, filt->name, fp.levels, raw_features, feat->count, som->neurons);
        if (truth && score.interior)
            printf("misclassified: %.2f%% overall, %.2f%% away from boundaries (%zu voxels)\n",
                   100 * score.error_all, 100 * score.error_interior, score.interior);
        else if (truth)
            printf("misclassified: %.2f%% overall; no voxel lies away from the boundaries (radius %d)\n",
                   100 * score.error_all, rad);
        printf("time: features %.2fs, pca %.2fs, som %.2fs, classify %.2fs\n", t_feat - t0, t_pca - t_feat,
               t_som - t_pca, t_class - t_som);
        if (outp) printf("labels: %s\n", outp);
        if (colors) printf("colours: %s\n", colors);
    }
    rc = CLI_OK;
    goto out;
fail:
    rc = cli_fail_err("segment", &err);
out:
    wvol_volume_destroy(v);
    wvol_features_destroy(feat);
    wvol_som_destroy(som);
    free(labels);
    free(truth);
    free(rgb);
    free(mask);
    return rc;
}
