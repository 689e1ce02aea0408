/* SPDX-License-Identifier: MIT */
/* load / save of volume files. */
#include "pyutil.h"
#include "methods.h"

static PyObject *py_load(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "dims", "dtype", "grid", "big_endian", "spacing", "origin", NULL};
    PyObject *path_obj, *dims_obj = Py_None, *spacing_obj = Py_None, *origin_obj = Py_None, *bytes = NULL, *arr, *res;
    const char *dtype = "float32", *grid = NULL;
    int big_endian = 0;
    wvol_load_options lo;
    wvol_volume *v = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|OszpOO", kwlist, &path_obj, &dims_obj, &dtype, &grid,
                                     &big_endian, &spacing_obj, &origin_obj))
        return NULL;
    if (!PyUnicode_FSConverter(path_obj, &bytes)) return NULL;
    wvol_load_options_default(&lo);
    if (dims_obj != Py_None) {
        /* dims given in (x, y, z) order, like the command line */
        double d[3];
        if (wvolpy_triple(dims_obj, d, "dims") < 0) goto fail;
        for (int a = 0; a < 3; a++) {
            if (!(d[a] >= 1 && d[a] <= 9.2e18) || d[a] != (double)(size_t)d[a]) {
                PyErr_SetString(PyExc_ValueError, "dims: each dimension must be a positive integer");
                goto fail;
            }
            lo.dims[a] = (size_t)d[a];
        }
    }
    {
        int t = wvol_sample_type_parse(dtype);
        if (t < 0) {
            PyErr_Format(PyExc_ValueError, "unknown sample type '%s'", dtype);
            goto fail;
        }
        lo.raw_type = (wvol_sample_type)t;
    }
    lo.big_endian = big_endian;
    lo.grid_name = grid;
    /* a raw file's place in the world (the other formats carry their own, as on the command line);
     * the file's source refuses a spacing or origin that is not a place */
    if (wvolpy_triple(spacing_obj, lo.spacing, "spacing") < 0 || wvolpy_triple(origin_obj, lo.origin, "origin") < 0)
        goto fail;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_volume_load(&v, PyBytes_AS_STRING(bytes), &lo, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) {
        wvolpy_raise(&err);
        goto fail;
    }
    arr = wvolpy_volume_to_array(v, 0);
    res = arr ? Py_BuildValue("N(ddd)(ddd)", arr, v->spacing[0], v->spacing[1], v->spacing[2], v->origin[0],
                              v->origin[1], v->origin[2])
              : NULL;
    wvol_volume_destroy(v);
    Py_DECREF(bytes);
    return res;
fail:
    Py_XDECREF(bytes);
    return NULL;
}

static PyObject *py_save(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"array", "path", "spacing", "origin", NULL};
    PyObject *arr_obj, *path_obj, *sp = Py_None, *org = Py_None, *bytes = NULL;
    PyArrayObject *holder = NULL;
    wvol_volume v;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|OO", kwlist, &arr_obj, &path_obj, &sp, &org)) return NULL;
    if (wvolpy_as_placed_volume(arr_obj, sp, org, &v, &holder, 1) < 0) return NULL;
    if (wvol_volume_set_geometry(&v, v.spacing, v.origin, &err) != WVOL_OK) {
        wvolpy_raise(&err);
        goto fail;
    }
    if (!PyUnicode_FSConverter(path_obj, &bytes)) goto fail;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_volume_save(&v, PyBytes_AS_STRING(bytes), &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(bytes);
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    Py_RETURN_NONE;
fail:
    Py_XDECREF(holder);
    return NULL;
}

PyMethodDef wvolpy_io_methods[] = {
    {"load", (PyCFunction)(void (*)(void))py_load, METH_VARARGS | METH_KEYWORDS,
     "load(path, dims=None, dtype='float32', grid=None, big_endian=False) -> (array, spacing, origin)"},
    {"save", (PyCFunction)(void (*)(void))py_save, METH_VARARGS | METH_KEYWORDS,
     "save(array, path, spacing=None, origin=None)"},
    {NULL, NULL, 0, NULL}};
