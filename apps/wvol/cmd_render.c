/* SPDX-License-Identifier: MIT */
/* wvol render: an image of a volume or a .wvc store (DESIGN.md section 8, docs/render.md).
 * The steps: parse the options, load the input (a dense volume, or a store built by the
 * library's compression pipeline), camera and transfer function, wvol_render (--repeat
 * times), write the image, report. Method choice and defaults are the library's. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "wvol/compress.h"
#include "wvol/image.h"
#include "wvol/io.h"
#include "wvol/render.h"
#include "wvol/store.h"
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
    CLI_MEMORY_OPT,
    CLI_LOAD_OPTS,
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

static const char about[] =
    "Renders the low-albedo integral along rays: X-ray (integral of the value) or\n"
    "emission-absorption with a transfer function. 'reference' composites trilinear\n"
    "samples of the volume; 'bricks' does the same from a store, reconstructing bricks\n"
    "on demand (never the whole volume); 'spline' integrates the kept wavelet basis\n"
    "functions analytically (the exact model, slow); 'axis' is the X-ray fast path for\n"
    "views along an axis, 'splat' for any orthographic view (footprint splatting, the\n"
    "spline model to ~1e-3); 'reference-fhat' samples the wavelet model.\n"
    "'auto' picks reference for a volume at 100%, else axis when it applies, else bricks.\n"
    "See docs/render.md for cameras, transfer-function files and errors.";

typedef struct render_args {
    const char *in, *out, *camspec, *tfname, *colors_path;
    long width, height, repeat;
    double keep, exposure;
    int json, keep_given, exposure_given;
    wvol_render_params rp;
    wvol_compress_params cp;
    wvol_load_options lo;
    size_t memory;              /* .wvc input: budget of the file-backed store (0: default) */
} render_args;

/* What the render reads, and what made it. */
typedef struct render_input {
    int is_wvc;
    wvol_volume *volume;        /* dense source (reference at 100%), else NULL */
    wvol_compressed store;      /* store source: the pipeline's result */
    wvol_volume *colors;
    wvol_geometry geometry;
    double vmin, vmax;
} render_input;

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

static int parse_args(render_args *a, int argc, char **argv)
{
    const char *cmd = "render";
    cli_parser ps;
    const cli_opt *o;
    const char *val;
    long v;
    int r;
    wvol_error err;
    memset(a, 0, sizeof *a);
    a->camspec = "+z";
    a->tfname = "gaussian";
    a->width = a->height = 512;
    a->repeat = 1;
    a->keep = 1.0;
    wvol_render_params_default(&a->rp);
    wvol_compress_params_default(&a->cp);
    wvol_load_options_default(&a->lo);
    cli_parser_init(&ps, cmd, argc, argv, opts);
    while ((r = cli_next(&ps, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (a->in) return cli_usage(cmd, "one input expected, got '%s' too", val);
            a->in = val;
        } else if (o->short_name == 'h') {
            cli_print_help(cmd, "IN(.wvc|volume) -o OUT.exr|.png [--camera C] [--tf TF] [--mode M] [--method M] [--keep 5%]",
                           about, opts);
            return -1;
        } else if (!strcmp(o->name, "json")) a->json = 1;
        else if (!strcmp(o->name, "output")) a->out = val;
        else if (!strcmp(o->name, "camera")) a->camspec = val;
        else if (!strcmp(o->name, "tf")) a->tfname = val;
        else if (!strcmp(o->name, "wavelet")) a->cp.wavelet = val;
        else if (!strcmp(o->name, "shading")) a->rp.shading = 1;
        else if (!strcmp(o->name, "colors")) a->colors_path = val;
        else if (!strcmp(o->name, "size")) {
            if (!cli_parse_size(cmd, "size", val, &a->width, &a->height)) return CLI_USAGE;
        } else if (!strcmp(o->name, "method")) {
            if (wvol_render_method_parse(&a->rp.method, val, &err) != WVOL_OK)
                return cli_usage(cmd, "--%s", err.message);
        } else if (!strcmp(o->name, "mode")) {
            if (wvol_render_mode_parse(&a->rp.mode, val, &err) != WVOL_OK) return cli_usage(cmd, "--%s", err.message);
        } else if (!strcmp(o->name, "memory")) {
            if (!cli_parse_bytes(cmd, "memory", val, &a->memory)) return CLI_USAGE;
        } else if (!strcmp(o->name, "keep")) {
            if (!cli_parse_fraction(cmd, "keep", val, &a->keep)) return CLI_USAGE;
            a->keep_given = 1;
        } else if (!strcmp(o->name, "levels")) {
            if (!cli_parse_long(cmd, "levels", val, 1, 30, &v)) return CLI_USAGE;
            a->cp.levels = (int)v;
        } else if (!strcmp(o->name, "spline-j")) {
            if (!cli_parse_long(cmd, "spline-j", val, 1, 12, &v)) return CLI_USAGE;
            a->cp.store.spline_J = (int)v;
        } else if (!strcmp(o->name, "brick")) {
            if (!cli_parse_long(cmd, "brick", val, 2, 4096, &v)) return CLI_USAGE;
            a->rp.reference.brick = a->rp.bricks.brick = (int)v;
        } else if (!strcmp(o->name, "gauss")) {
            if (!cli_parse_long(cmd, "gauss", val, 1, 10, &v)) return CLI_USAGE;
            a->rp.spline.gauss_nodes = (int)v;
        } else if (!strcmp(o->name, "repeat")) {
            if (!cli_parse_long(cmd, "repeat", val, 1, 100, &a->repeat)) return CLI_USAGE;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_parse_long(cmd, "threads", val, 0, 4096, &v)) return CLI_USAGE;
            a->rp.threads = (int)v;
        } else if (!strcmp(o->name, "step")) {
            if (!cli_parse_double(cmd, "step", val, &a->rp.step)) return CLI_USAGE;
            if (!(a->rp.step > 0)) return cli_usage(cmd, "--step %g: must be > 0", a->rp.step);
        } else if (!strcmp(o->name, "skip-tolerance")) {
            if (!cli_parse_double(cmd, "skip-tolerance", val, &a->rp.skip_tolerance)) return CLI_USAGE;
            if (!(a->rp.skip_tolerance >= 0))
                return cli_usage(cmd, "--skip-tolerance %g: must be >= 0", a->rp.skip_tolerance);
        } else if (!strcmp(o->name, "exposure")) {
            if (!cli_parse_double(cmd, "exposure", val, &a->exposure)) return CLI_USAGE;
            if (!(a->exposure > 0)) return cli_usage(cmd, "--exposure %g: must be > 0", a->exposure);
            a->exposure_given = 1;
        } else if ((r = cli_load_option(cmd, o, val, &a->lo)) != -1) {
            if (r != CLI_OK) return r;
        }
    }
    if (!a->in) return cli_usage(cmd, "missing input (see 'wvol render --help')");
    if (!a->out) return cli_usage(cmd, "missing output image (-o OUT.exr or OUT.png)");
    if (!wvol_path_has_ext(a->out, ".exr") && !wvol_path_has_ext(a->out, ".png"))
        return cli_usage(cmd, "output '%s': the extension must be .exr or .png", a->out);
    if (a->colors_path && a->rp.mode == WVOL_RENDER_MODE_XRAY)
        return cli_usage(cmd, "--colors needs an absorption mode (X-ray has no colour)");
    if (a->colors_path && a->rp.method != WVOL_RENDER_METHOD_AUTO && a->rp.method != WVOL_RENDER_METHOD_REFERENCE &&
        a->rp.method != WVOL_RENDER_METHOD_REFERENCE_FHAT && a->rp.method != WVOL_RENDER_METHOD_BRICKS)
        return cli_usage(cmd, "--colors needs --method reference, reference-fhat or bricks (got %s)",
                         wvol_render_method_name(a->rp.method));
    if (a->keep < 1.0) {
        a->cp.select.mode = WVOL_SELECT_FRACTION;
        a->cp.select.fraction = a->keep;
    }
    {
        const wvol_filter *f;
        if (wvol_filter_get(&f, a->cp.wavelet, &err) != WVOL_OK) return cli_usage(cmd, "--wavelet: %s", err.message);
    }
    return CLI_OK;
}

/* The input as a dense volume (reference at 100%) or as a store, freeing what built it. */
static int load_input(const render_args *a, render_input *in, wvol_error *err)
{
    int dense;
    in->is_wvc = wvol_path_has_ext(a->in, ".wvc");
    dense = !in->is_wvc && a->keep >= 1.0 &&
            (a->rp.method == WVOL_RENDER_METHOD_AUTO || a->rp.method == WVOL_RENDER_METHOD_REFERENCE);
    if (in->is_wvc && a->keep >= 1.0 &&
        (a->rp.method == WVOL_RENDER_METHOD_BRICKS ||
         (a->rp.method == WVOL_RENDER_METHOD_AUTO && a->rp.mode != WVOL_RENDER_MODE_XRAY))) {
        /* the bricked renderer reads the file chunk by chunk within --memory (main() makes AUTO
         * bricks for it; an X-ray's AUTO may pick a fast path that needs the octree: built below) */
        const wvol_wvc_info *wi;
        if (cli_open_wvc_store("render", a->in, a->memory, &in->store) != CLI_OK) return CLI_FAILED;
        wi = wvol_store_file_info(in->store.store);
        in->vmin = wi->value_min;
        in->vmax = wi->value_max;
        in->geometry.dims[0] = wi->nx, in->geometry.dims[1] = wi->ny, in->geometry.dims[2] = wi->nz;
        memcpy(in->geometry.spacing, wi->spacing, sizeof wi->spacing);
        memcpy(in->geometry.origin, wi->origin, sizeof wi->origin);
        return CLI_OK;
    }
    if (in->is_wvc) {
        wvol_wvc_info wi;
        wvol_coeffs *c = NULL;
        if (wvol_wvc_read(&c, a->in, NULL, &wi, err) != WVOL_OK) return cli_fail_err("render", err);
        in->vmin = wi.value_min;
        in->vmax = wi.value_max;
        wvol_geometry_of_coeffs(&in->geometry, c);
        if (wvol_compress_coeffs(&in->store, &c, &a->cp, err) != WVOL_OK) return cli_fail_err("render", err);
        return CLI_OK;
    }
    if (wvol_volume_load(&in->volume, a->in, &a->lo, err) != WVOL_OK) return cli_fail_err("render", err);
    wvol_volume_range(in->volume, &in->vmin, &in->vmax, NULL);
    wvol_geometry_of_volume(&in->geometry, in->volume);
    if (dense) return CLI_OK;
    if (wvol_compress(&in->store, in->volume, &a->cp, err) != WVOL_OK) return cli_fail_err("render", err);
    wvol_coeffs_destroy(in->store.coeffs); /* the store path never holds the dense data */
    in->store.coeffs = NULL;
    wvol_volume_destroy(in->volume);
    in->volume = NULL;
    return CLI_OK;
}

/* --colors: interleaved RGB float32, read through the raw reader as a volume 3 nx wide
 * (which checks the size). */
static int load_colors(const render_args *a, render_input *in, wvol_render_params *rp, wvol_error *err)
{
    wvol_load_options co;
    if (!a->colors_path) return CLI_OK;
    if (!wvol_path_has_ext(a->colors_path, ".raw"))
        return cli_usage("render", "--colors %s: expected interleaved RGB float32 .raw", a->colors_path);
    wvol_load_options_default(&co);
    co.dims[0] = 3 * in->geometry.dims[0], co.dims[1] = in->geometry.dims[1], co.dims[2] = in->geometry.dims[2];
    co.raw_type = WVOL_SAMPLE_TYPE_F32;
    if (wvol_volume_load(&in->colors, a->colors_path, &co, err) != WVOL_OK) return cli_fail_err("render", err);
    rp->colors = in->colors->data;
    rp->colors_count = wvol_volume_count(in->colors);
    return CLI_OK;
}

/* --repeat: the same call N times (each builds all it needs again), the fastest kept: the
 * benchmarks read the best of N beside the peers' best of N. The resident peak is the first
 * call's: later calls allocate the same, but malloc's reuse of what earlier ones freed can
 * raise the process's peak a little. */
static wvol_status render_repeat(wvol_image *img, const wvol_render_source *src, const wvol_camera *cam,
                                 const wvol_tf *tf, const render_args *a, const wvol_render_params *rp,
                                 wvol_render_stats *best, double *cpu_max, double rss[2], wvol_error *err)
{
    double wall_min = 0;
    rss[0] = rss[1] = -1;
    if (rss_reset_peak() == 0) rss[0] = rss_mib("VmRSS");
    for (long i = 0; i < a->repeat; i++) {
        wvol_render_stats one;
        memset(&one, 0, sizeof one);
        wvol_status s = wvol_render(img, src, cam, tf, rp, &one, err);
        if (s != WVOL_OK) return s;
        if (i == 0 && rss[0] >= 0) rss[1] = rss_mib("VmHWM");
        if (i == 0 || one.cpu_seconds > *cpu_max) *cpu_max = one.cpu_seconds;
        if (i == 0 || one.seconds < wall_min) wall_min = one.seconds;
        if (i == 0 || one.cpu_seconds < best->cpu_seconds) *best = one;
    }
    best->seconds = wall_min;
    return WVOL_OK;
}

static wvol_status write_image(const wvol_image *img, const render_args *a, wvol_error *err)
{
    double exposure = a->exposure;
    if (wvol_path_has_ext(a->out, ".exr")) return wvol_image_write_exr(img, a->out, NULL, err);
    if (!a->exposure_given) {
        exposure = 1.0;
        if (a->rp.mode == WVOL_RENDER_MODE_XRAY) {
            size_t i, n = (size_t)img->width * (size_t)img->height;
            double mx = 0;
            for (i = 0; i < n; i++) mx = fmax(mx, img->rgba[4 * i]);
            exposure = mx > 0 ? 1.0 / mx : 1.0;
        }
    }
    return wvol_image_write_png(img, a->out, NULL, exposure, err);
}

static void report(const render_args *a, const render_input *in, const wvol_render_stats *st, double t_prep,
                   double cpu_max, const double rss[2])
{
    const char *method = wvol_render_method_name(st->method), *mode = wvol_render_mode_name(a->rp.mode);
    const wvol_store *store = in->store.store;
    wvol_store_info si;
    if (store) wvol_store_get_info(store, &si);
    if (!a->json) {
        printf("wrote %s (%ldx%ld, %s, %s) in %.3f s render + %.3f s preparation\n", a->out, a->width, a->height,
               method, mode, st->seconds, t_prep);
        if (a->rp.skip_tolerance > 0)
            printf("skipped %zu nearly empty brick runs: each pixel within %.3g of the unskipped image (tolerance %g)\n",
                   st->skipped_tolerance, st->skip_bound, a->rp.skip_tolerance);
        return;
    }
    cli_json_begin();
    cli_json_str("input", a->in);
    cli_json_str("output", a->out);
    cli_json_str("method", method);
    cli_json_str("mode", mode);
    cli_json_int("width", a->width);
    cli_json_int("height", a->height);
    if (store) {
        cli_json_str("wavelet", si.filter->name);
        cli_json_num("keep", a->keep);
        cli_json_int("kept", (long long)in->store.report.kept);
        cli_json_num("predicted_rmse", in->store.report.predicted_rmse);
        cli_json_int("spline_j", a->cp.store.spline_J);
    }
    cli_json_num("prepare_seconds", t_prep);
    if (st->method == WVOL_RENDER_METHOD_REFERENCE && store)
        cli_json_num("reconstruct_cpu_seconds", st->reconstruct_cpu_seconds);
    cli_json_num("render_seconds", st->seconds);
    cli_json_num("render_cpu_seconds", st->cpu_seconds - st->reconstruct_cpu_seconds);
    if (a->repeat > 1) {
        cli_json_int("repeat", a->repeat);
        cli_json_num("render_cpu_seconds_max", cpu_max);
    }
    cli_json_int("rays_hit", (long long)st->rays_hit);
    cli_json_int("samples", (long long)st->samples);
    cli_json_int("pieces", (long long)st->pieces);
    cli_json_int("functions", (long long)st->functions);
    cli_json_int("terminated", (long long)st->terminated);
    cli_json_int("clamped", (long long)st->clamped);
    if (a->rp.skip_tolerance > 0) {
        cli_json_num("skip_tolerance", a->rp.skip_tolerance);
        cli_json_int("skipped_tolerance", (long long)st->skipped_tolerance);
        cli_json_num("skip_bound", st->skip_bound);
    }
    if (st->method == WVOL_RENDER_METHOD_BRICKS) {
        cli_json_int("brick", st->brick);
        cli_json_num("step", a->rp.step);
        cli_json_int("bricks_built", (long long)st->bricks_built);
        cli_json_int("bricks_bound_skipped", (long long)st->bricks_bound_skipped);
        cli_json_int("render_bytes", (long long)st->bytes);
    }
    if (store) cli_json_int("store_bytes", (long long)si.bytes);
    cli_json_num("rss_before_render_mib", rss[0]);
    cli_json_num("rss_peak_render_mib", rss[1]);
    cli_json_end();
}

int wvol_cmd_render(int argc, char **argv)
{
    render_args a;
    render_input in;
    wvol_render_source src;
    wvol_render_stats stats;
    wvol_image *img = NULL;
    wvol_camera cam;
    wvol_tf tf;
    wvol_error err;
    double t0, t_prep, cpu_max = 0, rss[2] = {-1, -1};
    int rc = parse_args(&a, argc, argv);
    if (rc != CLI_OK) return rc < 0 ? CLI_OK : rc;
    memset(&in, 0, sizeof in);
    memset(&tf, 0, sizeof tf);
    memset(&stats, 0, sizeof stats);
    wvol_error_clear(&err);

    t0 = cli_now();
    if ((rc = load_input(&a, &in, &err)) != CLI_OK) goto done;
    if ((rc = load_colors(&a, &in, &a.rp, &err)) != CLI_OK) goto done;
    if (wvol_camera_parse(&cam, a.camspec, &in.geometry, (int)a.width, (int)a.height, &err) != WVOL_OK) {
        rc = cli_usage("render", "--camera: %s", err.message);
        goto done;
    }
    if (a.rp.mode != WVOL_RENDER_MODE_XRAY && (rc = cli_load_tf("render", a.tfname, in.vmin, in.vmax, &tf)) != CLI_OK)
        goto done;
    src = in.volume ? wvol_render_source_volume(in.volume) : wvol_render_source_store(in.store.store);
    if (wvol_store_is_file(in.store.store)) a.rp.method = WVOL_RENDER_METHOD_BRICKS;
    if (wvol_image_create(&img, (int)a.width, (int)a.height, &err) != WVOL_OK) goto fail;
    t_prep = cli_now() - t0;
    if (render_repeat(img, &src, &cam, &tf, &a, &a.rp, &stats, &cpu_max, rss, &err) != WVOL_OK) goto fail;
    if (write_image(img, &a, &err) != WVOL_OK) goto fail;
    if ((rc = cli_check_wvc_store("render", &in.store, 0)) != CLI_OK) goto done;
    report(&a, &in, &stats, t_prep, cpu_max, rss);
    rc = CLI_OK;
    goto done;
fail:
    rc = cli_fail_err("render", &err);
done:
    wvol_image_destroy(img);
    wvol_compressed_free(&in.store);
    wvol_volume_destroy(in.volume);
    wvol_volume_destroy(in.colors);
    return rc;
}
