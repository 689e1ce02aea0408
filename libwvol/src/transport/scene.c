/* SPDX-License-Identifier: MIT
 * The stained-glass computation of Lewis & Fournier 2002, §7.3: window radiance, transport to the
 * floor, reflection off a checkerboard of mostly diffuse and mostly specular Phong tiles. */
#include "transport_internal.h"

#include <string.h>

#include "core/clock.h"

static const wvol_transport_brdf *checker(void *user, double u, double v)
{
    const wvol_transport_scene *s = user;
    int iu = (int)(u * s->tiles), iv = (int)(v * s->tiles);
    return (iu + iv) % 2 ? &s->glossy : &s->diffuse;
}

void wvol_transport_scene_result_free(wvol_transport_scene_result *r)
{
    if (!r) return;
    wvol_transport_tree_destroy(r->source);
    wvol_transport_tree_destroy(r->incident);
    wvol_transport_tree_destroy(r->reflected);
    memset(r, 0, sizeof *r);
}

wvol_status wvol_transport_scene_run(wvol_transport_scene_result *r, const wvol_transport_scene *s,
                                     const wvol_transport_window *w, const wvol_transport_params *p, wvol_error *err)
{
    double t0;
    wvol_status st;
    WVOL_RETURN_IF(!r || !s || !w || !p, err, WVOL_ERR_ARG, "window scene: NULL argument");
    memset(r, 0, sizeof *r);
    WVOL_RETURN_IF(s->tiles < 1 || s->tiles > 1024, err, WVOL_ERR_ARG, "window scene: %d tiles outside 1..1024", s->tiles);
    WVOL_FORWARD(wvol__transport_params_check(p, err));
    t0 = wvol__now();
    st = wvol_transport_scene_source(&r->source, s, w, p->levels, err);
    r->seconds_source = wvol__now() - t0;
    if (st == WVOL_OK) st = wvol_transport_run(&r->incident, r->source, &s->window, &s->floor, p, &r->transport, err);
    if (st == WVOL_OK) {
        t0 = wvol__now();
        st = wvol_transport_reflect(&r->reflected, r->incident, &s->diffuse, checker, (void *)s, 0, err);
        r->seconds_reflect = wvol__now() - t0;
    }
    if (st != WVOL_OK) wvol_transport_scene_result_free(r);
    return st;
}
