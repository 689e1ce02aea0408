/* wvol render: an image of a volume or a .wvc store (DESIGN.md section 8, docs/render.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "wvol/image.h"
#include "wvol/io.h"
#include "wvol/render.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

const char wvol_cmd_render_summary[] = "render a volume or a .wvc store to an EXR or PNG image";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output image: .exr (float RGBA, linear) or .png (8-bit sRGB)"},
    {"camera", 0, 1, "camera: +z, -x, \"persp dir=1,1,0.5\", \"ortho eye=X,Y,Z center=X,Y,Z up=0,0,1\" ... (default +z)"},
    {"size", 0, 1, "image size WxH (default 512x512)"},
    {"tf", 0, 1, "transfer function: gaussian, grey, ct-bone, ct-soft, or a file (default gaussian)"},
    {"mode", 0, 1, "xray | absorption | absorption-linear (default absorption)"},
    {"method", 0, 1, "auto | reference | reference-fhat | spline | axis | splat | bricks (default auto)"},
    {"keep", 0, 1, "fraction of coefficients kept, e.g. 5% (default 100%: a .wvc's nonzero ones); with --method reference the dense reconstruction of those is rendered"},
    {"wavelet", 0, 1, "volume input, wavelet methods: family (default db2)"},
    {"levels", 0, 1, "volume input, wavelet methods: levels (default 3, or fewer when the volume is small)"},
    {"spline-j", 0, 1, "basis splines: 2^J knots per unit (default 4)"},
    {"step", 0, 1, "reference methods: step in voxels (default 0.5)"},
    {"brick", 0, 1, "bricks: brick side in voxels (default 32); reference: empty-space brick side (default 8)"},
    {"skip-tolerance", 0, 1, "reference, bricks: optical depth (X-ray: integral) each ray may skip in nearly empty bricks; bounds each pixel's change (default 0: skip only what adds nothing)"},
    {"gauss", 0, 1, "spline method: Gauss-Legendre nodes per piece for the exponential (default 5)"},
    {"shading", 0, 0, "diffuse headlight shading from the gradient"},
    {"colors", 0, 1, "colour volume replacing the TF colour: interleaved RGB float32 .raw, e.g. from 'wvol segment --colors'"},
    {"threads", 0, 1, "threads (default: all)"},
    {"repeat", 0, 1, "render N times (1..100), report the fastest call's times (benchmarks; default 1)"},
    {"exposure", 0, 1, "PNG: scale before sRGB encoding (default 1; X-ray: 1/max)"},
    {"dims", 0, 1, "raw input: NXxNYxNZ"},
    {"type", 0, 1, "raw input: sample type"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

/* Resident memory in MiB from /proc/self/status ("VmRSS" now, "VmHWM" peak), -1 if unknown. */
static double rss_mib(const char *key)
{
    char line[256];
    double v = -1;
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return -1;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, key, strlen(key)) && line[strlen(key)] == ':') {
            v = atof(line + strlen(key) + 1) / 1024.0; /* kB */
            break;
        }
    fclose(f);
    return v;
}

/* Resets the peak resident size to the current one (Linux >= 4.0); 0 when that worked. */
static int rss_reset_peak(void)
{
    FILE *f = fopen("/proc/self/clear_refs", "w");
    int ok;
    if (!f) return -1;
    ok = fputs("5", f) >= 0;
    return fclose(f) == 0 && ok ? 0 : -1;
}

int wvol_cmd_render(int argc, char **argv)
{
    const char *cmd = "render";
    cli_parser ps;
    const cli_opt *o;
    const char *val, *in = NULL, *out = NULL, *camspec = "+z", *tfname = "gaussian", *wname = "db2";
    const char *method = "auto", *colors_path = NULL;
    int r, json = 0, rc = CLI_FAILED;
    long W = 512, H = 512, levels = 0, spline_j = 4, threads = 0, gauss = 5, brick = -1, repeat = 1;
    double keep = 1.0, exposure = 0, step = 0.5;
    int keep_given = 0, exposure_given = 0, auto_fast = 0, is_wvc;
    wvol_render_params rp;
    wvol_load_options lo;
    wvol_error err;
    wvol_volume *v = NULL, *colors = NULL;
    wvol_coeffs *c = NULL;
    wvol_selection *sel = NULL;
    wvol_store *st = NULL;
    wvol_image *img = NULL;
    wvol_camera cam;
    wvol_tf tf;
    wvol_geometry g;
    wvol_render_stats stats;
    wvol_select_report rep;
    double vmin = 0, vmax = 1, t0, t_prep = 0, rss_before = -1, rss_peak = -1, recon_cpu = -1, cpu_max = 0, wall_min = 0;
    size_t store_bytes = 0;
    const wvol_filter *filt = NULL;

    wvol_render_params_default(&rp);
    memset(&tf, 0, sizeof tf);
    memset(&stats, 0, sizeof stats);
    wvol_load_options_default(&lo);
    memset(&rep, 0, sizeof rep);
    cli_parser_init(&ps, cmd, argc, argv, opts);
    while ((r = cli_next(&ps, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (in) return cli_usage(cmd, "one input expected, got '%s' too", val);
            in = val;
        } else if (o->short_name == 'h') {
            cli_print_help(cmd, "IN(.wvc|volume) -o OUT.exr|.png [--camera C] [--tf TF] [--mode M] [--method M] [--keep 5%]",
                           "Renders the low-albedo integral along rays: X-ray (integral of the value) or\n"
                           "emission-absorption with a transfer function. 'reference' composites trilinear\n"
                           "samples of the volume; 'bricks' does the same from a store, reconstructing bricks\n"
                           "on demand (never the whole volume); 'spline' integrates the kept wavelet basis\n"
                           "functions analytically (the exact model, slow); 'axis' is the X-ray fast path for\n"
                           "views along an axis, 'splat' for any orthographic view (footprint splatting, the\n"
                           "spline model to ~1e-3); 'reference-fhat' samples the wavelet model.\n"
                           "'auto' picks reference for a volume at 100%, else axis when it applies, else bricks.\n"
                           "See docs/render.md for cameras, transfer-function files and errors.",
                           opts);
            return CLI_OK;
        } else if (!strcmp(o->name, "json")) json = 1;
        else if (!strcmp(o->name, "output")) out = val;
        else if (!strcmp(o->name, "camera")) camspec = val;
        else if (!strcmp(o->name, "tf")) tfname = val;
        else if (!strcmp(o->name, "wavelet")) wname = val;
        else if (!strcmp(o->name, "method")) method = val;
        else if (!strcmp(o->name, "shading")) rp.shading = 1;
        else if (!strcmp(o->name, "colors")) colors_path = val;
        else if (!strcmp(o->name, "size")) {
            if (!cli_parse_size(cmd, "size", val, &W, &H)) return CLI_USAGE;
        } else if (!strcmp(o->name, "mode")) {
            if (!strcmp(val, "xray")) rp.mode = WVOL_MODE_XRAY;
            else if (!strcmp(val, "absorption")) rp.mode = WVOL_MODE_ABSORPTION;
            else if (!strcmp(val, "absorption-linear")) rp.mode = WVOL_MODE_ABSORPTION_LINEAR;
            else return cli_usage(cmd, "--mode '%s': expected xray, absorption or absorption-linear", val);
        } else if (!strcmp(o->name, "keep")) {
            if (!cli_parse_fraction(cmd, "keep", val, &keep)) return CLI_USAGE;
            keep_given = 1;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long(cmd, "levels", val, 1, 30, &levels)) return CLI_USAGE;
        } else if (!strcmp(o->name, "spline-j")) {
            if (!cli_parse_long(cmd, "spline-j", val, 1, 12, &spline_j)) return CLI_USAGE;
        } else if (!strcmp(o->name, "brick")) {
            if (!cli_parse_long(cmd, "brick", val, 2, 4096, &brick)) return CLI_USAGE;
        } else if (!strcmp(o->name, "gauss")) {
            if (!cli_parse_long(cmd, "gauss", val, 1, 10, &gauss)) return CLI_USAGE;
        } else if (!strcmp(o->name, "repeat")) {
            if (!cli_parse_long(cmd, "repeat", val, 1, 100, &repeat)) return CLI_USAGE;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_parse_long(cmd, "threads", val, 0, 4096, &threads)) return CLI_USAGE;
        } else if (!strcmp(o->name, "step")) {
            if (!cli_parse_double(cmd, "step", val, &step)) return CLI_USAGE;
            if (!(step > 0)) return cli_usage(cmd, "--step %g: must be > 0", step);
        } else if (!strcmp(o->name, "skip-tolerance")) {
            if (!cli_parse_double(cmd, "skip-tolerance", val, &rp.skip_tolerance)) return CLI_USAGE;
            if (!(rp.skip_tolerance >= 0)) return cli_usage(cmd, "--skip-tolerance %g: must be >= 0", rp.skip_tolerance);
        } else if (!strcmp(o->name, "exposure")) {
            if (!cli_parse_double(cmd, "exposure", val, &exposure)) return CLI_USAGE;
            if (!(exposure > 0)) return cli_usage(cmd, "--exposure %g: must be > 0", exposure);
            exposure_given = 1;
        } else if (!strcmp(o->name, "dims")) {
            if (!cli_parse_dims(cmd, "dims", val, lo.dims)) return CLI_USAGE;
        } else if (!strcmp(o->name, "type")) {
            int t = wvol_sample_type_parse(val);
            if (t < 0) return cli_usage(cmd, "--type '%s': unknown sample type", val);
            lo.raw_type = (wvol_sample_type)t;
        }
    }
    if (!in) return cli_usage(cmd, "missing input (see 'wvol render --help')");
    if (!out) return cli_usage(cmd, "missing output image (-o OUT.exr or OUT.png)");
    if (!wvol_path_has_ext(out, ".exr") && !wvol_path_has_ext(out, ".png"))
        return cli_usage(cmd, "output '%s': the extension must be .exr or .png", out);
    if (strcmp(method, "auto") && strcmp(method, "reference") && strcmp(method, "reference-fhat") &&
        strcmp(method, "spline") && strcmp(method, "axis") && strcmp(method, "splat") && strcmp(method, "bricks"))
        return cli_usage(cmd, "--method '%s': expected auto, reference, reference-fhat, spline, axis, splat or bricks",
                         method);
    is_wvc = wvol_path_has_ext(in, ".wvc");
    rp.step = step;
    if (brick > 0) rp.brick = (int)brick;
    rp.threads = (int)threads;
    rp.gauss_nodes = (int)gauss;
    if (colors_path && rp.mode == WVOL_MODE_XRAY) return cli_usage(cmd, "--colors needs an absorption mode (X-ray has no colour)");
    if (!strcmp(method, "auto")) {
        /* a .wvc is rendered from its store unless a reference was asked for; bricks read
         * a colour volume like the reference does */
        method = !is_wvc && (!keep_given || keep >= 1.0) ? "reference" : "bricks";
        auto_fast = !colors_path;
    }
    if (colors_path && strcmp(method, "reference") && strcmp(method, "reference-fhat") && strcmp(method, "bricks"))
        return cli_usage(cmd, "--colors needs --method reference, reference-fhat or bricks (got %s)", method);
    if (wvol_filter_get(&filt, wname, &err) != WVOL_OK) return cli_usage(cmd, "--wavelet: %s", err.message);

    t0 = cli_now();
    if (is_wvc) {
        /* the decoder gives dense coefficients (the file's own layout); they become a store
         * (or, for the reference, a volume) and are freed before rendering */
        wvol_wvc_info wi;
        if (wvol_wvc_read(&c, in, NULL, &wi, &err) != WVOL_OK) return cli_fail_err(cmd, &err);
        filt = c->filter;
        vmin = wi.value_min;
        vmax = wi.value_max;
        wvol_geometry_of_coeffs(&g, c);
    } else {
        if (wvol_volume_load(&v, in, &lo, &err) != WVOL_OK) return cli_fail_err(cmd, &err);
        wvol_volume_range(v, &vmin, &vmax, NULL);
        wvol_geometry_of_volume(&g, v);
    }
    if (colors_path) {
        /* RGB interleaved: read through the raw reader as a volume 3 nx wide, which checks the size. */
        wvol_load_options co;
        wvol_load_options_default(&co);
        co.dims[0] = 3 * g.dims[0], co.dims[1] = g.dims[1], co.dims[2] = g.dims[2];
        co.raw_type = WVOL_F32;
        if (!wvol_path_has_ext(colors_path, ".raw")) {
            rc = cli_usage(cmd, "--colors %s: expected interleaved RGB float32 .raw", colors_path);
            goto done;
        }
        if (wvol_volume_load(&colors, colors_path, &co, &err) != WVOL_OK) goto fail;
        rp.colors = colors->data;
        rp.colors_count = wvol_volume_count(colors);
    }
    if (wvol_camera_parse(&cam, camspec, &g, (int)W, (int)H, &err) != WVOL_OK) {
        rc = cli_usage(cmd, "--camera: %s", err.message);
        goto done;
    }
    if (rp.mode != WVOL_MODE_XRAY && (rc = cli_load_tf(cmd, tfname, vmin, vmax, &tf)) != CLI_OK) goto done;
    /* a store is built for the store methods, for a .wvc, and for the reference with --keep
     * below 100% (which renders the dense reconstruction of the kept coefficients) */
    if (strcmp(method, "reference") || is_wvc || keep < 1.0) {
        wvol_select_params sp;
        wvol_select_params_default(&sp);
        wvol_store_params stp;
        wvol_store_params_default(&stp);
        if (!is_wvc) {
            int maxl = wvol_dwt_max_levels(v->nx, v->ny, v->nz);
            int lev = levels ? (int)levels : (maxl < 3 ? maxl : 3);
            if (lev > maxl) {
                rc = cli_usage(cmd, "--levels %d: at most %d for %zux%zux%zu", lev, maxl, v->nx, v->ny, v->nz);
                goto done;
            }
            if (wvol_dwt3(&c, v, filt, lev, &err) != WVOL_OK) goto fail;
        }
        if (keep < 1.0) {
            sp.mode = WVOL_SELECT_FRACTION;
            sp.fraction = keep;
        }
        if (wvol_select(&sel, c, &sp, v, &rep, &err) != WVOL_OK) goto fail;
        if (is_wvc && keep >= 1.0) { /* the store of a file holds its nonzero coefficients only */
            wvol_selection_destroy(sel);
            sel = NULL;
        }
        stp.spline_J = (int)spline_j;
        if (!strcmp(method, "reference")) { /* the dense reconstruction of the kept part */
            clock_t c0 = clock();
            wvol_volume_destroy(v);
            v = NULL;
            if (sel && wvol_selection_apply(sel, c, &err) != WVOL_OK) goto fail;
            if (wvol_idwt3(&v, c, &err) != WVOL_OK) goto fail;
            recon_cpu = (double)(clock() - c0) / CLOCKS_PER_SEC; /* the reference's price of a store */
            wvol_coeffs_destroy(c);
            c = NULL;
        } else if (!strcmp(method, "reference-fhat")) {
            if (sel && wvol_selection_apply(sel, c, &err) != WVOL_OK) goto fail;
        } else {
            if (wvol_store_build(&st, c, sel, &stp, &err) != WVOL_OK) goto fail;
            wvol_coeffs_destroy(c);
            c = NULL;
            wvol_volume_destroy(v); /* the store path never holds the dense volume */
            v = NULL;
        }
    }
    if (!strcmp(method, "bricks") && brick <= 0) rp.brick = 0; /* the library chooses (32) */
    if (st) {
        wvol_store_info si;
        wvol_store_get_info(st, &si);
        store_bytes = si.bytes;
    }
    if (wvol_image_create(&img, (int)W, (int)H, &err) != WVOL_OK) goto fail;
    t_prep = cli_now() - t0;
    /* the render's own peak: the process's peak resident size from here on (the volume or
     * decoded coefficients that built the store are freed by now) */
    if (rss_reset_peak() == 0) rss_before = rss_mib("VmRSS");
    /* --repeat: the same call N times (each builds all it needs again), the fastest kept:
     * the benchmarks read the best of N beside the peers' best of N */
    for (long rep_i = 0; rep_i < repeat; rep_i++) {
        wvol_render_stats one;
        wvol_status s = WVOL_ERR_INTERNAL;
        memset(&one, 0, sizeof one);
        if (!strcmp(method, "reference")) s = wvol_render_reference(img, v, &cam, &tf, &rp, &one, &err);
        else if (!strcmp(method, "reference-fhat")) {
            wvol_basis *b = NULL;
            s = wvol_basis_create(&b, filt, (int)spline_j, &err);
            if (s == WVOL_OK) s = wvol_render_reference_fhat(img, c, b, &cam, &tf, &rp, &one, &err);
            wvol_basis_destroy(b);
        } else if (!strcmp(method, "axis")) s = wvol_render_xray_axis(img, st, &cam, &rp, &one, &err);
        else if (!strcmp(method, "splat")) s = wvol_render_xray_splat(img, st, &cam, &rp, &one, &err);
        else if (!strcmp(method, "spline")) s = wvol_render_spline(img, st, &cam, &tf, &rp, &one, &err);
        else {
            s = WVOL_ERR_UNSUPPORTED;
            if (auto_fast && rp.mode == WVOL_MODE_XRAY) {
                s = wvol_render_xray_axis(img, st, &cam, &rp, &one, &err);
                if (s == WVOL_OK) method = "axis";
            }
            if (s == WVOL_ERR_UNSUPPORTED) s = wvol_render_bricks(img, st, &cam, &tf, &rp, &one, &err);
        }
        if (s != WVOL_OK) goto fail;
        /* the resident peak of the first call: later calls allocate the same, but malloc's
         * reuse of what the earlier ones freed can raise the process's peak a little */
        if (rep_i == 0 && rss_before >= 0) rss_peak = rss_mib("VmHWM");
        if (rep_i == 0 || one.cpu_seconds > cpu_max) cpu_max = one.cpu_seconds;
        if (rep_i == 0 || one.seconds < wall_min) wall_min = one.seconds;
        if (rep_i == 0 || one.cpu_seconds < stats.cpu_seconds) stats = one;
    }
    stats.seconds = wall_min;
    {
        wvol_status s;
        if (wvol_path_has_ext(out, ".exr")) {
            s = wvol_image_write_exr(img, out, NULL, &err);
        } else {
            if (!exposure_given) {
                exposure = 1.0;
                if (rp.mode == WVOL_MODE_XRAY) {
                    size_t i, n = (size_t)W * (size_t)H;
                    double mx = 0;
                    for (i = 0; i < n; i++) mx = fmax(mx, img->rgba[4 * i]);
                    exposure = mx > 0 ? 1.0 / mx : 1.0;
                }
            }
            s = wvol_image_write_png(img, out, NULL, exposure, &err);
        }
        if (s != WVOL_OK) goto fail;
    }
    if (json) {
        cli_json_begin();
        cli_json_str("input", in);
        cli_json_str("output", out);
        cli_json_str("method", method);
        cli_json_str("mode", rp.mode == WVOL_MODE_XRAY ? "xray" : rp.mode == WVOL_MODE_ABSORPTION ? "absorption"
                                                                                                 : "absorption-linear");
        cli_json_int("width", W);
        cli_json_int("height", H);
        if (strcmp(method, "reference") || is_wvc || keep < 1.0) {
            cli_json_str("wavelet", filt->name);
            cli_json_num("keep", keep);
            cli_json_int("kept", (long long)rep.kept);
            cli_json_num("predicted_rmse", rep.predicted_rmse);
            cli_json_int("spline_j", spline_j);
        }
        cli_json_num("prepare_seconds", t_prep);
        if (recon_cpu >= 0) cli_json_num("reconstruct_cpu_seconds", recon_cpu);
        cli_json_num("render_seconds", stats.seconds);
        cli_json_num("render_cpu_seconds", stats.cpu_seconds);
        if (repeat > 1) {
            cli_json_int("repeat", repeat);
            cli_json_num("render_cpu_seconds_max", cpu_max);
        }
        cli_json_int("rays_hit", (long long)stats.rays_hit);
        cli_json_int("samples", (long long)stats.samples);
        cli_json_int("pieces", (long long)stats.pieces);
        cli_json_int("functions", (long long)stats.functions);
        cli_json_int("terminated", (long long)stats.terminated);
        cli_json_int("clamped", (long long)stats.clamped);
        if (rp.skip_tolerance > 0) {
            cli_json_num("skip_tolerance", rp.skip_tolerance);
            cli_json_int("skipped_tolerance", (long long)stats.skipped_tolerance);
            cli_json_num("skip_bound", stats.skip_bound);
        }
        if (!strcmp(method, "bricks")) {
            cli_json_int("brick", stats.brick);
            cli_json_num("step", rp.step);
            cli_json_int("bricks_built", (long long)stats.bricks_built);
            cli_json_int("bricks_bound_skipped", (long long)stats.bricks_bound_skipped);
            cli_json_int("render_bytes", (long long)stats.bytes);
        }
        if (st) cli_json_int("store_bytes", (long long)store_bytes);
        cli_json_num("rss_before_render_mib", rss_before);
        cli_json_num("rss_peak_render_mib", rss_peak);
        cli_json_end();
    } else {
        printf("wrote %s (%ldx%ld, %s, %s) in %.3f s render + %.3f s preparation\n", out, W, H, method,
               rp.mode == WVOL_MODE_XRAY ? "xray" : rp.mode == WVOL_MODE_ABSORPTION ? "absorption" : "absorption-linear",
               stats.seconds, t_prep);
        if (rp.skip_tolerance > 0)
            printf("skipped %zu nearly empty brick runs: each pixel within %.3g of the unskipped image (tolerance %g)\n",
                   stats.skipped_tolerance, stats.skip_bound, rp.skip_tolerance);
    }
    rc = CLI_OK;
    goto done;
fail:
    rc = cli_fail_err(cmd, &err);
done:
    wvol_image_destroy(img);
    wvol_store_destroy(st);
    wvol_selection_destroy(sel);
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
    wvol_volume_destroy(colors);
    return rc;
}
