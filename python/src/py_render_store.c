/* The renderers that read a store capsule: the spline-projected integral, the X-ray fast
 * paths (axis, splat) and the bricked reference integrator. */
#include "pyutil.h"
#include "methods.h"
#include "py_render.h"
#include "py_store.h"

#include <string.h>

enum store_method { STORE_SPLINE, STORE_AXIS, STORE_SPLAT, STORE_BRICKS };

static PyObject *render_store(PyObject *args, enum store_method method)
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
    if (s == WVOL_OK) {
        if (method == STORE_AXIS) s = wvol_render_xray_axis(img, st, &cam, &rp, &stats, &err);
        else if (method == STORE_SPLAT) s = wvol_render_xray_splat(img, st, &cam, &rp, &stats, &err);
        else if (method == STORE_BRICKS) s = wvol_render_bricks(img, st, &cam, &tf, &rp, &stats, &err);
        else s = wvol_render_spline(img, st, &cam, &tf, &rp, &stats, &err);
    }
    Py_END_ALLOW_THREADS
    return wvolpy_render_finish(img, s, &stats, &err, colors);
}

static PyObject *py_render_spline(PyObject *self, PyObject *args)
{
    (void)self;
    return render_store(args, STORE_SPLINE);
}

static PyObject *py_render_axis(PyObject *self, PyObject *args)
{
    (void)self;
    return render_store(args, STORE_AXIS);
}

static PyObject *py_render_splat(PyObject *self, PyObject *args)
{
    (void)self;
    return render_store(args, STORE_SPLAT);
}

static PyObject *py_render_bricks(PyObject *self, PyObject *args)
{
    (void)self;
    return render_store(args, STORE_BRICKS);
}

PyMethodDef wvolpy_render_store_methods[] = {
    {"render_spline", py_render_spline, METH_VARARGS, "render_spline(store, value_range, opts) -> (image, stats)"},
    {"render_axis", py_render_axis, METH_VARARGS, "render_axis(store, value_range, opts) -> (image, stats)"},
    {"render_splat", py_render_splat, METH_VARARGS, "render_splat(store, value_range, opts) -> (image, stats)"},
    {"render_bricks", py_render_bricks, METH_VARARGS, "render_bricks(store, value_range, opts) -> (image, stats)"},
    {NULL, NULL, 0, NULL}};
