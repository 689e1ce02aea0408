/* The C store (wvol/store.h) behind wvol.Store: built from the kept coefficients, held in a
 * capsule, used by the spline renderer and for its memory footprint. */
#include "pyutil.h"
#include "methods.h"
#include "py_store.h"

#include <math.h>
#include <string.h>

#define STORE_CAPSULE "wvol.store"

static void store_capsule_free(PyObject *cap)
{
    wvol_store_destroy(PyCapsule_GetPointer(cap, STORE_CAPSULE));
}

const wvol_store *wvolpy_store_from(PyObject *cap)
{
    return PyCapsule_GetPointer(cap, STORE_CAPSULE); /* NULL with TypeError/ValueError when not a store */
}

/* store_build(coeffs, wavelet, levels, shape, spacing, origin, spline_j=0) -> capsule.
 * Every nonzero coefficient is kept (dropped ones are zero in the array), plus the low-pass cube. */
static PyObject *py_store_build(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"coeffs", "wavelet", "levels", "shape", "spacing", "origin", "spline_j", NULL};
    PyObject *arr_obj, *shape, *sp = Py_None, *org = Py_None, *cap;
    const char *name;
    int levels, J = 0;
    PyArrayObject *holder;
    wvol_coeffs c;
    wvol_store_params prm;
    wvol_store_params_default(&prm);
    wvol_store *st = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OsiO|OOi", kwlist, &arr_obj, &name, &levels, &shape, &sp, &org, &J))
        return NULL;
    if (J < 0 || J > 12) return PyErr_Format(PyExc_ValueError, "spline_j must be in 0..12 (0: default), got %d", J);
    prm.spline_J = J;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, sp, org, &c, &holder) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_store_build(&st, &c, NULL, &prm, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    cap = PyCapsule_New(st, STORE_CAPSULE, store_capsule_free);
    if (!cap) wvol_store_destroy(st);
    return cap;
}

static PyObject *py_store_info(PyObject *self, PyObject *cap)
{
    const wvol_store *st = wvolpy_store_from(cap);
    wvol_store_info in;
    (void)self;
    if (!st) return NULL;
    wvol_store_get_info(st, &in);
    return Py_BuildValue("{s:s,s:i,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:n}", "wavelet", in.filter->name, "levels",
                         in.levels, "kept", (Py_ssize_t)in.kept, "kept_lowpass", (Py_ssize_t)in.kept_lowpass, "nodes",
                         (Py_ssize_t)in.nodes, "roots", (Py_ssize_t)in.roots, "hash_slots", (Py_ssize_t)in.hash_slots,
                         "bytes", (Py_ssize_t)in.bytes, "basis_bytes", (Py_ssize_t)in.basis_bytes, "bytes_per_coeff",
                         in.bytes_per_coeff, "spline_j", (Py_ssize_t)wvol_store_basis(st)->J);
}

/* store_eval(capsule, points (n, 3) in world (x, y, z)) -> (values (n,), gradients (n, 3) world units) */
static PyObject *py_store_eval(PyObject *self, PyObject *args)
{
    PyObject *cap, *pts_obj, *vals, *grads;
    PyArrayObject *pts;
    const wvol_store *st;
    wvol_store_info in;
    npy_intp n;
    (void)self;
    if (!PyArg_ParseTuple(args, "OO", &cap, &pts_obj)) return NULL;
    if (!(st = wvolpy_store_from(cap))) return NULL;
    pts = (PyArrayObject *)PyArray_FROM_OTF(pts_obj, NPY_FLOAT64, NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
    if (!pts) return NULL;
    if (PyArray_NDIM(pts) != 2 || PyArray_DIM(pts, 1) != 3) {
        Py_DECREF(pts);
        return PyErr_Format(PyExc_ValueError, "points must be an (n, 3) array of world (x, y, z)");
    }
    n = PyArray_DIM(pts, 0);
    {
        const double *p = PyArray_DATA(pts);
        for (npy_intp i = 0; i < 3 * n; i++)
            if (!isfinite(p[i])) {
                Py_DECREF(pts);
                return PyErr_Format(PyExc_ValueError, "points: non-finite coordinate in point %zd", (Py_ssize_t)(i / 3));
            }
    }
    {
        npy_intp gd[2] = {n, 3};
        vals = PyArray_SimpleNew(1, &n, NPY_FLOAT64);
        grads = PyArray_SimpleNew(2, gd, NPY_FLOAT64);
    }
    if (!vals || !grads) {
        Py_XDECREF(vals);
        Py_XDECREF(grads);
        Py_DECREF(pts);
        return NULL;
    }
    wvol_store_get_info(st, &in);
    {
        const double *p = PyArray_DATA(pts);
        double *v = PyArray_DATA((PyArrayObject *)vals), *g = PyArray_DATA((PyArrayObject *)grads);
        Py_BEGIN_ALLOW_THREADS
        for (npy_intp i = 0; i < n; i++) {
            double vox[3], gr[3];
            wvol_store_world_to_voxel(st, p + 3 * i, vox);
            v[i] = wvol_store_eval(st, vox, gr);
            for (int a = 0; a < 3; a++) g[3 * i + a] = gr[a] / in.spacing[a]; /* voxel -> world units */
        }
        Py_END_ALLOW_THREADS
    }
    Py_DECREF(pts);
    return Py_BuildValue("NN", vals, grads);
}

PyMethodDef wvolpy_store_methods[] = {
    {"store_build", (PyCFunction)(void (*)(void))py_store_build, METH_VARARGS | METH_KEYWORDS,
     "store_build(coeffs, wavelet, levels, shape, spacing=None, origin=None, spline_j=0) -> store capsule"},
    {"store_info", py_store_info, METH_O, "store_info(store) -> dict"},
    {"store_eval", py_store_eval, METH_VARARGS, "store_eval(store, points) -> (values, gradients)"},
    {NULL, NULL, 0, NULL}};
