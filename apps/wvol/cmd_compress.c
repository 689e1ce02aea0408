/* SPDX-License-Identifier: MIT */
/* wvol compress: volume -> wavelet transform -> selection -> quantiser + coder -> .wvc,
 * then decodes the file it wrote and reports the measured error beside the predicted one. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "output_set.h"
#include "source_in.h"
#include "wvol/compress.h"
#include "wvol/io.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

const char wvol_cmd_compress_summary[] = "compress a volume into a .wvc file (wavelets, quantiser, entropy coder)";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output file OUT.wvc"},
    {"wavelet", 'w', 1, "filter: auto (default: a trial on a sample keeps db2 unless db4, coif2 or haar saves > 10% of "
                        "the bits), haar, db1..db10, coif1..coif5, bl3"},
    {"levels", 'l', 1, "levels 1..max (default min(5, max))"},
    {"psnr", 0, 1, "target PSNR in dB (peak = data range): the quantiser step is chosen to meet it"},
    {"keep", 0, 1, "keep this fraction of the coefficients, largest first (5% or 0.05)"},
    {"keep-count", 0, 1, "keep the K largest coefficients (low-pass cube included)"},
    {"energy", 0, 1, "keep the smallest set holding this share of the energy (0.999)"},
    {"step", 0, 1, "quantiser step (overrides the one chosen from the error target)"},
    {"roi", 0, 1, "region of interest cx,cy,cz,rx,ry,rz (world units; repeatable): ranks detail there first"},
    {"roi-floor", 0, 1, "LOD weight far from every region, 0..1 (default 0.1)"},
    {"drop-levels", 0, 1, "drop the n finest levels entirely"},
    {"quant-share", 0, 1, "selection modes: quantisation error as a share of the dropped energy (default 0.02)"},
    {"coder", 0, 1,
     "auto (default: chunk mode 4, the fastest decode, where a chunk allows; docs/wvc-format.md), compact (the "
     "smaller of modes 0, 2, 3 per chunk), cabac, zstd, rans or rans4"},
    {"rounding", 0, 1, "dead-zone rounding offset in [0, 0.5] (default 0.38)"},
    {"format", 0, 1, ".wvc format version: 2 (default: chunks, random access) or 1"},
    {"tile", 0, 1, "format 2: chunk size in coefficients, XY or XY,Z, powers of two in 8..256 (default 64,32)"},
    CLI_LOAD_OPTS,
    CLI_THREADS_OPT,
    {"verify", 0, 0, "decode the file written and measure its error (the encoder's own error is exact)"},
    {"in-memory", 0, 0, "hold the volume in memory even when the input streams (raw, NRRD, synth:)"},
    {"memory", 0, 1, "streamed input: keep the transformed volume between the two passes when it fits in this many "
                     "bytes, K/M/G (default 1G; a smaller budget reads and transforms the source twice)"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

enum { MODE_NONE, MODE_PSNR, MODE_KEEP, MODE_COUNT, MODE_ENERGY };

static int parse_roi(const char *s, wvol_lod_ellipsoid *e)
{
    double v[6];
    char *end;
    const char *q = s;
    int i;
    for (i = 0; i < 6; i++) {
        v[i] = strtod(q, &end);
        if (end == q || !isfinite(v[i])) break;
        q = end;
        if (i < 5) {
            if (*q != ',') break;
            q++;
        }
    }
    if (i < 6 || *q) return cli_usage("compress", "--roi '%s': expected cx,cy,cz,rx,ry,rz", s), 0;
    for (i = 0; i < 3; i++) {
        e->center[i] = v[i];
        e->radii[i] = v[3 + i];
        if (!(v[3 + i] > 0)) return cli_usage("compress", "--roi '%s': radii must be > 0", s), 0;
    }
    e->power = 2; /* flat-topped: full detail inside the ellipsoid, fading outside */
    return 1;
}

/* --wavelet auto: the library's trial (wvol_compress_choose_wavelet) on src; cp->wavelet
 * becomes the filter chosen. The CLI runs it itself, not through wvol_compress, to report it. */
static wvol_status choose_wavelet(wvol_wavelet_choice *wc, wvol_source *src, wvol_compress_params *cp,
                                  wvol_error *err)
{
    wvol_status s = wvol_compress_choose_wavelet(wc, src, cp, err);
    if (s == WVOL_OK) cp->wavelet = wc->wavelet;
    return s;
}

static void choice_json(const wvol_wavelet_choice *wc)
{
    cli_json_open("wavelet_choice", '{');
    cli_json_str("chosen", wc->wavelet);
    cli_json_num("margin", wc->margin);
    if (wc->psnr > 0) cli_json_num("psnr", wc->psnr);
    cli_json_int("blocks", wc->blocks);
    cli_json_int("sample_voxels", (long long)wc->sample_voxels);
    cli_json_int("sample_coefficients", (long long)wc->sample_coefficients);
    cli_json_open("bits_per_coefficient", '{');
    for (int i = 0; i < wc->candidates; i++) cli_json_num(wc->name[i], wc->bits[i]);
    cli_json_close('}');
    cli_json_num("seconds", wc->seconds);
    cli_json_close('}');
}

static void choice_text(const wvol_wavelet_choice *wc)
{
    printf("wavelet    auto: %s (estimated bits per sampled coefficient", wc->wavelet);
    for (int i = 0; i < wc->candidates; i++) printf("%s %s %.4f", i ? "," : "", wc->name[i], wc->bits[i]);
    printf("; db2 unless another saves > %.0f%%; %zu voxels sampled in %.3f s)\n", 100 * wc->margin,
           wc->sample_voxels, wc->seconds);
}

/* The streamed path (wvol_compress_stream): the volume is never held; with verify the file
 * is decoded and compared with the source read again (that holds both volumes). */
static int compress_streamed(const char *in, const char *outp, const wvol_load_options *lo, wvol_compress_params *cp,
                             double psnr, int verify, int json)
{
    wvol_source *src = NULL;
    wvol_wavelet_choice wc;
    int chose = wvol_compress_wavelet_is_auto(cp->wavelet);
    wvol_compress_stream_report rep;
    wvol_error err;
    wvol_volume *v = NULL, *rec = NULL;
    wvol_coeffs *dec = NULL;
    const wvol_filter *f = NULL;
    size_t dims[3];
    double t0, t_all, nvox, raw_bytes, bpv, sse_meas = 0, maxerr = 0, t_dec = 0, t_idwt = 0;
    double p_psnr, m_psnr = 0;
    int rc = CLI_FAILED;

    wvol_error_clear(&err);
    if (source_in_open(&src, in, lo, &err) != WVOL_OK) return cli_fail_err("compress", &err);
    wvol_source_geometry(src, dims, NULL, NULL);
    nvox = (double)dims[0] * (double)dims[1] * (double)dims[2];
    if (wvol_dwt_max_levels(dims[0], dims[1], dims[2]) < 1) { /* as the in-memory path says it */
        rc = cli_fail("compress", "%s: a %zux%zux%zu volume cannot be transformed", in, dims[0], dims[1], dims[2]);
        goto done;
    }
    if (cp->levels > 0 && cp->levels > wvol_dwt_max_levels(dims[0], dims[1], dims[2])) {
        rc = cli_usage("compress", "--levels %d: a %zux%zux%zu volume allows 1..%d", cp->levels, dims[0], dims[1],
                       dims[2], wvol_dwt_max_levels(dims[0], dims[1], dims[2]));
        goto done;
    }
    t0 = cli_now();
    /* the trial reads the sample's slices; the passes then read the source from the start */
    if (chose && choose_wavelet(&wc, src, cp, &err) != WVOL_OK) goto fail;
    if (wvol_filter_get(&f, cp->wavelet, &err) != WVOL_OK) goto fail;
    /* written, then decoded to check a target: a miss undoes it (main's output_set_undo) */
    if (output_set_add(outp, &err) != WVOL_OK) goto fail;
    if (wvol_compress_stream(outp, src, cp, &rep, &err) != WVOL_OK) {
        /* the options were checked above: what fails now is what the input decides (a target or
         * a step its coefficients cannot have: bad input, exit 1, as the in-memory path), or
         * reading and writing; the library's message names it */
        rc = cli_fail("compress", "%s", err.message);
        goto done;
    }
    t_all = cli_now() - t0;
    p_psnr = wvol_wvc_psnr(rep.sse_quant, nvox, rep.value_min, rep.value_max);
    if (verify) {
        t0 = cli_now();
        if (wvol_wvc_read(&dec, outp, NULL, NULL, &err) != WVOL_OK) goto fail;
        t_dec = cli_now() - t0;
        t0 = cli_now();
        if (wvol_idwt3(&rec, dec, &err) != WVOL_OK) goto fail;
        t_idwt = cli_now() - t0;
        if (wvol_source_read_volume(src, &v, &err) != WVOL_OK || wvol_wvc_compare(&sse_meas, &maxerr, v, rec, &err))
            goto fail;
        m_psnr = wvol_wvc_psnr(sse_meas, nvox, rep.value_min, rep.value_max);
        if (psnr > 0 && m_psnr < psnr - 0.01) {
            /* as in memory: the encoder's error is exact in double, so a miss is the float32
             * decoding's own rounding (subnormal values); the output is undone */
            rc = cli_fail("compress",
                          "%s with --psnr %g: the decoded volume measures %.3f dB (predicted %.3f dB): float32 "
                          "cannot hold the reconstruction that precisely at magnitudes ~%.3g (subnormal below "
                          "1.18e-38); the output is left as it was",
                          in, psnr, m_psnr, p_psnr, fmax(fabs(rep.value_min), fabs(rep.value_max)));
            goto done;
        }
    }
    raw_bytes = nvox * sizeof(float);
    bpv = 8.0 * (double)rep.bytes / nvox;
    if (json) {
        cli_json_begin();
        cli_json_str("input", in);
        cli_json_str("output", outp);
        cli_json_str("wavelet", f->name);
        if (chose) choice_json(&wc);
        cli_json_int("levels", rep.levels);
        cli_json_int("threads", omp_get_max_threads());
        cli_json_size3("dims", dims[0], dims[1], dims[2]);
        cli_json_str("mode", "psnr");
        cli_json_key("streamed");
        printf("true");
        cli_json_int("passes", rep.passes);
        cli_json_int("source_reads", rep.source_reads);
        cli_json_int("kept_bytes", (long long)rep.kept_bytes);
        if (psnr > 0) cli_json_num("target_psnr", psnr);
        cli_json_int("raw_bytes", (long long)raw_bytes);
        cli_json_int("bytes", (long long)rep.bytes);
        cli_json_int("bytes_cabac", (long long)rep.wvc.bytes_cabac);
        cli_json_int("bytes_zstd", (long long)rep.wvc.bytes_zstd);
        cli_json_int("bytes_rans", (long long)rep.wvc.bytes_rans);
        cli_json_num("ratio", raw_bytes / (double)rep.bytes);
        cli_json_num("bits_per_voxel", bpv);
        cli_json_num("step", rep.step);
        cli_json_int("coefficients", (long long)rep.wvc.coefficients);
        cli_json_int("nonzero", (long long)rep.wvc.nonzero);
        cli_json_num("value_min", rep.value_min);
        cli_json_num("value_max", rep.value_max);
        cli_json_int("window_bytes", (long long)rep.window_bytes);
        cli_json_int("writer_bytes", (long long)rep.writer_bytes);
        cli_json_open("predicted", '{');
        cli_json_num("dropped_energy", 0);
        cli_json_num("quantisation_sse", rep.sse_quant);
        cli_json_num("sse", rep.sse_quant);
        cli_json_num("rmse", sqrt(rep.sse_quant / nvox));
        cli_json_num("psnr", p_psnr); /* null when infinite (lossless) */
        cli_json_close('}');
        if (verify) {
            cli_json_open("measured", '{');
            cli_json_num("sse", sse_meas);
            cli_json_num("rmse", sqrt(sse_meas / nvox));
            cli_json_num("psnr", m_psnr); /* null when infinite (lossless) */
            cli_json_num("max_error", maxerr);
            cli_json_close('}');
        }
        cli_json_open("seconds", '{');
        if (chose) cli_json_num("wavelet_trial", wc.seconds);
        cli_json_num("statistics_pass", rep.seconds_stats);
        cli_json_num("write_pass", rep.seconds_write);
        cli_json_num("encode", t_all);
        if (verify) {
            cli_json_num("decode", t_dec);
            cli_json_num("inverse_transform", t_idwt);
        }
        cli_json_close('}');
        cli_json_num("compress_mb_per_s", raw_bytes / 1e6 / (t_all > 0 ? t_all : 1e-9));
        cli_json_end();
    } else {
        printf("%s -> %s (%s, %d levels, streamed in %d passes, the source read %s)\n", in, outp, f->name,
               rep.levels, rep.passes, rep.source_reads == 1 ? "once" : rep.source_reads == 2 ? "twice" : "more often");
        if (chose) choice_text(&wc);
        printf("size       %.0f -> %zu bytes, ratio %.1f, %.4f bits/voxel\n", raw_bytes, rep.bytes,
               raw_bytes / (double)rep.bytes, bpv);
        printf("quantiser  step %.6g, %llu of %llu coefficients non-zero\n", rep.step,
               (unsigned long long)rep.wvc.nonzero, (unsigned long long)rep.wvc.coefficients);
        printf("encoder    RMSE %.6g, PSNR %.3f dB (exact quantisation error; peak = range %.6g)\n",
               sqrt(rep.sse_quant / nvox), p_psnr, rep.value_max - rep.value_min);
        if (verify)
            printf("measured   RMSE %.6g, PSNR %.3f dB, max error %.6g\n", sqrt(sse_meas / nvox), m_psnr, maxerr);
        printf("memory     transform window %.1f MiB, writer rows %.1f MiB, kept coefficients %.1f MiB\n",
               rep.window_bytes / 1048576.0, rep.writer_bytes / 1048576.0, rep.kept_bytes / 1048576.0);
        printf("time       statistics pass %.3f s, write pass %.3f s: %.1f MB/s\n", rep.seconds_stats, rep.seconds_write,
               raw_bytes / 1e6 / (t_all > 0 ? t_all : 1e-9));
    }
    rc = CLI_OK;
    goto done;
fail:
    rc = cli_fail_err("compress", &err);
done:
    wvol_volume_destroy(v);
    wvol_volume_destroy(rec);
    wvol_coeffs_destroy(dec);
    wvol_source_destroy(src);
    return rc;
}

int wvol_cmd_compress(int argc, char **argv)
{
    cli_parser p;
    const cli_opt *o;
    const char *val, *in = NULL, *outp = NULL;
    int r, json = 0, mode = MODE_NONE, modes = 0, max, rc = CLI_FAILED;
    long levels = 0, drop = 0, kcount = 0;
    double psnr = 0, frac = 0, energy = 0, step = 0, quant_share = 0.02, roi_floor = 0.1, rounding = -1;
    wvol_wvc_coder coder = WVOL_WVC_CODER_AUTO;
    long format = 0, tile = 0, tile_z = 0;
    wvol_load_options lo;
    wvol_error err;
    wvol_volume *v = NULL, *rec = NULL;
    wvol_coeffs *dec = NULL;
    wvol_compress_params cp;
    wvol_compressed cc;
    wvol_select_params *sp = &cp.select;
    wvol_wvc_report wrep;
    const wvol_filter *f;
    void *buf = NULL;
    size_t nbytes = 0, nvox;
    double vmin, vmax, t0, t_load, t_dwt, t_sel = 0, t_enc, t_write, t_dec, t_idwt, dropped = 0;
    double sse_pred, sse_meas = 0, maxerr = 0;
    int use_select, verify = 0, in_memory = 0, chose;
    wvol_wavelet_choice wc;

    memset(&cc, 0, sizeof cc);
    wvol_compress_params_default(&cp);
    cp.wavelet = WVOL_COMPRESS_WAVELET_AUTO;
    wvol_load_options_default(&lo);
    cli_parser_init(&p, "compress", argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input("compress", &in, val)) return CLI_USAGE;
        } else if (o->short_name == 'h') {
            cli_print_help("compress",
                           "IN -o OUT.wvc [--wavelet auto] [--levels 5] (--psnr 50 | --keep 5% | --keep-count K |\n"
                           "       --energy 0.999) [--roi cx,cy,cz,rx,ry,rz ...] [--drop-levels n] [--json]",
                           "Transforms the volume, optionally selects coefficients by energy (with regions of\n"
                           "interest and a level cut), quantises with a dead-zone step chosen from the error\n"
                           "target and entropy-codes each sub-band (docs/wvc-format.md). With --psnr the step\n"
                           "alone meets the target (default: --psnr 50). It prints sizes, ratio, bits per\n"
                           "voxel, the encoder's exact error and timings; with --verify it also decodes what\n"
                           "it wrote and prints the measured error.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "output")) {
            outp = val;
        } else if (!strcmp(o->name, "wavelet")) {
            cp.wavelet = val;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long("compress", "levels", val, 1, 30, &levels)) return CLI_USAGE;
        } else if (!strcmp(o->name, "psnr")) {
            if (!cli_parse_double("compress", "psnr", val, &psnr)) return CLI_USAGE;
            if (!(psnr > 0 && psnr < 200)) return cli_usage("compress", "--psnr %s: expected 0 < dB < 200", val);
            mode = MODE_PSNR, modes++;
        } else if (!strcmp(o->name, "keep")) {
            if (!cli_parse_fraction("compress", "keep", val, &frac)) return CLI_USAGE;
            mode = MODE_KEEP, modes++;
        } else if (!strcmp(o->name, "keep-count")) {
            if (!cli_parse_long("compress", "keep-count", val, 1, 0x7fffffffffffffffL, &kcount)) return CLI_USAGE;
            mode = MODE_COUNT, modes++;
        } else if (!strcmp(o->name, "energy")) {
            if (!cli_parse_fraction("compress", "energy", val, &energy)) return CLI_USAGE;
            mode = MODE_ENERGY, modes++;
        } else if (!strcmp(o->name, "step")) {
            if (!cli_parse_double("compress", "step", val, &step)) return CLI_USAGE;
            if (!(step > 0)) return cli_usage("compress", "--step %s: must be > 0", val);
        } else if (!strcmp(o->name, "roi")) {
            if (sp->n_ellipsoids >= WVOL_LOD_MAX_ELLIPSOIDS)
                return cli_usage("compress", "--roi: at most %d regions", WVOL_LOD_MAX_ELLIPSOIDS);
            if (!parse_roi(val, &sp->ellipsoids[sp->n_ellipsoids])) return CLI_USAGE;
            sp->n_ellipsoids++;
        } else if (!strcmp(o->name, "roi-floor")) {
            if (!cli_parse_double("compress", "roi-floor", val, &roi_floor)) return CLI_USAGE;
            if (!(roi_floor >= 0 && roi_floor <= 1)) return cli_usage("compress", "--roi-floor %s: expected 0..1", val);
        } else if (!strcmp(o->name, "drop-levels")) {
            if (!cli_parse_long("compress", "drop-levels", val, 0, 29, &drop)) return CLI_USAGE;
        } else if (!strcmp(o->name, "quant-share")) {
            if (!cli_parse_double("compress", "quant-share", val, &quant_share)) return CLI_USAGE;
            if (!(quant_share > 0 && quant_share <= 1))
                return cli_usage("compress", "--quant-share %s: expected 0 < share <= 1", val);
        } else if (!strcmp(o->name, "coder")) {
            if (!strcmp(val, "auto")) coder = WVOL_WVC_CODER_AUTO;
            else if (!strcmp(val, "cabac")) coder = WVOL_WVC_CODER_CABAC;
            else if (!strcmp(val, "zstd")) coder = WVOL_WVC_CODER_ZSTD;
            else if (!strcmp(val, "rans")) coder = WVOL_WVC_CODER_RANS;
            else if (!strcmp(val, "rans4")) coder = WVOL_WVC_CODER_RANS4;
            else if (!strcmp(val, "compact")) coder = WVOL_WVC_CODER_COMPACT;
            else return cli_usage("compress", "--coder '%s': expected auto, compact, cabac, zstd, rans or rans4", val);
        } else if (!strcmp(o->name, "format")) {
            if (!cli_parse_long("compress", "format", val, 1, 2, &format)) return CLI_USAGE;
        } else if (!strcmp(o->name, "tile")) {
            char *end;
            tile = strtol(val, &end, 10);
            tile_z = *end == ',' ? strtol(end + 1, &end, 10) : tile;
            if (*end || tile < 8 || tile > 256 || tile_z < 8 || tile_z > 256 || (tile & (tile - 1)) ||
                (tile_z & (tile_z - 1)))
                return cli_usage("compress", "--tile %s: expected XY or XY,Z, powers of two in 8..256", val);
        } else if (!strcmp(o->name, "rounding")) {
            if (!cli_parse_double("compress", "rounding", val, &rounding)) return CLI_USAGE;
            if (!(rounding >= 0 && rounding <= 0.5)) return cli_usage("compress", "--rounding %s: expected 0..0.5", val);
        } else if (!strcmp(o->name, "json")) {
            json = 1;
        } else if (!strcmp(o->name, "verify")) {
            verify = 1;
        } else if (!strcmp(o->name, "in-memory")) {
            in_memory = 1;
        } else if (!strcmp(o->name, "memory")) {
            if (!cli_parse_bytes("compress", "memory", val, &cp.memory)) return CLI_USAGE;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads("compress", val, NULL)) return CLI_USAGE;
        } else if (cli_load_option("compress", o, val, &lo) == CLI_USAGE) {
            return CLI_USAGE;
        }
    }
    if (!in) return cli_usage("compress", "missing input file (see 'wvol compress --help')");
    if (!outp) return cli_usage("compress", "missing -o OUT.wvc");
    if (cli_load_options_fit("compress", in, NULL) != CLI_OK) return CLI_USAGE;
    if (!wvol_path_has_ext(outp, ".wvc")) return cli_usage("compress", "-o %s: the output must end in .wvc", outp);
    if (modes > 1) return cli_usage("compress", "choose one of --psnr, --keep, --keep-count, --energy");
    if (mode == MODE_NONE) mode = MODE_PSNR, psnr = 50;
    if (sp->n_ellipsoids && mode == MODE_PSNR)
        return cli_usage("compress", "--roi ranks coefficients: use it with --keep, --keep-count or --energy");
    if (cli_given(&p, "roi-floor") && !sp->n_ellipsoids)
        return cli_usage("compress", "--roi-floor weights the coefficients outside the --roi regions: add --roi");
    if ((coder == WVOL_WVC_CODER_RANS || coder == WVOL_WVC_CODER_RANS4) && format == 1)
        return cli_usage("compress", "--coder rans and rans4 write chunks of format 2: --format 1 has none");
    if (cli_given(&p, "tile") && format == 1)
        return cli_usage("compress", "--tile sets the chunks of format 2: --format 1 has none");
    wvol_error_clear(&err);
    chose = wvol_compress_wavelet_is_auto(cp.wavelet);
    if (!chose && wvol_filter_get(&f, cp.wavelet, &err) != WVOL_OK)
        return cli_usage("compress", "--wavelet %s: %s, or auto (the default)", cp.wavelet, err.message);

    if (!in_memory && source_in_streams(in) && mode == MODE_PSNR && drop == 0 && format != 1) {
        cp.levels = (int)levels;
        cp.for_file = 1;
        cp.build_store = 0;
        cp.quant.psnr = psnr;
        cp.quant.share = quant_share;
        cp.quant.step = step;
        cp.quant.rounding = rounding;
        cp.quant.coder = coder;
        cp.quant.tile = (int)tile;
        cp.quant.tile_z = (int)tile_z;
        return compress_streamed(in, outp, &lo, &cp, step > 0 ? 0 : psnr, verify, json);
    }
    t0 = cli_now();
    if (source_in_is_synth(in)) {
        wvol_source *src = NULL;
        if (source_in_open(&src, in, &lo, &err) != WVOL_OK || wvol_source_read_volume(src, &v, &err) != WVOL_OK) {
            wvol_source_destroy(src);
            return cli_fail_err("compress", &err);
        }
        wvol_source_destroy(src);
    } else if (wvol_volume_load(&v, in, &lo, &err) != WVOL_OK) {
        return cli_fail_err("compress", &err);
    }
    t_load = cli_now() - t0;
    nvox = wvol_volume_count(v);
    max = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
    if (max < 1) {
        rc = cli_fail("compress", "%s: a %zux%zux%zu volume cannot be transformed", in, v->nx, v->ny, v->nz);
        goto done;
    }
    if (levels > max) {
        rc = cli_usage("compress", "--levels %ld: a %zux%zux%zu volume allows 1..%d", levels, v->nx, v->ny, v->nz, max);
        goto done;
    }
    cp.levels = (int)levels;
    cp.for_file = 1;
    cp.build_store = 0;
    levels = wvol_compress_levels(v, &cp);
    if (drop >= levels) {
        rc = cli_usage("compress", "--drop-levels %ld: must be below --levels %ld", drop, levels);
        goto done;
    }
    /* selection: ranks by energy (with LOD weights) and zeroes what it drops; with --psnr
     * alone it keeps everything and the quantiser step meets the target */
    use_select = mode != MODE_PSNR || drop > 0;
    cp.select.mode = mode == MODE_KEEP ? WVOL_SELECT_FRACTION
                     : mode == MODE_COUNT ? WVOL_SELECT_COUNT
                     : mode == MODE_ENERGY ? WVOL_SELECT_ENERGY
                                           : WVOL_SELECT_ALL;
    cp.select.fraction = frac;
    cp.select.count = (size_t)kcount;
    cp.select.energy = energy;
    cp.select.drop_levels = (int)drop;
    cp.select.lod_floor = roi_floor;
    cp.quant.psnr = mode == MODE_PSNR ? psnr : 0;
    cp.quant.share = quant_share;
    cp.quant.step = step;
    cp.quant.rounding = rounding;
    cp.quant.coder = coder;
    cp.quant.format_version = (int)format;
    cp.quant.tile = (int)tile;
    cp.quant.tile_z = (int)tile_z;
    if (chose) {
        /* the same trial as the streamed path's, on the same sample read through a source */
        wvol_source *vs = NULL;
        wvol_status s = wvol_source_of_volume(&vs, v, &err);
        if (s == WVOL_OK) s = choose_wavelet(&wc, vs, &cp, &err);
        wvol_source_destroy(vs);
        if (s != WVOL_OK) {
            rc = cli_fail_err("compress", &err);
            goto done;
        }
    }
    if (wvol_filter_get(&f, cp.wavelet, &err) != WVOL_OK) {
        rc = cli_fail_err("compress", &err);
        goto done;
    }
    if (wvol_compress(&cc, v, &cp, &err) != WVOL_OK) {
        rc = cli_fail_err("compress", &err);
        goto done;
    }
    vmin = cc.value_min, vmax = cc.value_max;
    t_dwt = cc.seconds_transform;
    t_sel = use_select ? cc.seconds_select : 0;
    dropped = cc.report.energy_dropped;
    t0 = cli_now();
    if (wvol_compress_encode(&buf, &nbytes, &cc, &cp, &wrep, &err) != WVOL_OK) {
        /* the error target cannot be met (a constant volume, or levels dropped beyond it): bad
         * input (exit 1), whatever the status; the library's message names the target */
        rc = mode == MODE_PSNR ? cli_fail("compress", "%s", err.message) : cli_fail_err("compress", &err);
        goto done;
    }
    t_enc = cli_now() - t0;
    t0 = cli_now();
    if (output_set_add(outp, &err) != WVOL_OK || wvol_wvc_save(outp, buf, nbytes, &err) != WVOL_OK) {
        rc = cli_fail_err("compress", &err);
        goto done;
    }
    t_write = cli_now() - t0;

    /* measure (--verify): decode what was written and compare with the input; without it the
     * error reported is the encoder's, exact by Parseval */
    t0 = cli_now();
    t_dec = t_idwt = 0;
    if (verify && wvol_wvc_decode(&dec, buf, nbytes, NULL, NULL, &err) != WVOL_OK) {
        rc = cli_fail_err("compress", &err);
        goto done;
    }
    t_dec = cli_now() - t0;
    t0 = cli_now();
    if (verify && wvol_idwt3(&rec, dec, &err) != WVOL_OK) {
        rc = cli_fail_err("compress", &err);
        goto done;
    }
    t_idwt = cli_now() - t0; /* the comparison below is measurement, not decompression */
    if (verify && wvol_wvc_compare(&sse_meas, &maxerr, v, rec, &err) != WVOL_OK) {
        rc = cli_fail_err("compress", &err);
        goto done;
    }
    sse_pred = dropped + wrep.sse_quant;
    {
        double raw_bytes = (double)nvox * sizeof(float), bpv = 8.0 * (double)nbytes / (double)nvox;
        double ratio = raw_bytes / (double)nbytes;
        double p_rmse = sqrt(sse_pred / (double)nvox), m_rmse = sqrt(sse_meas / (double)nvox);
        double p_psnr = wvol_wvc_psnr(sse_pred, (double)nvox, vmin, vmax);
        double m_psnr = wvol_wvc_psnr(sse_meas, (double)nvox, vmin, vmax);
        double t_total = t_dwt + t_sel + t_enc + (chose ? wc.seconds : 0);
        if (verify && mode == MODE_PSNR && step == 0 && m_psnr < psnr - 0.01) {
            /* a target is met or refused, never missed with status 0: the quantiser's error is
             * exact in double, so a miss is the float32 decoding's own rounding (subnormal values) */
            rc = cli_fail("compress",
                          "%s with --psnr %g: the decoded volume measures %.3f dB (predicted %.3f dB): float32 "
                          "cannot hold the reconstruction that precisely at magnitudes ~%.3g (subnormal below "
                          "1.18e-38); the output is left as it was",
                          in, psnr, m_psnr, p_psnr, fmax(fabs(vmin), fabs(vmax)));
            goto done;
        }
        double mbs = raw_bytes / 1e6 / (t_total > 0 ? t_total : 1e-9);
        if (json) {
            cli_json_begin();
            cli_json_str("input", in);
            cli_json_str("output", outp);
            cli_json_str("wavelet", f->name);
            if (chose) choice_json(&wc);
            cli_json_int("levels", levels);
            cli_json_int("threads", omp_get_max_threads());
            cli_json_size3("dims", v->nx, v->ny, v->nz);
            cli_json_str("mode", mode == MODE_PSNR ? "psnr" : mode == MODE_KEEP ? "keep"
                                 : mode == MODE_COUNT ? "keep-count" : "energy");
            if (mode == MODE_PSNR) cli_json_num("target_psnr", psnr);
            cli_json_int("raw_bytes", (long long)raw_bytes);
            cli_json_int("bytes", (long long)nbytes);
            cli_json_int("bytes_cabac", (long long)wrep.bytes_cabac);
            cli_json_int("bytes_zstd", (long long)wrep.bytes_zstd);
            cli_json_int("bytes_rans", (long long)wrep.bytes_rans);
            cli_json_num("ratio", ratio);
            cli_json_num("bits_per_voxel", bpv);
            cli_json_num("step", wrep.step);
            cli_json_int("step_iterations", wrep.step_iterations);
            cli_json_int("coefficients", (long long)wrep.coefficients);
            cli_json_int("nonzero", (long long)wrep.nonzero);
            if (use_select) cli_json_int("kept_by_selection", (long long)cc.report.kept);
            cli_json_num("value_min", vmin);
            cli_json_num("value_max", vmax);
            cli_json_open("predicted", '{');
            cli_json_num("dropped_energy", dropped);
            cli_json_num("quantisation_sse", wrep.sse_quant);
            cli_json_num("sse", sse_pred);
            cli_json_num("rmse", p_rmse);
            cli_json_num("psnr", p_psnr); /* null when infinite (lossless) */
            cli_json_close('}');
            if (verify) {
                cli_json_open("measured", '{');
                cli_json_num("sse", sse_meas);
                cli_json_num("rmse", m_rmse);
                cli_json_num("psnr", m_psnr); /* null when infinite (lossless) */
                cli_json_num("max_error", maxerr);
                cli_json_close('}');
            }
            cli_json_open("seconds", '{');
            cli_json_num("load", t_load);
            if (chose) cli_json_num("wavelet_trial", wc.seconds);
            cli_json_num("transform", t_dwt);
            cli_json_num("select", t_sel);
            cli_json_num("step_search", wrep.seconds_step);
            cli_json_num("quantise", wrep.seconds_quantise);
            cli_json_num("code", wrep.seconds_code);
            cli_json_num("encode", t_enc);
            cli_json_num("write", t_write);
            if (verify) {
                cli_json_num("decode", t_dec);
                cli_json_num("inverse_transform", t_idwt);
            }
            cli_json_close('}');
            cli_json_num("compress_mb_per_s", mbs);
            if (verify)
                cli_json_num("decompress_mb_per_s", raw_bytes / 1e6 / (t_dec + t_idwt > 0 ? t_dec + t_idwt : 1e-9));
            cli_json_end();
        } else {
            printf("%s -> %s (%s, %ld levels)\n", in, outp, f->name, levels);
            if (chose) choice_text(&wc);
            printf("size       %.0f -> %zu bytes, ratio %.1f, %.4f bits/voxel (cabac %zu, zstd %zu payload bytes)\n",
                   raw_bytes, nbytes, ratio, bpv, wrep.bytes_cabac, wrep.bytes_zstd);
            printf("quantiser  step %.6g, %llu of %llu coefficients non-zero", wrep.step,
                   (unsigned long long)wrep.nonzero, (unsigned long long)wrep.coefficients);
            if (use_select) printf(" (%zu kept by the selection)", cc.report.kept);
            printf("\n");
            printf("predicted  RMSE %.6g, PSNR %.3f dB (dropped energy %.6g + quantisation %.6g)\n", p_rmse, p_psnr,
                   dropped, wrep.sse_quant);
            if (verify)
                printf("measured   RMSE %.6g, PSNR %.3f dB, max error %.6g (peak = range %.6g)\n", m_rmse, m_psnr,
                       maxerr, vmax - vmin);
            printf("time       transform %.3f s, select %.3f s, encode %.3f s (step %.3f, quantise %.3f, code %.3f): "
                   "%.1f MB/s",
                   t_dwt, t_sel, t_enc, wrep.seconds_step, wrep.seconds_quantise, wrep.seconds_code, mbs);
            if (verify) printf("; decode %.3f s + inverse %.3f s", t_dec, t_idwt);
            printf("\n");
        }
    }
    rc = CLI_OK;
done:
    free(buf);
    wvol_volume_destroy(rec);
    wvol_coeffs_destroy(dec);
    wvol_compressed_free(&cc);
    wvol_volume_destroy(v);
    return rc;
}
