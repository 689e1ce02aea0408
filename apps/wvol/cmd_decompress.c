/* SPDX-License-Identifier: MIT */
/* wvol decompress: .wvc -> volume (.raw, .nrrd, or any format the build writes),
 * optionally stopping after a coarser level. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "volume_out.h"
#include "wvol/io.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

const char wvol_cmd_decompress_summary[] = "decode a .wvc file into a volume (optionally a coarser level)";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output volume OUT.raw, OUT.nrrd (or another format this build writes)"},
    {"level", 0, 1, "stop after this level: 0 = full resolution (default), m = the level-m low-pass volume"},
    {"roi", 0, 1, "only the box x0,y0,z0,x1,y1,z1 (voxels of the original grid, x1 exclusive): decodes only the chunks it needs"},
    {"memory", 0, 1, "budget for decoded chunks, bytes or with K/M/G (default 1G): a region (--roi), or the whole volume when its decode would not fit, is read through the chunk cache within it and a .raw/.nrrd/.nhdr output written slab by slab"},
    CLI_THREADS_OPT,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

/* Formats the slab writer writes (wvol_slab_writer_open). */
static int slab_format(const char *path)
{
    return wvol_path_has_ext(path, ".raw") || wvol_path_has_ext(path, ".nrrd") || wvol_path_has_ext(path, ".nhdr");
}

/* The box [lo, hi) of level `level` into the file at path, slabs of whole slices in order (as
 * many as the library reads at a time: wvol_wvc_region_slab_slices), so the process holds the
 * decoded chunks (within the budget), one slab and the threads' parts of it. */
static wvol_status read_region_slabs(wvol_wvc_file *f, const size_t lo[3], const size_t hi[3], int level,
                                     const char *path, double spacing[3], double *t_write, wvol_error *err)
{
    const size_t nx = hi[0] - lo[0], ny = hi[1] - lo[1], nz = hi[2] - lo[2], slice = nx * ny * sizeof(float);
    const size_t dims[3] = {nx, ny, nz}, per = wvol_wvc_region_slab_slices(f, lo, hi);
    double origin[3];
    float *slab;
    wvol_slab_writer *w = NULL;
    wvol_status s;
    *t_write = 0;
    slab = malloc(per * slice);
    if (!slab) return wvol_error_set(err, WVOL_ERR_NOMEM, "decompress: out of memory for a slab of %zu slices", per);
    for (size_t z = lo[2]; z < hi[2]; z += per) {
        const size_t l[3] = {lo[0], lo[1], z}, h[3] = {hi[0], hi[1], z + per < hi[2] ? z + per : hi[2]};
        double sp[3], org[3], t0;
        s = wvol_wvc_read_region_into(slab, f, l, h, level, 0, sp, org, err);
        if (s != WVOL_OK) break;
        t0 = cli_now();
        if (!w) {
            memcpy(spacing, sp, sizeof sp);
            memcpy(origin, org, sizeof org);
            s = volume_out_claim(path, 0, err);
            if (s == WVOL_OK) s = wvol_slab_writer_open(&w, path, dims, spacing, origin, 0, err);
            if (s != WVOL_OK) break;
        }
        s = wvol_slab_writer_put(w, slab, h[2] - z, err);
        *t_write += cli_now() - t0;
        if (s != WVOL_OK) break;
    }
    free(slab);
    if (s == WVOL_OK) {
        double t0 = cli_now();
        s = wvol_slab_writer_commit(w, NULL, err);
        *t_write += cli_now() - t0;
    } else {
        wvol_slab_writer_abort(w);
    }
    return s;
}

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
    int roi = 0; /* 1: --roi; 2: the whole box read as a region (a decode over the budget) */
    size_t box[6], budget = 0;
    wvol_wvc_file *wf = NULL;
    wvol_wvc_cache_stats cs;
    size_t dims[3] = {0, 0, 0};
    double spacing[3] = {0, 0, 0};
    int streamed = 0;

    cli_parser_init(&p, "decompress", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input("decompress", &in, val)) return CLI_USAGE;
        } else if (o->short_name == 'h') {
            cli_print_help("decompress", "IN.wvc -o OUT.(raw|nrrd) [--level m] [--roi x0,y0,z0,x1,y1,z1] [--memory 1G] [--json]",
                           "Decodes a .wvc file and reconstructs the volume. With --level m only the levels\n"
                           "coarser than m are read (the file is read up to there) and the result is the\n"
                           "level-m low-pass volume: 2^m times coarser, spacing 2^m times larger. With --roi\n"
                           "only the box is reconstructed (at the level's resolution), from the chunks of a\n"
                           "version-2 file whose basis functions reach it, within --memory. A whole volume\n"
                           "is decoded in memory when its coefficients fit --memory (default 1G), else read\n"
                           "as the region of the whole box (a .raw, .nrrd or .nhdr output, written slab by\n"
                           "slab; other formats are made in memory whatever their size).",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) {
            outp = val;
        } else if (!strcmp(o->name, "level")) {
            if (!cli_parse_long("decompress", "level", val, 0, 30, &level)) return CLI_USAGE;
        } else if (!strcmp(o->name, "roi")) {
            double b[6];
            char *end;
            const char *q = val;
            for (int i = 0; i < 6; i++) {
                b[i] = strtod(q, &end);
                if (end == q || (i < 5 && *end != ',') || (i == 5 && *end) || !(b[i] >= 0 && b[i] < 1e15) ||
                    b[i] != (double)(size_t)b[i])
                    return cli_usage("decompress", "--roi %s: expected x0,y0,z0,x1,y1,z1 (voxel indices)", val);
                box[i] = (size_t)b[i];
                q = end + 1;
            }
            roi = 1;
        } else if (!strcmp(o->name, "memory")) {
            if (!cli_parse_bytes("decompress", "memory", val, &budget)) return CLI_USAGE;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("decompress", val, NULL)) return CLI_USAGE;
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
    /* a region reads the header and index only (read_info would check every chunk) */
    if (roi ? wvol_wvc_open(&wf, in, budget, &err) : wvol_wvc_read_info(info, in, &err)) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    if (roi) *info = *wvol_wvc_file_info(wf);
    if (level > info->levels) {
        rc = cli_usage("decompress", "--level %ld: %s has levels 0..%d", level, in, info->levels);
        goto done;
    }
    /* a whole decode holds every coefficient (the padded grid, whatever the level): when that
     * is over the budget and the output can be written slab by slab, the whole box of a
     * version-2 file is read as a region, through the chunk cache (the same values up to
     * float rounding: the region's synthesis sums in another order); version 1 has no
     * chunks to read by region and is decoded whole, as before */
    if (!roi && info->version == 2 && slab_format(outp) &&
        (double)info->px * (double)info->py * (double)info->pz * sizeof(float) >
            (double)(budget ? budget : WVOL_WVC_DEFAULT_BUDGET)) {
        if (wvol_wvc_open(&wf, in, budget, &err)) {
            rc = cli_fail_err("decompress", &err);
            goto done;
        }
        box[0] = box[1] = box[2] = 0;
        box[3] = info->nx, box[4] = info->ny, box[5] = info->nz;
        roi = 2;
    }
    if (roi) {
        /* the box at the level: the level's samples that cover the voxels asked for */
        size_t lo[3], hi[3], n[3] = {info->nx, info->ny, info->nz};
        for (int a = 0; a < 3; a++) {
            size_t dl = n[a] > 1 ? (n[a] + ((size_t)1 << level) - 1) >> level : 1;
            if (box[a] >= box[a + 3] || box[a + 3] > n[a]) {
                rc = cli_usage("decompress", "--roi: %zu..%zu along axis %d is empty or outside 0..%zu", box[a],
                               box[a + 3], a, n[a]);
                goto done;
            }
            lo[a] = n[a] > 1 ? box[a] >> level : 0;
            hi[a] = n[a] > 1 ? (box[a + 3] + ((size_t)1 << level) - 1) >> level : 1;
            if (hi[a] > dl) hi[a] = dl;
        }
        t0 = cli_now();
        for (int a = 0; a < 3; a++) dims[a] = hi[a] - lo[a];
        if (slab_format(outp)) {
            /* slab by slab into the file: the output is never held whole, so the process
             * stays within the chunk budget plus one slab. A cache smaller than the slabs'
             * chunks would decode them again slab after slab (with 2048^2 slices, every chunk
             * once per slab): without --memory the default grows to that need; a --memory
             * below it is kept, with a note. */
            size_t need = wvol_wvc_slab_budget(wf, (int)level, lo, hi);
            if (!budget && need > WVOL_WVC_DEFAULT_BUDGET) {
                if (wvol_wvc_set_budget(wf, need, &err) != WVOL_OK) {
                    rc = cli_fail_err("decompress", &err);
                    goto done;
                }
            } else if (budget && need > budget) {
                fprintf(stderr, "decompress: note: --memory %zu bytes is below the %zu bytes of chunks a slab of this box "
                        "needs; chunks evicted between slabs will be decoded again\n", budget, need);
            }
            if (read_region_slabs(wf, lo, hi, (int)level, outp, spacing, &t_write, &err) != WVOL_OK) {
                rc = cli_fail_err("decompress", &err);
                goto done;
            }
            t_read = cli_now() - t0 - t_write;
            streamed = 1;
        } else {
            if (wvol_wvc_read_region(&v, wf, lo, hi, (int)level, &err) != WVOL_OK) {
                rc = cli_fail_err("decompress", &err);
                goto done;
            }
            t_read = cli_now() - t0;
        }
        t_inv = 0;
        wvol_wvc_file_stats(wf, &cs);
    } else {
    wvol_wvc_read_options_default(&ro);
    ro.stop_level = (int)level;
    t0 = cli_now();
    if (wvol_wvc_read(&c, in, &ro, info, &err) != WVOL_OK) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    t_read = cli_now() - t0;
    t0 = cli_now();
    if ((level ? wvol_idwt3_level(&v, c, (int)level, &err) : wvol_idwt3_consume(&v, &c, &err)) != WVOL_OK) {
        rc = cli_fail_err("decompress", &err);
        goto done;
    }
    t_inv = cli_now() - t0;
    }
    if (!streamed) {
        t0 = cli_now();
        if (volume_out_claim(outp, 0, &err) != WVOL_OK || wvol_volume_save(v, outp, &err) != WVOL_OK) {
            rc = cli_fail_err("decompress", &err);
            goto done;
        }
        t_write = cli_now() - t0;
        dims[0] = v->nx, dims[1] = v->ny, dims[2] = v->nz;
        memcpy(spacing, v->spacing, sizeof spacing);
    }
    if (json) {
        cli_json_begin();
        cli_json_str("input", in);
        cli_json_str("output", outp);
        cli_json_int("level", level);
        cli_json_size3("dims", dims[0], dims[1], dims[2]);
        cli_json_num3("spacing", spacing);
        cli_json_open("seconds", '{');
        cli_json_num("read_decode", t_read);
        cli_json_num("inverse_transform", t_inv);
        cli_json_num("write", t_write);
        cli_json_close('}');
        if (wf) cli_json_int("slabs", streamed);
        if (wf) cli_json_wvc_cache("chunks", &cs, wvol_wvc_file_info(wf)->chunks);
        cli_json_end();
    } else {
        if (wf)
            printf("%s -> %s: %zu x %zu x %zu %s%s%s (%llu of %llu chunks decoded, %llu bytes read, cache peak %zu "
                   "bytes; read+reconstruct %.3f s, write %.3f s)\n",
                   in, outp, dims[0], dims[1], dims[2], roi == 2 ? "volume" : "region",
                   level ? " of a coarser level" : "", roi == 2 ? ", slab by slab within --memory" : "",
                   (unsigned long long)cs.decoded,
                   (unsigned long long)wvol_wvc_file_info(wf)->chunks, (unsigned long long)cs.bytes_read, cs.peak,
                   t_read, t_write);
        else
            printf("%s -> %s: %zu x %zu x %zu%s (decode %.3f s, inverse %.3f s, write %.3f s)\n", in, outp, v->nx,
                   v->ny, v->nz, level ? " (coarser level)" : "", t_read, t_inv, t_write);
    }
    rc = CLI_OK;
done:
    wvol_wvc_close(wf);
    free(info);
    wvol_volume_destroy(v);
    wvol_coeffs_destroy(c);
    return rc;
}
