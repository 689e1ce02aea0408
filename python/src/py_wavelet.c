/* filters, dwt3, idwt3. */
#include "pyutil.h"
#include "methods.h"

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
    static char *kwlist[] = {"array", "wavelet", "levels", NULL};
    PyObject *arr_obj, *out;
    const char *name = "db2";
    int levels = 3;
    PyArrayObject *holder;
    wvol_volume v;
    const wvol_filter *f;
    wvol_coeffs *c = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|si", kwlist, &arr_obj, &name, &levels)) return NULL;
    if (wvol_filter_get(&f, name, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (wvolpy_as_volume(arr_obj, &v, &holder, 0) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_dwt3(&c, &v, f, levels, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    {
        wvol_volume pv = {c->px, c->py, c->pz, {1, 1, 1}, {0, 0, 0}, c->data, 0};
        out = wvolpy_volume_to_array(&pv, 0);
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
    PyObject *arr_obj, *out;
    const char *name = "db2";
    int levels = 3;
    Py_ssize_t sz = 0, sy = 0, sx = 0;
    PyArrayObject *holder;
    wvol_volume v;
    wvol_coeffs c;
    wvol_volume *rec = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Osi(nnn)", kwlist, &arr_obj, &name, &levels, &sz, &sy, &sx))
        return NULL;
    memset(&c, 0, sizeof c);
    if (wvol_filter_get(&c.filter, name, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (wvolpy_as_volume(arr_obj, &v, &holder, 1) < 0) return NULL;
    if (sx < 1 || sy < 1 || sz < 1 || (size_t)sx > v.nx || (size_t)sy > v.ny || (size_t)sz > v.nz) {
        Py_DECREF(holder);
        return PyErr_Format(PyExc_ValueError, "shape (%zd, %zd, %zd) must be positive and fit in the padded (%zu, %zu, %zu)",
                            sz, sy, sx, v.nz, v.ny, v.nx);
    }
    c.levels = levels;
    c.nx = (size_t)sx; c.ny = (size_t)sy; c.nz = (size_t)sz;
    c.px = v.nx; c.py = v.ny; c.pz = v.nz;
    c.spacing[0] = c.spacing[1] = c.spacing[2] = 1;
    c.data = v.data;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_idwt3(&rec, &c, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    out = wvolpy_volume_to_array(rec, 0);
    wvol_volume_destroy(rec);
    return out;
}

PyMethodDef wvolpy_wavelet_methods[] = {
    {"filters", py_filters, METH_NOARGS, "filters() -> list of dicts"},
    {"dwt3", (PyCFunction)(void (*)(void))py_dwt3, METH_VARARGS | METH_KEYWORDS,
     "dwt3(array, wavelet='db2', levels=3) -> (coeffs, info)"},
    {"idwt3", (PyCFunction)(void (*)(void))py_idwt3, METH_VARARGS | METH_KEYWORDS,
     "idwt3(coeffs, wavelet, levels, shape) -> array"},
    {NULL, NULL, 0, NULL}};
