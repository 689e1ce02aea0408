/* SPDX-License-Identifier: MIT */
/* The rendering entry point (wvol_render): resolves AUTO, runs one method on a dense volume
 * or a store; names of methods and modes as the CLI and Python spell them. */
#include "render_internal.h"

#include <string.h>

static const char *const method_names[] = {"auto", "reference", "reference-fhat", "bricks", "spline", "axis", "splat"};
static const char *const mode_names[] = {"xray", "absorption", "absorption-linear"};
#define COUNT(a) (int)(sizeof(a) / sizeof(a)[0])

const char *wvol_render_method_name(wvol_render_method m)
{
    return (int)m >= 0 && (int)m < COUNT(method_names) ? method_names[m] : "unknown";
}

const char *wvol_render_mode_name(wvol_render_mode m)
{
    return (int)m >= 0 && (int)m < COUNT(mode_names) ? mode_names[m] : "unknown";
}

wvol_status wvol_render_method_parse(wvol_render_method *m, const char *name, wvol_error *err)
{
    WVOL_RETURN_IF(!m, err, WVOL_ERR_ARG, "render: method output pointer is NULL");
    for (int i = 0; name && i < COUNT(method_names); i++)
        if (!strcmp(name, method_names[i])) {
            *m = (wvol_render_method)i;
            return WVOL_OK;
        }
    return wvol_error_set(err, WVOL_ERR_ARG,
                          "method '%s': expected auto, reference, reference-fhat, bricks, spline, axis or splat",
                          name ? name : "(null)");
}

wvol_status wvol_render_mode_parse(wvol_render_mode *m, const char *name, wvol_error *err)
{
    WVOL_RETURN_IF(!m, err, WVOL_ERR_ARG, "render: mode output pointer is NULL");
    for (int i = 0; name && i < COUNT(mode_names); i++)
        if (!strcmp(name, mode_names[i])) {
            *m = (wvol_render_mode)i;
            return WVOL_OK;
        }
    return wvol_error_set(err, WVOL_ERR_ARG, "mode '%s': expected xray, absorption or absorption-linear",
                          name ? name : "(null)");
}

wvol_render_source wvol_render_source_volume(const wvol_volume *v)
{
    wvol_render_source s = {WVOL_RENDER_SOURCE_VOLUME, v, NULL};
    return s;
}

wvol_render_source wvol_render_source_store(const wvol_store *st)
{
    wvol_render_source s = {WVOL_RENDER_SOURCE_STORE, NULL, st};
    return s;
}

/* REFERENCE and REFERENCE_FHAT from a store: the dense volume (or coefficients) first. */
static wvol_status render_store_dense(wvol_image *img, const wvol_store *st, wvol_render_method m,
                                      const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *p,
                                      wvol_render_stats *stats, double *recon_cpu, wvol_error *err)
{
    wvol_coeffs *c = NULL;
    wvol_volume *v = NULL;
    double c0 = wvol__cpu_now();
    wvol_status s = wvol_store_densify(st, &c, err);
    if (s == WVOL_OK && m == WVOL_RENDER_METHOD_REFERENCE) {
        s = wvol_idwt3(&v, c, err);
        wvol_coeffs_destroy(c);
        c = NULL;
    }
    *recon_cpu = wvol__cpu_now() - c0;
    if (s == WVOL_OK)
        s = m == WVOL_RENDER_METHOD_REFERENCE
                ? wvol_render_reference(img, v, cam, tf, p, stats, err)
                : wvol_render_reference_fhat(img, c, wvol_store_basis(st), cam, tf, p, stats, err);
    wvol_volume_destroy(v);
    wvol_coeffs_destroy(c);
    return s;
}

/* The bricked method from a store: through the context's kept state when there is one. */
static wvol_status render_bricks(wvol_render_context *ctx, wvol_image *img, const wvol_store *st,
                                 const wvol_camera *cam, const wvol_tf *tf, const wvol_render_params *p,
                                 wvol_render_stats *stats, wvol_error *err)
{
    return ctx ? wvol__context_bricks(ctx, img, st, cam, tf, p, stats, err)
               : wvol_render_bricks(img, st, cam, tf, p, stats, err);
}

wvol_status wvol__render_dispatch(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                                  const wvol_tf *tf, const wvol_render_params *params, wvol_render_stats *stats,
                                  wvol_render_context *ctx, wvol_error *err)
{
    wvol_render_params p;
    wvol_render_method m;
    wvol_status s;
    double recon_cpu = 0;
    wvol__params(&p, params);
    m = p.method;
    WVOL_RETURN_IF(!source, err, WVOL_ERR_ARG, "render: no source");
    WVOL_RETURN_IF((int)m < 0 || (int)m >= COUNT(method_names), err, WVOL_ERR_ARG, "render: unknown method %d",
                   (int)m);
    if (source->kind == WVOL_RENDER_SOURCE_VOLUME) {
        WVOL_RETURN_IF(!source->volume, err, WVOL_ERR_ARG, "render: no volume");
        if (m == WVOL_RENDER_METHOD_AUTO) m = WVOL_RENDER_METHOD_REFERENCE;
        WVOL_RETURN_IF(m != WVOL_RENDER_METHOD_REFERENCE, err, WVOL_ERR_UNSUPPORTED,
                       "render: method %s needs a store (wvol_compress); a dense volume renders with reference",
                       wvol_render_method_name(m));
        s = wvol_render_reference(img, source->volume, cam, tf, &p, stats, err);
    } else if (source->kind == WVOL_RENDER_SOURCE_STORE) {
        const wvol_store *st = source->store;
        WVOL_RETURN_IF(!st, err, WVOL_ERR_ARG, "render: no store");
        s = WVOL_ERR_UNSUPPORTED;
        if (m == WVOL_RENDER_METHOD_AUTO) {
            /* axis is exact and costs O(kept + pixels): take it wherever it applies */
            m = WVOL_RENDER_METHOD_BRICKS;
            if (p.mode == WVOL_RENDER_MODE_XRAY && !p.colors) {
                wvol_error axis_err;
                wvol_error_clear(&axis_err);
                s = wvol_render_xray_axis(img, st, cam, &p, stats, &axis_err);
                if (s == WVOL_OK) m = WVOL_RENDER_METHOD_AXIS;
                else if (s != WVOL_ERR_UNSUPPORTED) {
                    if (err) *err = axis_err;
                    return s;
                }
            }
            if (s == WVOL_ERR_UNSUPPORTED) s = render_bricks(ctx, img, st, cam, tf, &p, stats, err);
        } else {
            switch (m) {
            case WVOL_RENDER_METHOD_REFERENCE:
            case WVOL_RENDER_METHOD_REFERENCE_FHAT:
                s = render_store_dense(img, st, m, cam, tf, &p, stats, &recon_cpu, err);
                break;
            case WVOL_RENDER_METHOD_BRICKS: s = render_bricks(ctx, img, st, cam, tf, &p, stats, err); break;
            case WVOL_RENDER_METHOD_SPLINE: s = wvol_render_spline(img, st, cam, tf, &p, stats, err); break;
            case WVOL_RENDER_METHOD_AXIS: s = wvol_render_xray_axis(img, st, cam, &p, stats, err); break;
            case WVOL_RENDER_METHOD_SPLAT: s = wvol_render_xray_splat(img, st, cam, &p, stats, err); break;
            default: break;
            }
        }
    } else {
        return wvol_error_set(err, WVOL_ERR_ARG, "render: unknown source kind %d", (int)source->kind);
    }
    if (s == WVOL_OK && stats) {
        stats->method = m;
        stats->reconstruct_cpu_seconds = recon_cpu;
        stats->cpu_seconds += recon_cpu;
    }
    return s;
}

wvol_status wvol_render(wvol_image *img, const wvol_render_source *source, const wvol_camera *cam,
                        const wvol_tf *tf, const wvol_render_params *params, wvol_render_stats *stats,
                        wvol_error *err)
{
    return wvol__render_dispatch(img, source, cam, tf, params, stats, NULL, err);
}
