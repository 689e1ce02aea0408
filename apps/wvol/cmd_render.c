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
#include "output_set.h"
#include "wvol/compress.h"
#include "wvol/image.h"
#include "wvol/io.h"
#include "wvol/lod.h"
#include "wvol/progressive.h"
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
    {"termination", 0, 1, "sampling methods: end a ray once its transmittance is below this (default 1e-6; VTK's fixed-point mapper: 0xff/0x7fff = 7.8e-3)"},
    {"skip-tolerance", 0, 1, "reference, bricks: optical depth (X-ray: integral) each ray may skip in nearly empty bricks; bounds each pixel's change (default 0: skip only what adds nothing)"},
    {"gauss", 0, 1, "spline method: Gauss-Legendre nodes per piece for the exponential (default 5)"},
    {"shading", 0, 0, "diffuse headlight shading from the gradient"},
    {"gradient-levels", 0, 1, "bricks with --shading: gradient of the low-pass model, the L finest levels' details dropped (default 0: the samples' own)"},
    {"preintegrate", 0, 0, "absorption, sampling methods: pre-integrated TF (value linear between samples, exact per segment)"},
    {"colors", 0, 1, "colour volume replacing the TF colour: interleaved RGB float32 .raw, e.g. from 'wvol segment --colors'"},
    CLI_THREADS_OPT,
    {"repeat", 0, 1, "render N frames (1..100) through one render context (its set-up kept), report the first frame's and the later frames' fastest times (benchmarks; default 1)"},
    {"orbit", 0, 1, "with --repeat N: frame i's camera turned by (N-1-i) x DEG degrees about the view's up axis through its centre, so every frame differs and the last, the one written, is --camera's (default 0)"},
    {"context-cache", 0, 1, "with --repeat: the render context's brick cache budget, bytes (K/M/G suffixes; default the dense volume's float32 size, at least 8 MiB)"},
    {"one-shot", 0, 0, "with --repeat: each frame a separate wvol_render call that builds everything again (no context)"},
    {"exposure", 0, 1, "PNG: scale before sRGB encoding (default 1; X-ray: 1/max)"},
    {"bound-method", 0, 1, "exact (default: the exact X-ray paths on the dropped coefficients; axis views in milliseconds, others ray by ray) | coarse (each band's largest dropped coefficient; O(1) a pixel, looser)"},
    {"progressive", 0, 0, "progressive passes from a volume: the low-pass cube, then --growth times more of the largest coefficients each pass, each written as OUT's name + .passN, the last also as OUT"},
    {"max-error", 0, 1, "progressive: stop at the first pass whose bound is <= this (pixel units of the image)"},
    {"budget", 0, 1, "progressive: wall-clock seconds; stop before a pass that would end beyond them"},
    {"growth", 0, 1, "progressive: kept coefficients multiplied by this per pass (default 4)"},
    {"full-resolution", 0, 0, "render the volume's own grid even when the image's pixels are much larger than its voxels (default: the wavelet level whose voxel matches the pixel footprint; docs/render.md, \"Level of detail\")"},
    {"bound", 0, 1, "also write a per-pixel bound on |image of all coefficients - this image| to this .exr (docs/render.md, \"Error bounds\"); xray or absorption, no shading"},
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
    "Level of detail: when the image's pixels are larger than the volume's voxels, the\n"
    "sampling methods render the wavelet level whose voxel matches the pixel footprint\n"
    "(orthographic: the pixel; perspective: at the volume's point nearest the eye),\n"
    "reporting the extra error (the dropped levels' energy as RMSE and PSNR); a .wvc\n"
    "decodes only the levels kept. --full-resolution turns it off.\n"
    "See docs/render.md for cameras, transfer-function files and errors.";

/* The options only some methods read (bit m: wvol_render_method m). AUTO picks reference,
 * bricks or axis, never spline or splat, so it takes what those three read. */
#define M_(m) (1u << WVOL_RENDER_METHOD_##m)
#define M_SAMPLING (M_(AUTO) | M_(REFERENCE) | M_(REFERENCE_FHAT) | M_(BRICKS))
static const cli_method_rule method_rules[] = {
    {"gauss", M_(SPLINE), "spline"},
    {"step", M_SAMPLING, "auto, reference, reference-fhat or bricks"},
    {"termination", M_SAMPLING | M_(SPLINE), "auto, reference, reference-fhat, bricks or spline"},
    {"brick", M_(AUTO) | M_(REFERENCE) | M_(BRICKS), "auto, reference or bricks"},
    {"skip-tolerance", M_(AUTO) | M_(REFERENCE) | M_(BRICKS), "auto, reference or bricks"},
    {"preintegrate", M_SAMPLING, "auto, reference, reference-fhat or bricks"},
    {"gradient-levels", M_(AUTO) | M_(BRICKS), "auto or bricks"},
    {NULL, 0, NULL}};
#undef M_SAMPLING
#undef M_

typedef struct render_args {
    const char *in, *out, *camspec, *tfname, *colors_path, *bound_path;
    long width, height, repeat;
    double keep, exposure, orbit;
    int json, keep_given, exposure_given, progressive, full_resolution, one_shot;
    wvol_bound_method bound_method;
    wvol_progressive_params pp;
    wvol_render_params rp;
    wvol_compress_params cp;
    wvol_load_options lo;
    size_t memory;              /* .wvc input: budget of the file-backed store (0: default) */
    size_t context_cache;       /* --context-cache (0: the library's default) */
} render_args;

/* What the render reads, and what made it. */
typedef struct render_input {
    int is_wvc;
    wvol_volume *volume;        /* dense source (reference at 100%), else NULL */
    wvol_compressed store;      /* store source: the pipeline's result */
    wvol_volume *colors;
    wvol_geometry geometry;
    double vmin, vmax;
    double coeff_error;         /* a .wvc's largest quantiser error per coefficient */
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
    wvol_progressive_params_default(&a->pp);
    a->bound_method = WVOL_BOUND_EXACT;
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
        else if (!strcmp(o->name, "preintegrate")) a->rp.preintegrate = 1;
        else if (!strcmp(o->name, "colors")) a->colors_path = val;
        else if (!strcmp(o->name, "bound")) a->bound_path = val;
        else if (!strcmp(o->name, "progressive")) a->progressive = 1;
        else if (!strcmp(o->name, "full-resolution")) a->full_resolution = 1;
        else if (!strcmp(o->name, "bound-method")) {
            if (!strcmp(val, "exact")) a->bound_method = WVOL_BOUND_EXACT;
            else if (!strcmp(val, "coarse")) a->bound_method = WVOL_BOUND_COARSE;
            else return cli_usage(cmd, "--bound-method '%s': exact or coarse", val);
        }
        else if (!strcmp(o->name, "max-error")) {
            if (!cli_parse_double(cmd, "max-error", val, &a->pp.max_error)) return CLI_USAGE;
            if (!(a->pp.max_error > 0)) return cli_usage(cmd, "--max-error %g: must be > 0", a->pp.max_error);
        } else if (!strcmp(o->name, "budget")) {
            if (!cli_parse_double(cmd, "budget", val, &a->pp.seconds)) return CLI_USAGE;
            if (!(a->pp.seconds > 0)) return cli_usage(cmd, "--budget %g: must be > 0 seconds", a->pp.seconds);
        } else if (!strcmp(o->name, "growth")) {
            if (!cli_parse_double(cmd, "growth", val, &a->pp.growth)) return CLI_USAGE;
            if (!(a->pp.growth > 1) || !isfinite(a->pp.growth))
                return cli_usage(cmd, "--growth %g: must be > 1", a->pp.growth);
        }
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
        } else if (!strcmp(o->name, "orbit")) {
            if (!cli_parse_double(cmd, "orbit", val, &a->orbit)) return CLI_USAGE;
            if (!(fabs(a->orbit) <= 360)) return cli_usage(cmd, "--orbit %g: expected degrees in -360..360", a->orbit);
        } else if (!strcmp(o->name, "context-cache")) {
            if (!cli_parse_bytes(cmd, "context-cache", val, &a->context_cache)) return CLI_USAGE;
        } else if (!strcmp(o->name, "one-shot")) {
            a->one_shot = 1;
        } else if (!strcmp(o->name, "threads")) {
            if (!cli_threads(cmd, val, &a->rp.threads)) return CLI_USAGE;
        } else if (!strcmp(o->name, "step")) {
            if (!cli_parse_double(cmd, "step", val, &a->rp.step)) return CLI_USAGE;
            if (!(a->rp.step > 0)) return cli_usage(cmd, "--step %g: must be > 0", a->rp.step);
        } else if (!strcmp(o->name, "gradient-levels")) {
            if (!cli_parse_long(cmd, "gradient-levels", val, 0, 32, &v)) return CLI_USAGE;
            a->rp.gradient_levels = (int)v;
        } else if (!strcmp(o->name, "termination")) {
            if (!cli_parse_double(cmd, "termination", val, &a->rp.termination)) return CLI_USAGE;
            if (!(a->rp.termination >= 0 && a->rp.termination < 1))
                return cli_usage(cmd, "--termination %g: must be in [0, 1)", a->rp.termination);
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
    if ((r = cli_method_rules(&ps, method_rules, (int)a->rp.method, wvol_render_method_name(a->rp.method))) != CLI_OK)
        return r;
    if ((a->rp.method == WVOL_RENDER_METHOD_AXIS || a->rp.method == WVOL_RENDER_METHOD_SPLAT) &&
        a->rp.mode != WVOL_RENDER_MODE_XRAY)
        return cli_usage(cmd, "--method %s renders X-ray images only: add --mode xray",
                         wvol_render_method_name(a->rp.method));
    if (cli_given(&ps, "gradient-levels") && !a->rp.shading)
        return cli_usage(cmd, "--gradient-levels sets the gradient --shading takes: add --shading");
    if ((cli_given(&ps, "orbit") || cli_given(&ps, "one-shot") || cli_given(&ps, "context-cache")) &&
        !cli_given(&ps, "repeat"))
        return cli_usage(cmd, "--orbit, --one-shot and --context-cache shape the frames of --repeat: add --repeat");
    if (cli_given(&ps, "growth") && !a->progressive)
        return cli_usage(cmd, "--growth sets how progressive passes grow: add --progressive");
    if (cli_given(&ps, "bound-method") && !a->bound_path && !(a->progressive && a->pp.max_error > 0))
        return cli_usage(cmd, "--bound-method chooses how a bound is computed: add --bound (or --progressive --max-error)");
    if ((a->pp.max_error > 0 || a->pp.seconds > 0) && !a->progressive)
        return cli_usage(cmd, "--max-error and --budget stop progressive passes: add --progressive");
    if (a->progressive) {
        if (wvol_path_has_ext(a->in, ".wvc"))
            return cli_usage(cmd, "--progressive starts from a volume (it ranks all the coefficients); %s is a .wvc",
                             a->in);
        if (a->keep_given) return cli_usage(cmd, "--progressive chooses the kept coefficients itself: drop --keep");
        if (a->colors_path) return cli_usage(cmd, "--progressive does not take --colors");
        a->pp.bound = a->bound_path != NULL || a->pp.max_error > 0 ? a->bound_method : WVOL_BOUND_NONE;
        if (a->pp.bound && (a->rp.mode == WVOL_RENDER_MODE_ABSORPTION_LINEAR || a->rp.shading))
            return cli_usage(cmd, "--progressive with a bound (--bound, --max-error) needs --mode xray or absorption, "
                                  "no --shading");
    }
    if (cli_load_options_fit(cmd, a->in, NULL) != CLI_OK) return CLI_USAGE;
    if (a->bound_path) {
        if (!wvol_path_has_ext(a->bound_path, ".exr"))
            return cli_usage(cmd, "--bound %s: the bound image is float data, the extension must be .exr", a->bound_path);
        if (a->rp.mode == WVOL_RENDER_MODE_ABSORPTION_LINEAR)
            return cli_usage(cmd, "--bound needs --mode xray or absorption (absorption-linear has no bound)");
        if (a->rp.shading) return cli_usage(cmd, "--bound does not cover --shading: render the bound without it");
        if (a->colors_path) return cli_usage(cmd, "--bound does not cover --colors");
        {
            const char *outs[2] = {a->out, a->bound_path}, *same = cli_same_output(outs, 2);
            if (same) return cli_usage(cmd, "--bound and -o would write the same file (%s)", same);
        }
        a->cp.build_residual = 1;
    }
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
    if (in->is_wvc && a->keep >= 1.0 && !a->bound_path &&
        (a->rp.method == WVOL_RENDER_METHOD_BRICKS ||
         (a->rp.method == WVOL_RENDER_METHOD_AUTO && a->rp.mode != WVOL_RENDER_MODE_XRAY))) {
        /* the bricked renderer reads the file chunk by chunk within --memory (main() makes AUTO
         * bricks for it; an X-ray's AUTO may pick a fast path that needs the octree, and --bound
         * needs every coefficient for its residual: built below) */
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
        if (a->bound_path && wi.dropped_energy > 0) {
            wvol_coeffs_destroy(c);
            /* the file's content, not the options, rules the bound out: bad input (docs/cli.md) */
            return cli_fail("render",
                            "--bound: %s dropped coefficients before coding (energy %g); their values are not in "
                            "the file, so no per-pixel bound. Compress with --keep 100%% to have one",
                            a->in, wi.dropped_energy);
        }
        in->coeff_error = wvol_wvc_max_coeff_error(&wi);
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

/* cam turned by deg degrees about its true up axis through its centre (--orbit): the eye
 * moves on the circle around the look-at point, the up vector stays. */
static wvol_camera orbit_camera(const wvol_camera *cam, double deg)
{
    wvol_camera c = *cam;
    double f[3], u[3], r[3], fn = 0, un = 0, dot = 0, v[3], k = deg * 3.14159265358979323846 / 180.0;
    if (deg == 0) return c; /* the camera as given, bit for bit */
    for (int q = 0; q < 3; q++) f[q] = cam->center[q] - cam->eye[q];
    for (int q = 0; q < 3; q++) dot += cam->up[q] * f[q], fn += f[q] * f[q];
    for (int q = 0; q < 3; q++) u[q] = cam->up[q] - dot / fn * f[q]; /* up made normal to the view */
    for (int q = 0; q < 3; q++) un += u[q] * u[q];
    un = sqrt(un);
    for (int q = 0; q < 3; q++) u[q] /= un;
    /* v = eye - centre = -f, turned about u: v cos k + (u x v) sin k (v is normal to u) */
    for (int q = 0; q < 3; q++) v[q] = -f[q];
    r[0] = u[1] * v[2] - u[2] * v[1];
    r[1] = u[2] * v[0] - u[0] * v[2];
    r[2] = u[0] * v[1] - u[1] * v[0];
    for (int q = 0; q < 3; q++) c.eye[q] = cam->center[q] + v[q] * cos(k) + r[q] * sin(k);
    return c;
}

/* What --repeat measured: the first frame (a context's set-up included) and the fastest later
 * frame, CPU and wall seconds. */
typedef struct repeat_times {
    double first_cpu, first_wall, later_cpu, later_wall;
    int context;            /* the frames went through one render context */
    size_t context_bytes;   /* what the context held after the last frame */
    wvol_render_stats last; /* the last frame's stats */
} repeat_times;

/* --repeat: N frames through one render context, its set-up kept from frame to frame (a user
 * turning the view: --orbit turns the camera between frames), or with --one-shot N separate
 * calls, each building all it needs again. *best is the fastest frame (the benchmarks read the
 * best of N beside the peers' best of N), rt the first frame's and the later frames' times. The
 * resident peak is the first frame's: later frames hold what the first built, and malloc's
 * reuse of what they freed can raise the process's peak a little. */
static wvol_status render_repeat(wvol_image *img, const wvol_render_source *src, const wvol_camera *cam,
                                 const wvol_tf *tf, const render_args *a, const wvol_render_params *rp,
                                 const wvol_lod_params *lp, wvol_render_stats *best, wvol_lod_stats *lod,
                                 double *cpu_max, double rss[2], repeat_times *rt, wvol_error *err)
{
    double wall_min = 0;
    wvol_render_context *ctx = NULL;
    wvol_status s = WVOL_OK;
    memset(rt, 0, sizeof *rt);
    rss[0] = rss[1] = -1;
    /* one frame: nothing to keep for a next one */
    if (!a->one_shot && a->repeat > 1 && (s = wvol_render_context_create(&ctx, src, rp, a->context_cache, err)) != WVOL_OK) return s;
    rt->context = ctx != NULL;
    if (rss_reset_peak() == 0) rss[0] = rss_mib("VmRSS");
    for (long i = 0; i < a->repeat; i++) {
        wvol_render_stats one;
        wvol_lod_stats lone;
        const wvol_camera c = orbit_camera(cam, a->orbit * (double)(a->repeat - 1 - i));
        memset(&one, 0, sizeof one);
        s = ctx ? wvol_render_lod_context(ctx, img, &c, tf, rp, lp, &one, &lone, err)
                : wvol_render_lod(img, src, &c, tf, rp, lp, &one, &lone, err);
        if (s != WVOL_OK) break;
        if (i == 0 && rss[0] >= 0) rss[1] = rss_mib("VmHWM");
        if (i == 0) rt->first_cpu = one.cpu_seconds, rt->first_wall = one.seconds;
        else if (i == 1 || one.cpu_seconds < rt->later_cpu) rt->later_cpu = one.cpu_seconds;
        if (i == 1 || (i > 1 && one.seconds < rt->later_wall)) rt->later_wall = one.seconds;
        if (i == 0 || one.cpu_seconds > *cpu_max) *cpu_max = one.cpu_seconds;
        if (i == 0 || one.seconds < wall_min) wall_min = one.seconds;
        if (i == 0 || one.cpu_seconds < best->cpu_seconds) *best = one, *lod = lone;
        rt->last = one;
    }
    if (s == WVOL_OK) best->seconds = wall_min;
    rt->context_bytes = wvol_render_context_bytes(ctx);
    wvol_render_context_destroy(ctx);
    return s;
}

/* A bound image: EXR, joining the command's outputs (output_set.h). */
static wvol_status write_bound_exr(const wvol_image *img, const char *path, wvol_error *err)
{
    wvol_status s = output_set_add(path, err);
    return s ? s : wvol_image_write_exr(img, path, NULL, err);
}

static wvol_status write_image_to(const wvol_image *img, const render_args *a, const char *path, wvol_error *err)
{
    double exposure = a->exposure;
    wvol_status s = output_set_add(path, err);
    if (s) return s;
    if (wvol_path_has_ext(path, ".exr")) return wvol_image_write_exr(img, path, NULL, err);
    if (!a->exposure_given) {
        exposure = 1.0;
        if (a->rp.mode == WVOL_RENDER_MODE_XRAY) {
            size_t i, n = (size_t)img->width * (size_t)img->height;
            double mx = 0;
            for (i = 0; i < n; i++) mx = fmax(mx, img->rgba[4 * i]);
            exposure = mx > 0 ? 1.0 / mx : 1.0;
        }
    }
    return wvol_image_write_png(img, path, NULL, exposure, err);
}

static wvol_status write_image(const wvol_image *img, const render_args *a, wvol_error *err)
{
    return write_image_to(img, a, a->out, err);
}

/* --bound: the per-pixel bound from what the store dropped (and a .wvc's quantiser); a dense
 * source dropped nothing, so its bound is 0. */
static wvol_status write_bound(const render_args *a, const render_input *in, const wvol_camera *cam,
                               const wvol_tf *tf, wvol_render_bound_stats *bs, wvol_error *err)
{
    wvol_image *b = NULL;
    wvol_status s;
    memset(bs, 0, sizeof *bs);
    if (!a->bound_path) return WVOL_OK;
    s = wvol_image_create(&b, (int)a->width, (int)a->height, err);
    if (s != WVOL_OK) return s;
    if (in->store.residual)
        s = (a->bound_method == WVOL_BOUND_COARSE ? wvol_render_bound_coarse : wvol_render_bound)(
            b, in->store.residual, in->coeff_error, cam, tf, &a->rp, bs, err);
    if (s == WVOL_OK) s = write_bound_exr(b, a->bound_path, err);
    wvol_image_destroy(b);
    return s;
}

static void report(const render_args *a, const render_input *in, const wvol_render_stats *st,
                   const wvol_lod_stats *lod, double t_prep, double cpu_max, const double rss[2],
                   const wvol_render_bound_stats *bs, const repeat_times *rt)
{
    double n = (double)in->geometry.dims[0] * (double)in->geometry.dims[1] * (double)in->geometry.dims[2];
    double lod_psnr = wvol_wvc_psnr(lod->energy, n, in->vmin, in->vmax);
    const char *method = wvol_render_method_name(st->method), *mode = wvol_render_mode_name(a->rp.mode);
    const wvol_store *store = in->store.store;
    wvol_store_info si;
    if (store) wvol_store_get_info(store, &si);
    if (!a->json) {
        printf("wrote %s (%ldx%ld, %s, %s) in %.3f s render + %.3f s preparation\n", a->out, a->width, a->height,
               method, mode, st->seconds, t_prep);
        if (lod->level > 0)
            printf("level of detail: level %d of %d (%zu x %zu x %zu, voxel %.4g <= pixel footprint %.4g), extra "
                   "error RMSE %.4g (PSNR %.2f dB); --full-resolution renders the full grid\n",
                   lod->level, lod->levels, lod->dims[0], lod->dims[1], lod->dims[2], lod->voxel, lod->footprint,
                   lod->rmse, lod_psnr);
        if (a->rp.skip_tolerance > 0)
            printf("skipped %zu nearly empty brick runs: each pixel within %.3g of the unskipped image (tolerance %g)\n",
                   st->skipped_tolerance, st->skip_bound, a->rp.skip_tolerance);
        if (a->bound_path)
            printf("wrote %s: per-pixel bound on the dropped coefficients' effect, max %.4g, mean %.4g (%.3f s)\n",
                   a->bound_path, bs->max, bs->mean, bs->seconds);
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
    cli_json_open("lod", '{');
    cli_json_int("enabled", !a->full_resolution);
    cli_json_int("level", lod->level);
    cli_json_int("levels", lod->levels);
    cli_json_num("footprint", lod->footprint);
    cli_json_num("voxel", lod->voxel);
    cli_json_size3("dims", lod->dims[0], lod->dims[1], lod->dims[2]);
    cli_json_num("energy", lod->energy);
    cli_json_num("rmse", lod->rmse);
    cli_json_num("psnr", lod_psnr);
    cli_json_num("coarse_seconds", lod->seconds);
    cli_json_close('}');
    cli_json_num("prepare_seconds", t_prep);
    if (st->method == WVOL_RENDER_METHOD_REFERENCE && store)
        cli_json_num("reconstruct_cpu_seconds", st->reconstruct_cpu_seconds);
    cli_json_num("render_seconds", st->seconds);
    cli_json_num("render_cpu_seconds", st->cpu_seconds - st->reconstruct_cpu_seconds);
    if (a->repeat > 1) {
        cli_json_int("repeat", a->repeat);
        cli_json_num("render_cpu_seconds_max", cpu_max);
        cli_json_int("context", rt->context);
        cli_json_num("orbit", a->orbit);
        cli_json_num("first_cpu_seconds", rt->first_cpu);
        cli_json_num("first_seconds", rt->first_wall);
        cli_json_num("later_cpu_seconds", rt->later_cpu);
        cli_json_num("later_seconds", rt->later_wall);
        if (rt->context) {
            /* the last frame's reuse */
            cli_json_int("context_frame", rt->last.context_frame);
            cli_json_int("rates_reused", rt->last.rates_reused);
            cli_json_int("bricks_reused", (long long)rt->last.bricks_reused);
            cli_json_int("bricks_built_last", (long long)rt->last.bricks_built);
            cli_json_int("tiles_own_last", rt->last.tiles_own);
            cli_json_int("cache_bytes", (long long)rt->last.cache_bytes);
            cli_json_int("context_bytes", (long long)rt->context_bytes);
        }
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
    if (a->bound_path) {
        cli_json_str("bound", a->bound_path);
        cli_json_num("bound_max", bs->max);
        cli_json_num("bound_mean", bs->mean);
        cli_json_num("bound_coeff_error", in->coeff_error);
        cli_json_num("bound_seconds", bs->seconds);
    }
    cli_json_num("rss_before_render_mib", rss[0]);
    cli_json_num("rss_peak_render_mib", rss[1]);
    cli_json_end();
}

/* PATH with ".passN" before its extension. 0 when it does not fit. */
static int pass_name(char *buf, size_t n, const char *path, int index)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    int w;
    if (!dot || (slash && dot < slash)) dot = path + strlen(path);
    w = snprintf(buf, n, "%.*s.pass%d%s", (int)(dot - path), path, index, dot);
    return w > 0 && (size_t)w < n;
}

/* One pass's files: OUT.passN (and BOUND.passN with --bound; a bound computed only for
 * --max-error is not written), and for the last OUT (and BOUND) too. A failure undoes every
 * pass's files (main's output_set_undo): none or all of them stay. */
static wvol_status write_pass(const render_args *a, const wvol_image *img, const wvol_image *bimg,
                              const wvol_progressive_pass *pass, wvol_error *err)
{
    char name[4096], bname[4096];
    wvol_status st = WVOL_OK;
    const int bounded = bimg && a->bound_path;
    if (!pass_name(name, sizeof name, a->out, pass->index))
        return wvol_error_set(err, WVOL_ERR_ARG, "output name %s too long", a->out);
    if (bounded && !pass_name(bname, sizeof bname, a->bound_path, pass->index))
        return wvol_error_set(err, WVOL_ERR_ARG, "bound name %s too long", a->bound_path);
    st = write_image_to(img, a, name, err);
    if (st == WVOL_OK && pass->last) st = write_image_to(img, a, a->out, err);
    if (st == WVOL_OK && bounded) st = write_bound_exr(bimg, bname, err);
    if (st == WVOL_OK && bounded && pass->last) st = write_bound_exr(bimg, a->bound_path, err);
    return st;
}

static void report_passes(const render_args *a, const wvol_progressive_pass *ps, int n)
{
    int i;
    if (!a->json) {
        for (i = 0; i < n; i++)
            printf("pass %d: %zu of %zu coefficients, %s, %.3f s (%.3f s in all)%s%.4g%s\n", ps[i].index,
                   ps[i].kept, ps[i].total, wvol_render_method_name(ps[i].method), ps[i].seconds, ps[i].elapsed,
                   a->pp.bound ? ", bound max " : "", a->pp.bound ? ps[i].bound_max : 0.0, "");
        if (n) printf("wrote %s (the last pass; stop: %s)\n", a->out, ps[n - 1].stop);
        return;
    }
    cli_json_begin();
    cli_json_str("input", a->in);
    cli_json_str("output", a->out);
    cli_json_str("mode", wvol_render_mode_name(a->rp.mode));
    if (n) cli_json_str("stop", ps[n - 1].stop);
    cli_json_open("passes", '[');
    for (i = 0; i < n; i++) {
        cli_json_open(NULL, '{');
        cli_json_int("index", ps[i].index);
        cli_json_int("kept", (long long)ps[i].kept);
        cli_json_int("total", (long long)ps[i].total);
        cli_json_str("method", wvol_render_method_name(ps[i].method));
        cli_json_num("seconds", ps[i].seconds);
        cli_json_num("elapsed", ps[i].elapsed);
        if (a->pp.bound) {
            cli_json_num("bound_max", ps[i].bound_max);
            cli_json_num("bound_mean", ps[i].bound_mean);
        }
        cli_json_close('}');
    }
    cli_json_close(']');
    cli_json_end();
}

/* --progressive: passes from the volume until the target, the budget or everything kept. */
static int render_progressive(render_args *a)
{
    wvol_volume *v = NULL;
    wvol_progressive *pr = NULL;
    wvol_progressive_pass *ps = NULL;
    wvol_image *img = NULL, *bimg = NULL;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_error err;
    double vmin, vmax;
    int rc = CLI_OK, n = 0, cap = 0;
    memset(&tf, 0, sizeof tf);
    if (wvol_volume_load(&v, a->in, &a->lo, &err) != WVOL_OK) return cli_fail_err("render", &err);
    wvol_volume_range(v, &vmin, &vmax, NULL);
    wvol_geometry_of_volume(&g, v);
    if (wvol_camera_parse(&cam, a->camspec, &g, (int)a->width, (int)a->height, &err) != WVOL_OK) {
        rc = cli_usage("render", "%s", err.message);
        goto done;
    }
    if (a->rp.mode != WVOL_RENDER_MODE_XRAY && (rc = cli_load_tf("render", a->tfname, vmin, vmax, &tf)) != CLI_OK)
        goto done;
    if (wvol_image_create(&img, (int)a->width, (int)a->height, &err) != WVOL_OK) goto fail;
    if (a->pp.bound && wvol_image_create(&bimg, (int)a->width, (int)a->height, &err) != WVOL_OK) goto fail;
    if (wvol_progressive_begin(&pr, v, &a->cp, &a->pp, &err) != WVOL_OK) goto fail;
    wvol_volume_destroy(v); /* the passes read the coefficients */
    v = NULL;
    for (;;) {
        if (n == cap) {
            int nc = cap ? 2 * cap : 16;
            wvol_progressive_pass *q = realloc(ps, (size_t)nc * sizeof *q);
            if (!q) {
                wvol_error_set(&err, WVOL_ERR_NOMEM, "out of memory");
                goto fail;
            }
            ps = q, cap = nc;
        }
        if (wvol_progressive_next(pr, img, bimg, &cam, &tf, &a->rp, &ps[n], &err) != WVOL_OK) goto fail;
        if (write_pass(a, img, bimg, &ps[n], &err) != WVOL_OK) goto fail;
        if (ps[n++].last) break;
    }
    report_passes(a, ps, n);
    goto done;
fail:
    rc = cli_fail_err("render", &err);
done:
    free(ps);
    wvol_progressive_end(pr);
    wvol_image_destroy(img);
    wvol_image_destroy(bimg);
    wvol_volume_destroy(v);
    return rc;
}

int wvol_cmd_render(int argc, char **argv)
{
    render_args a;
    render_input in;
    wvol_render_source src;
    wvol_render_stats stats;
    wvol_render_bound_stats bstats;
    wvol_lod_stats lstats;
    wvol_lod_params lp;
    repeat_times rt;
    wvol_image *img = NULL;
    wvol_camera cam;
    wvol_tf tf;
    wvol_error err;
    double t0, t_prep, cpu_max = 0, rss[2] = {-1, -1};
    int rc = parse_args(&a, argc, argv);
    if (rc != CLI_OK) return rc < 0 ? CLI_OK : rc;
    if (a.progressive) return render_progressive(&a);
    memset(&in, 0, sizeof in);
    memset(&tf, 0, sizeof tf);
    memset(&stats, 0, sizeof stats);
    wvol_error_clear(&err);

    t0 = cli_now();
    if ((rc = load_input(&a, &in, &err)) != CLI_OK) goto done;
    if ((rc = load_colors(&a, &in, &a.rp, &err)) != CLI_OK) goto done;
    if (wvol_camera_parse(&cam, a.camspec, &in.geometry, (int)a.width, (int)a.height, &err) != WVOL_OK) {
        rc = cli_usage("render", "%s", err.message);
        goto done;
    }
    if (a.rp.mode != WVOL_RENDER_MODE_XRAY && (rc = cli_load_tf("render", a.tfname, in.vmin, in.vmax, &tf)) != CLI_OK)
        goto done;
    src = in.volume ? wvol_render_source_volume(in.volume) : wvol_render_source_store(in.store.store);
    if (wvol_store_is_file(in.store.store)) a.rp.method = WVOL_RENDER_METHOD_BRICKS;
    if (wvol_image_create(&img, (int)a.width, (int)a.height, &err) != WVOL_OK) goto fail;
    t_prep = cli_now() - t0;
    wvol_lod_params_default(&lp);
    lp.enabled = !a.full_resolution && !a.bound_path; /* the bound is the full grid's */
    if (in.volume && wvol_filter_get(&lp.filter, a.cp.wavelet, &err) != WVOL_OK) goto fail;
    memset(&lstats, 0, sizeof lstats);
    if (render_repeat(img, &src, &cam, &tf, &a, &a.rp, &lp, &stats, &lstats, &cpu_max, rss, &rt, &err) != WVOL_OK)
        goto fail;
    /* a chunk of a .wvc found damaged while rendering fails the command before any output */
    if ((rc = cli_check_wvc_store("render", &in.store, 0)) != CLI_OK) goto done;
    if (write_image(img, &a, &err) != WVOL_OK) goto fail;
    if (write_bound(&a, &in, &cam, &tf, &bstats, &err) != WVOL_OK) goto fail;
    report(&a, &in, &stats, &lstats, t_prep, cpu_max, rss, &bstats, &rt);
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
