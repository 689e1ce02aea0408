/* filters, dwt3, idwt3. */
#include "pyutil.h"
#include "methods.h"

#include <string.h>

static PyObject *py_filters(PyObject *self, PyObject *noargs)
{
    PyObject *list = PyList_New(0);
    (void)self;
    (void)noargs;
    if (!list) return NULL;
    for (int i = 0; i < wvol_filter_count(); i++) {
        const wvol_filter *f = wvol_filter_at(i);
        PyObject *h = PyList_New(f->length), *d;
        if (!h) goto fail;
        for (int k = 0; k < f->length; k++) PyList_SET_ITEM(h, k, PyFloat_FromDouble(f->h[k]));
        d = Py_BuildValue("{s:s,s:i,s:i,s:N,s:i,s:d,s:d}", "name", f->name, "order", f->order, "taps",
                          f->length, "h", h, "vanishing_moments", f->vanishing_moments, "defect", f->defect,
                          "center", f->center);
        if (!d || PyList_Append(list, d) < 0) {
            Py_XDECREF(d);
            goto fail;
        }
        Py_DECREF(d);
    }
    return list;
fail:
    Py_DECREF(list);
    return NULL;
}

static PyObject *py_dwt3(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"array", "wavelet", "levels", "spacing", "origin", NULL};
    PyObject *arr_obj, *out, *sp = Py_None, *org = Py_None;
    const char *name = "db2";
    int levels = 3;
    PyArrayObject *holder;
    wvol_volume v;
    const wvol_filter *f;
    wvol_coeffs *c = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|siOO", kwlist, &arr_obj, &name, &levels, &sp, &org))
        return NULL;
    if (wvol_filter_get(&f, name, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (wvolpy_as_placed_volume(arr_obj, sp, org, &v, &holder, 0) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_volume_set_geometry(&v, v.spacing, v.origin, &err);
    if (s == WVOL_OK) s = wvol_dwt3(&c, &v, f, levels, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    {
        npy_intp dims[3] = {(npy_intp)c->pz, (npy_intp)c->py, (npy_intp)c->px};
        out = wvolpy_array_take(c->data, 3, dims); /* the coefficients are handed over, no copy */
        c->data = NULL;
    }
    if (out)
        out = Py_BuildValue("N{s:s,s:i,s:(nnn),s:(nnn)}", out, "wavelet", f->name, "levels", c->levels,
                            "shape", (Py_ssize_t)c->nz, (Py_ssize_t)c->ny, (Py_ssize_t)c->nx, "padded",
                            (Py_ssize_t)c->pz, (Py_ssize_t)c->py, (Py_ssize_t)c->px);
    wvol_coeffs_destroy(c);
    return out;
}

static PyObject *py_idwt3(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"coeffs", "wavelet", "levels", "shape", NULL};
    PyObject *arr_obj, *shape;
    const char *name;
    int levels;
    PyArrayObject *holder;
    wvol_coeffs c;
    wvol_volume *rec = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OsiO", kwlist, &arr_obj, &name, &levels, &shape)) return NULL;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, NULL, NULL, &c, &holder) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_idwt3(&rec, &c, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    return wvolpy_volume_take(rec, 0);
}

/* Coarser level: returns (array, spacing, origin). */
static PyObject *py_idwt3_level(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"coeffs", "wavelet", "levels", "shape", "stop_level", "spacing", "origin", NULL};
    PyObject *arr_obj, *shape, *sp = Py_None, *org = Py_None, *a;
    const char *name;
    int levels, stop;
    PyArrayObject *holder;
    wvol_coeffs c;
    wvol_volume *rec = NULL;
    wvol_error err;
    wvol_status s;
    double spv[3], orv[3];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OsiOi|OO", kwlist, &arr_obj, &name, &levels, &shape, &stop, &sp,
                                     &org))
        return NULL;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, sp, org, &c, &holder) < 0) return NULL;
    if (stop < 0 || stop > levels) {
        Py_DECREF(holder);
        return PyErr_Format(PyExc_ValueError, "level must be in 0..%d (the transform's levels), got %d", levels,
                            stop);
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_idwt3_level(&rec, &c, stop, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    memcpy(spv, rec->spacing, sizeof spv);
    memcpy(orv, rec->origin, sizeof orv);
    a = wvolpy_volume_take(rec, 0);
    if (!a) return NULL;
    return Py_BuildValue("N(ddd)(ddd)", a, spv[0], spv[1], spv[2], orv[0], orv[1], orv[2]);
}

/* One brick [lo, hi) given in (x, y, z) voxel indices; returns (array, origin). */
static PyObject *py_idwt3_brick(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"coeffs", "wavelet", "levels", "shape", "lo", "hi", "spacing", "origin", NULL};
    PyObject *arr_obj, *shape, *sp = Py_None, *org = Py_None, *a;
    const char *name;
    int levels;
    Py_ssize_t lo_[3], hi_[3];
    size_t lo[3], hi[3];
    PyArrayObject *holder;
    wvol_coeffs c;
    wvol_volume *rec = NULL;
    wvol_error err;
    wvol_status s;
    double orv[3];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OsiO(nnn)(nnn)|OO", kwlist, &arr_obj, &name, &levels, &shape,
                                     &lo_[0], &lo_[1], &lo_[2], &hi_[0], &hi_[1], &hi_[2], &sp, &org))
        return NULL;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, sp, org, &c, &holder) < 0) return NULL;
    {
        size_t n[3] = {c.nx, c.ny, c.nz};
        for (int ax = 0; ax < 3; ax++) {
            if (lo_[ax] < 0 || hi_[ax] <= lo_[ax] || (size_t)hi_[ax] > n[ax]) {
                Py_DECREF(holder);
                return PyErr_Format(PyExc_ValueError,
                                    "box: axis %c range [%zd, %zd) must be non-empty and inside [0, %zu)",
                                    "xyz"[ax], lo_[ax], hi_[ax], n[ax]);
            }
            lo[ax] = (size_t)lo_[ax];
            hi[ax] = (size_t)hi_[ax];
        }
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_idwt3_brick(&rec, &c, lo, hi, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    memcpy(orv, rec->origin, sizeof orv);
    a = wvolpy_volume_take(rec, 0);
    if (!a) return NULL;
    return Py_BuildValue("N(ddd)", a, orv[0], orv[1], orv[2]);
}

PyMethodDef wvolpy_wavelet_methods[] = {
    {"filters", py_filters, METH_NOARGS, "filters() -> list of dicts"},
    {"dwt3", (PyCFunction)(void (*)(void))py_dwt3, METH_VARARGS | METH_KEYWORDS,
     "dwt3(array, wavelet='db2', levels=3, spacing=None, origin=None) -> (coeffs, info)"},
    {"idwt3", (PyCFunction)(void (*)(void))py_idwt3, METH_VARARGS | METH_KEYWORDS,
     "idwt3(coeffs, wavelet, levels, shape) -> array"},
    {"idwt3_level", (PyCFunction)(void (*)(void))py_idwt3_level, METH_VARARGS | METH_KEYWORDS,
     "idwt3_level(coeffs, wavelet, levels, shape, stop_level, spacing=None, origin=None) -> (array, spacing, origin)"},
    {"idwt3_brick", (PyCFunction)(void (*)(void))py_idwt3_brick, METH_VARARGS | METH_KEYWORDS,
     "idwt3_brick(coeffs, wavelet, levels, shape, lo_xyz, hi_xyz, spacing=None, origin=None) -> (array, origin)"},
    {NULL, NULL, 0, NULL}};
