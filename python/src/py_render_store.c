/* The spline-projected renderer and the X-ray axis fast path from a store capsule. */
#include "pyutil.h"
#include "methods.h"
#include "py_render.h"
#include "py_store.h"

#include <string.h>

static PyObject *render_store(PyObject *args, int axis)
{
    PyObject *cap, *opts;
    PyArrayObject *colors;
    const wvol_store *st;
    wvol_store_info in;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_render_params rp;
    wvol_render_stats stats;
    wvol_image *img = NULL;
    wvol_error err;
    wvol_status s;
    double vmin, vmax;
    if (!PyArg_ParseTuple(args, "O(dd)O", &cap, &vmin, &vmax, &opts)) return NULL;
    if (!(st = wvolpy_store_from(cap))) return NULL;
    wvol_store_get_info(st, &in);
    g.dims[0] = in.nx;
    g.dims[1] = in.ny;
    g.dims[2] = in.nz;
    memcpy(g.spacing, in.spacing, sizeof g.spacing);
    memcpy(g.origin, in.origin, sizeof g.origin);
    if (wvolpy_render_setup(opts, &g, vmin, vmax, &cam, &tf, &rp, &colors) < 0) return NULL;
    memset(&stats, 0, sizeof stats);
    Py_BEGIN_ALLOW_THREADS
    s = wvol_image_create(&img, cam.width, cam.height, &err);
    if (s == WVOL_OK)
        s = axis ? wvol_render_xray_axis(img, st, &cam, &rp, &stats, &err)
                 : wvol_render_spline(img, st, &cam, &tf, &rp, &stats, &err);
    Py_END_ALLOW_THREADS
    return wvolpy_render_finish(img, s, &stats, &err, colors);
}

static PyObject *py_render_spline(PyObject *self, PyObject *args)
{
    (void)self;
    return render_store(args, 0);
}

static PyObject *py_render_axis(PyObject *self, PyObject *args)
{
    (void)self;
    return render_store(args, 1);
}

PyMethodDef wvolpy_render_store_methods[] = {
    {"render_spline", py_render_spline, METH_VARARGS, "render_spline(store, value_range, opts) -> (image, stats)"},
    {"render_axis", py_render_axis, METH_VARARGS, "render_axis(store, value_range, opts) -> (image, stats)"},
    {NULL, NULL, 0, NULL}};
