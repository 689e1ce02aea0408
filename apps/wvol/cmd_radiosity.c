/* SPDX-License-Identifier: MIT */
/* wvol radiosity: wavelet radiosity of a scene of quads (OBJ + MTL or a built-in), rendered
 * straight from the basis functions (.png/.exr) or written as a mesh with per-cell radiosity
 * (.ply/.vtp); --json reports interactions, kernel evaluations, iterations, time and the energy. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "output_set.h"
#include "wvol/radiosity.h"

const char wvol_cmd_radiosity_summary[] = "wavelet radiosity of quads (OBJ or built-in): image or mesh";

static const cli_opt opts[] = {
    {"output", 'o', 1, "output: .png .exr (image) or .ply .vtp (mesh with per-cell radiosity)"},
    {"basis", 0, 1, "haar (= m1), m2, m3, m4, f2, f3 (default haar)"},
    {"epsilon", 0, 1, "oracle threshold on the estimated transport error (default 1e-3)"},
    {"max-level", 0, 1, "finest level: cells of 2^-L of each patch side (default 5)"},
    {"brightness", 0, 0, "weight the oracle by the transferred brightness (refine, solve, refine again)"},
    {"full-matrix", 0, 0, "classical radiosity: link every finest cell to every other (no oracle)"},
    {"camera", 0, 1, "camera (docs/render.md; default \"persp dir=0.3,1,-0.4\", looking into the box)"},
    {"size", 0, 1, "image size WxH (default 512x512)"},
    {"exposure", 0, 1, "PNG: scale before sRGB encoding (default 1/the image's 99th percentile)"},
    {"mesh", 0, 1, "also write the mesh (.ply or .vtp)"},
    {"mesh-res", 0, 1, "mesh cells per patch side (default 2^max-level)"},
    CLI_JSON_OPT,
    CLI_HELP_OPT,
    {NULL, 0, 0, NULL}};

static int is_image(const char *p) { return wvol_path_has_ext(p, ".png") || wvol_path_has_ext(p, ".exr"); }
static int is_mesh(const char *p) { return wvol_path_has_ext(p, ".ply") || wvol_path_has_ext(p, ".vtp"); }

/* Exposure putting the 99th percentile of the lit pixels' largest channel at 1. */
static double auto_exposure(const wvol_image *img)
{
    size_t n = (size_t)img->width * img->height, hist[1024] = {0}, lit = 0, acc = 0;
    double mx = 0;
    for (size_t i = 0; i < n; i++)
        if (img->rgba[4 * i + 3] > 0)
            mx = fmax(mx, fmax(img->rgba[4 * i], fmax(img->rgba[4 * i + 1], img->rgba[4 * i + 2])));
    if (!(mx > 0)) return 1;
    for (size_t i = 0; i < n; i++)
        if (img->rgba[4 * i + 3] > 0) {
            double v = fmax(img->rgba[4 * i], fmax(img->rgba[4 * i + 1], img->rgba[4 * i + 2]));
            hist[(size_t)fmin(1023, v / mx * 1023)]++;
            lit++;
        }
    for (int b = 0; b < 1024; b++) {
        acc += hist[b];
        if (acc >= 0.99 * lit) return 1.0 / (mx * (b + 1) / 1024.0);
    }
    return 1.0 / mx;
}

int wvol_cmd_radiosity(int argc, char **argv)
{
    const char *cmd = "radiosity", *scene_arg = NULL, *out = NULL, *mesh = NULL,
               *camspec = "persp dir=0.3,1,-0.4";
    cli_parser p;
    const cli_opt *o;
    const char *val;
    int r, json = 0, rc = CLI_FAILED;
    long width = 512, height = 512, lv, mesh_res = 0;
    double exposure = 0;
    wvol_radiosity_params par;
    wvol_radiosity_stats st;
    wvol_radiosity_scene *scene = NULL;
    wvol_radiosity *sol = NULL;
    wvol_image *img = NULL;
    wvol_error err;
    double t0 = cli_now(), t_out = 0;

    wvol_radiosity_params_default(&par);
    cli_parser_init(&p, cmd, argc, argv, opts);
    while ((r = cli_next(&p, &o, &val)) >= 0) {
        if (r == CLI_USAGE) return CLI_USAGE;
        if (!o) {
            if (cli_one_input(cmd, &scene_arg, val) != CLI_OK) return CLI_USAGE;
            continue;
        }
        if (o->short_name == 'h') {
            cli_print_help(cmd, "SCENE -o OUT [--basis B] [--epsilon E] [--max-level L] [--camera C] [--json]",
                           "Wavelet radiosity (Gortler, Schroeder, Cohen, Hanrahan 1993). SCENE is a Wavefront .obj\n"
                           "of quads with its MTL (Kd reflectance, Ke emission) or a built-in: parallel,\n"
                           "perpendicular, box. The radiosity is projected onto tree wavelets on each patch,\n"
                           "links are refined by the kernel-smoothness oracle, then gather / push-pull to\n"
                           "convergence. Images show the basis functions as they are (no smoothing).",
                           opts);
            return CLI_OK;
        }
        if (!strcmp(o->name, "output")) out = val;
        else if (!strcmp(o->name, "basis")) {
            if (wvol_radiosity_basis_parse(val, &par.basis, &err) != WVOL_OK) return cli_usage(cmd, "%s", err.message);
        } else if (!strcmp(o->name, "epsilon")) {
            if (!cli_parse_double(cmd, "epsilon", val, &par.epsilon)) return CLI_USAGE;
            if (!(par.epsilon >= 0) || !isfinite(par.epsilon)) return cli_usage(cmd, "--epsilon %s: must be >= 0", val);
        } else if (!strcmp(o->name, "max-level")) {
            if (!cli_parse_long(cmd, "max-level", val, 0, 12, &lv)) return CLI_USAGE;
            par.max_level = (int)lv;
        } else if (!strcmp(o->name, "brightness")) par.brightness = 1;
        else if (!strcmp(o->name, "full-matrix")) par.full_matrix = 1;
        else if (!strcmp(o->name, "camera")) camspec = val;
        else if (!strcmp(o->name, "size")) {
            if (!cli_parse_size(cmd, "size", val, &width, &height)) return CLI_USAGE;
        } else if (!strcmp(o->name, "exposure")) {
            if (!cli_parse_double(cmd, "exposure", val, &exposure)) return CLI_USAGE;
            if (!(exposure > 0)) return cli_usage(cmd, "--exposure %s: must be > 0", val);
        } else if (!strcmp(o->name, "mesh")) mesh = val;
        else if (!strcmp(o->name, "mesh-res")) {
            if (!cli_parse_long(cmd, "mesh-res", val, 1, 4096, &mesh_res)) return CLI_USAGE;
        } else if (!strcmp(o->name, "json")) json = 1;
    }
    if (!scene_arg) return cli_usage(cmd, "no scene (an .obj file or parallel, perpendicular, box)");
    if (!out) return cli_usage(cmd, "no output (-o OUT.png|.exr|.ply|.vtp)");
    if (!is_image(out) && !is_mesh(out)) return cli_usage(cmd, "-o %s: use .png, .exr, .ply or .vtp", out);
    if (mesh && !is_mesh(mesh)) return cli_usage(cmd, "--mesh %s: use .ply or .vtp", mesh);
    {
        const char *outs[2] = {out, mesh}, *same = cli_same_output(outs, 2);
        if (same) return cli_usage(cmd, "--mesh and -o would write the same file (%s)", same);
    }
    /* options that shape an output this run does not write are refused, not ignored (docs/cli.md) */
    if (mesh_res && !mesh && !is_mesh(out))
        return cli_usage(cmd, "--mesh-res sets the written mesh's cells: add --mesh (or -o a .ply or .vtp)");
    if (!is_image(out) && (cli_given(&p, "camera") || cli_given(&p, "size") || cli_given(&p, "exposure")))
        return cli_usage(cmd, "--camera, --size and --exposure shape an image: -o %s writes a mesh", out);
    if (exposure > 0 && !wvol_path_has_ext(out, ".png"))
        return cli_usage(cmd, "--exposure scales a PNG's values: -o %s is not a .png", out);
    if (!mesh_res) mesh_res = 1L << (par.max_level < 8 ? par.max_level : 8);

    if (wvol_path_has_ext(scene_arg, ".obj")) {
        /* a quad the file describes badly is bad input (exit 1), not bad usage */
        if (wvol_radiosity_scene_load_obj(&scene, scene_arg, &err) != WVOL_OK) return cli_fail(cmd, "%s", err.message);
    } else if (wvol_radiosity_scene_builtin(&scene, scene_arg, &err) != WVOL_OK) {
        return cli_usage(cmd, "%s", err.message);
    }
    if (wvol_radiosity_solve(&sol, scene, &par, &st, &err) != WVOL_OK) goto fail;
    t_out = cli_now();
    if (output_set_add(out, &err) != WVOL_OK) goto fail;
    if (is_image(out)) {
        wvol_camera cam;
        wvol_geometry g;
        wvol_radiosity_geometry(scene, &g);
        if (wvol_camera_parse(&cam, camspec, &g, (int)width, (int)height, &err) != WVOL_OK) {
            rc = cli_usage(cmd, "%s", err.message);
            goto done;
        }
        if (wvol_image_create(&img, (int)width, (int)height, &err) != WVOL_OK) goto fail;
        if (wvol_radiosity_render(sol, img, &cam, &err) != WVOL_OK) goto fail;
        if (wvol_path_has_ext(out, ".exr")) {
            if (wvol_image_write_exr(img, out, NULL, &err) != WVOL_OK) goto fail;
        } else if (wvol_image_write_png(img, out, NULL, exposure > 0 ? exposure : auto_exposure(img), &err) != WVOL_OK) {
            goto fail;
        }
    } else if (wvol_radiosity_write_mesh(sol, out, (int)mesh_res, &err) != WVOL_OK) {
        goto fail;
    }
    if (mesh && (output_set_add(mesh, &err) || wvol_radiosity_write_mesh(sol, mesh, (int)mesh_res, &err) != WVOL_OK))
        goto fail;
    t_out = cli_now() - t_out;
    if (json) {
        cli_json_begin();
        cli_json_str("scene", scene_arg);
        cli_json_int("patches", (long long)wvol_radiosity_scene_count(scene));
        cli_json_str("basis", wvol_radiosity_basis_name(par.basis));
        cli_json_num("epsilon", par.epsilon);
        cli_json_int("max_level", par.max_level);
        cli_json_int("brightness", par.brightness);
        cli_json_int("full_matrix", par.full_matrix);
        cli_json_int("interactions", (long long)st.links);
        cli_json_int("link_terms", (long long)st.link_terms);
        cli_json_int("nodes", (long long)st.nodes);
        cli_json_int("leaves", (long long)st.leaves);
        cli_json_int("kernel_evaluations", (long long)st.kernel_evals);
        cli_json_int("closed_form_evaluations", (long long)st.closed_form_evals);
        cli_json_int("rays", (long long)st.rays);
        cli_json_int("iterations", st.iterations);
        cli_json_num("last_change", st.change);
        cli_json_num3("emitted", st.emitted);
        cli_json_num3("absorbed", st.absorbed);
        cli_json_num("energy_error", st.energy_error);
        cli_json_num("seconds_refine", st.seconds_refine);
        cli_json_num("seconds_solve", st.seconds_solve);
        cli_json_num("seconds_output", t_out);
        cli_json_num("seconds_total", cli_now() - t0);
        cli_json_str("output", out);
        if (mesh) cli_json_str("mesh", mesh);
        cli_json_end();
    } else {
        printf("%s: %s, %zu patches, %zu interactions, %zu kernel evaluations, %d iterations, energy balance %.2e; "
               "wrote %s%s%s\n",
               scene_arg, wvol_radiosity_basis_name(par.basis), wvol_radiosity_scene_count(scene), st.links,
               st.kernel_evals, st.iterations, st.energy_error, out, mesh ? " and " : "", mesh ? mesh : "");
    }
    rc = CLI_OK;
    goto done;
fail:
    rc = cli_fail_err(cmd, &err);
done:
    wvol_image_destroy(img);
    wvol_radiosity_destroy(sol);
    wvol_radiosity_scene_destroy(scene);
    return rc;
}
