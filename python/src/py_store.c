/* SPDX-License-Identifier: MIT */
/* wvol._wvol.StoreHandle: the object behind wvol.Store (py_store.h). It owns the library's
 * wvol_compressed and frees it when it dies; its methods read it in place: the coefficient
 * array (a read-only view), the C store's numbers and f^, reconstructions (whole, coarser
 * level, one brick) and the .wvc encoder with the pipeline's quantiser rule. */
#include "pyutil.h"
#include "methods.h"
#include "py_store.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_J 12

static void store_dealloc(PyObject *self)
{
    wvolpy_store *h = (wvolpy_store *)self;
    wvol_compressed_free(&h->c);
    for (int j = 0; j <= MAX_J; j++) wvol_store_destroy(h->by_J[j]);
    Py_TYPE(self)->tp_free(self);
}

PyObject *wvolpy_store_wrap(wvol_compressed *c)
{
    wvolpy_store *h = PyObject_New(wvolpy_store, &wvolpy_store_type);
    if (!h) {
        wvol_compressed_free(c);
        return NULL;
    }
    h->c = *c;
    memset(c, 0, sizeof *c);
    memset(h->by_J, 0, sizeof h->by_J);
    return (PyObject *)h;
}

PyObject *wvolpy_store_with(wvol_compressed *c, PyObject *d)
{
    PyObject *h;
    if (!d) {
        wvol_compressed_free(c);
        return NULL;
    }
    if (!(h = wvolpy_store_wrap(c))) {
        Py_DECREF(d);
        return NULL;
    }
    return Py_BuildValue("NN", h, d);
}

const wvol_store *wvolpy_store_at(wvolpy_store *h, int J)
{
    wvol_compress_params p;
    wvol_store *st = NULL;
    const wvol_selection *sel;
    wvol_error err;
    wvol_status s;
    if (J < 0 || J > MAX_J) {
        PyErr_Format(PyExc_ValueError, "spline_j must be in 0..%d (0: default), got %d", MAX_J, J);
        return NULL;
    }
    if (J == 0 || J == wvol_store_basis(h->c.store)->J) return h->c.store;
    if (h->by_J[J]) return h->by_J[J];
    /* the pipeline's store, at another J: its parameters, its kept set */
    wvol_compress_params_default(&p);
    p.store.spline_J = J;
    sel = h->c.report.kept < h->c.report.total ? h->c.selection : NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_store_build(&st, h->c.coeffs, sel, &p.store, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) {
        wvolpy_raise(&err);
        return NULL;
    }
    if (h->by_J[J]) wvol_store_destroy(st); /* another thread built it meanwhile */
    else h->by_J[J] = st;
    return h->by_J[J];
}

/* ---- attributes ---- */

static PyObject *get_coeffs(PyObject *self, void *closure)
{
    const wvol_coeffs *c = ((wvolpy_store *)self)->c.coeffs;
    npy_intp dims[3] = {(npy_intp)c->pz, (npy_intp)c->py, (npy_intp)c->px};
    PyObject *a;
    (void)closure;
    a = PyArray_New(&PyArray_Type, 3, dims, NPY_FLOAT32, NULL, c->data, 0, NPY_ARRAY_CARRAY_RO, NULL);
    if (!a) return NULL;
    Py_INCREF(self);
    if (PyArray_SetBaseObject((PyArrayObject *)a, self) < 0) { /* steals the reference */
        Py_DECREF(a);
        return NULL;
    }
    return a;
}

static PyObject *get_meta(PyObject *self, void *closure)
{
    const wvolpy_store *h = (wvolpy_store *)self;
    const wvol_coeffs *c = h->c.coeffs;
    (void)closure;
    return Py_BuildValue("{s:s,s:i,s:(nnn),s:(ddd),s:(ddd),s:(dd),s:d}", "wavelet", c->filter->name, "levels",
                         c->levels, "shape", (Py_ssize_t)c->nz, (Py_ssize_t)c->ny, (Py_ssize_t)c->nx, "spacing",
                         c->spacing[0], c->spacing[1], c->spacing[2], "origin", c->origin[0], c->origin[1],
                         c->origin[2], "value_range", h->c.value_min, h->c.value_max, "energy_dropped",
                         h->c.report.energy_dropped);
}

static PyGetSetDef store_getset[] = {
    {"coeffs", get_coeffs, NULL, "the coefficients (padded Mallat array, (z, y, x), dropped ones zero): a "
                                 "read-only view", NULL},
    {"meta", get_meta, NULL, "dict: wavelet, levels, shape (z, y, x), spacing, origin, value_range, "
                             "energy_dropped", NULL},
    {NULL, NULL, NULL, NULL, NULL}};

/* ---- the C store ---- */

static PyObject *store_info(PyObject *self, PyObject *noargs)
{
    const wvol_store *st = ((wvolpy_store *)self)->c.store;
    wvol_store_info in;
    (void)noargs;
    wvol_store_get_info(st, &in);
    return Py_BuildValue("{s:s,s:i,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:n}", "wavelet", in.filter->name, "levels",
                         in.levels, "kept", (Py_ssize_t)in.kept, "kept_lowpass", (Py_ssize_t)in.kept_lowpass, "nodes",
                         (Py_ssize_t)in.nodes, "roots", (Py_ssize_t)in.roots, "hash_slots", (Py_ssize_t)in.hash_slots,
                         "bytes", (Py_ssize_t)in.bytes, "basis_bytes", (Py_ssize_t)in.basis_bytes, "bytes_per_coeff",
                         in.bytes_per_coeff, "spline_j", (Py_ssize_t)wvol_store_basis(st)->J);
}

/* evaluate(points (n, 3) in world (x, y, z)) -> (values (n,), gradients (n, 3) world units) */
static PyObject *store_evaluate(PyObject *self, PyObject *pts_obj)
{
    const wvol_store *st = ((wvolpy_store *)self)->c.store;
    PyObject *vals, *grads;
    PyArrayObject *pts;
    wvol_store_info in;
    npy_intp n;
    {
        PyArrayObject *in = (PyArrayObject *)PyArray_FROM_O(pts_obj);
        if (!in) return NULL;
        if (!(PyArray_ISFLOAT(in) || PyArray_ISINTEGER(in)) || PyArray_ISCOMPLEX(in)) {
            PyErr_Format(PyExc_TypeError, "points must be real numbers, got dtype %S", (PyObject *)PyArray_DESCR(in));
            Py_DECREF(in);
            return NULL;
        }
        pts = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)in, NPY_FLOAT64, NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
        Py_DECREF(in);
    }
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

/* ---- reconstructions ---- */

/* reconstruct(level=0) -> (array, spacing, origin): the whole volume, or the coarser level. */
static PyObject *store_reconstruct(PyObject *self, PyObject *args)
{
    const wvol_coeffs *c = ((wvolpy_store *)self)->c.coeffs;
    int stop = 0;
    wvol_volume *rec = NULL;
    wvol_error err;
    wvol_status s;
    double sp[3], org[3];
    PyObject *a;
    if (!PyArg_ParseTuple(args, "|i", &stop)) return NULL;
    if (stop < 0 || stop > c->levels)
        return PyErr_Format(PyExc_ValueError, "level must be in 0..%d (the transform's levels), got %d", c->levels,
                            stop);
    Py_BEGIN_ALLOW_THREADS
    s = stop == 0 ? wvol_idwt3(&rec, c, &err) : wvol_idwt3_level(&rec, c, stop, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) return wvolpy_raise(&err);
    memcpy(sp, rec->spacing, sizeof sp);
    memcpy(org, rec->origin, sizeof org);
    if (!(a = wvolpy_volume_take(rec, 0))) return NULL;
    return Py_BuildValue("N(ddd)(ddd)", a, sp[0], sp[1], sp[2], org[0], org[1], org[2]);
}

/* reconstruct_box(lo, hi) with [lo, hi) in (x, y, z) voxel indices -> (array, origin) */
static PyObject *store_reconstruct_box(PyObject *self, PyObject *args)
{
    const wvol_coeffs *c = ((wvolpy_store *)self)->c.coeffs;
    Py_ssize_t lo_[3], hi_[3];
    size_t lo[3], hi[3], n[3] = {c->nx, c->ny, c->nz};
    wvol_volume *rec = NULL;
    wvol_error err;
    wvol_status s;
    double org[3];
    PyObject *a;
    if (!PyArg_ParseTuple(args, "(nnn)(nnn)", &lo_[0], &lo_[1], &lo_[2], &hi_[0], &hi_[1], &hi_[2])) return NULL;
    for (int ax = 0; ax < 3; ax++) {
        if (lo_[ax] < 0 || hi_[ax] <= lo_[ax] || (size_t)hi_[ax] > n[ax])
            return PyErr_Format(PyExc_ValueError, "box: axis %c range [%zd, %zd) must be non-empty and inside [0, %zu)",
                                "xyz"[ax], lo_[ax], hi_[ax], n[ax]);
        lo[ax] = (size_t)lo_[ax];
        hi[ax] = (size_t)hi_[ax];
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_idwt3_brick(&rec, c, lo, hi, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) return wvolpy_raise(&err);
    memcpy(org, rec->origin, sizeof org);
    if (!(a = wvolpy_volume_take(rec, 0))) return NULL;
    return Py_BuildValue("N(ddd)", a, org[0], org[1], org[2]);
}

/* ---- .wvc ---- */

/* save(path, quant_share=None, step=None) -> report: wvol_compress_encode, i.e. the
 * pipeline's quantiser rule (a share of the dropped energy, at least what 120 dB allows) or
 * the step given; None leaves the library's default. */
static PyObject *store_save(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "quant_share", "step", NULL};
    wvolpy_store *h = (wvolpy_store *)self;
    PyObject *path_obj, *share_obj = Py_None, *step_obj = Py_None, *bytes = NULL;
    wvol_compress_params p;
    wvol_wvc_report rep;
    void *buf = NULL;
    size_t nbytes = 0;
    wvol_error err;
    wvol_status s;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|OO", kwlist, &path_obj, &share_obj, &step_obj)) return NULL;
    wvol_compress_params_default(&p);
    if (step_obj != Py_None) {
        p.quant.step = PyFloat_AsDouble(step_obj);
        if (PyErr_Occurred()) return NULL;
        if (!(p.quant.step > 0) || !isfinite(p.quant.step))
            return wvolpy_value_error("step must be finite and > 0, got %g", p.quant.step);
    } else if (share_obj != Py_None) {
        p.quant.share = PyFloat_AsDouble(share_obj);
        if (PyErr_Occurred()) return NULL;
        if (!(p.quant.share > 0 && p.quant.share <= 1))
            return wvolpy_value_error("quant_share must be in (0, 1], got %g", p.quant.share);
    }
    if (!PyUnicode_FSConverter(path_obj, &bytes)) return NULL;
    if (!wvol_path_has_ext(PyBytes_AS_STRING(bytes), ".wvc")) {
        /* every reader goes by the extension: a .wvc named x.nrrd could not be read back */
        PyObject *e = wvolpy_value_error("save: the path must end in .wvc (the format follows the extension), got '%s'",
                                         PyBytes_AS_STRING(bytes));
        Py_DECREF(bytes);
        return e;
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_compress_encode(&buf, &nbytes, &h->c, &p, &rep, &err);
    if (s == WVOL_OK) s = wvol_wvc_save(PyBytes_AS_STRING(bytes), buf, nbytes, &err);
    Py_END_ALLOW_THREADS
    free(buf);
    Py_DECREF(bytes);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    return Py_BuildValue("{s:d,s:d,s:K,s:K,s:n}", "step", rep.step, "sse_quant", rep.sse_quant, "nonzero",
                         (unsigned long long)rep.nonzero, "coefficients", (unsigned long long)rep.coefficients,
                         "bytes", (Py_ssize_t)rep.bytes);
}

/* replace_coeffs(array) -> a new handle over a copy of array (same grid, wavelet, levels,
 * geometry, data range and dropped energy; every nonzero coefficient kept). */
static PyObject *store_replace_coeffs(PyObject *self, PyObject *arr)
{
    const wvolpy_store *h = (wvolpy_store *)self;
    const wvol_coeffs *old = h->c.coeffs;
    PyObject *shape;
    PyArrayObject *holder;
    wvol_coeffs view, *copy = NULL;
    wvol_compressed out;
    wvol_compress_params p;
    wvol_error err;
    wvol_status s;
    int rc;
    if (!(shape = Py_BuildValue("(nnn)", (Py_ssize_t)old->nz, (Py_ssize_t)old->ny, (Py_ssize_t)old->nx))) return NULL;
    rc = wvolpy_as_coeffs(arr, old->filter->name, old->levels, shape, NULL, NULL, &view, &holder, 1);
    Py_DECREF(shape);
    if (rc < 0) return NULL;
    memcpy(view.spacing, old->spacing, sizeof view.spacing);
    memcpy(view.origin, old->origin, sizeof view.origin);
    wvol_compress_params_default(&p);
    Py_BEGIN_ALLOW_THREADS
    s = wvol_coeffs_clone(&copy, &view, &err);
    if (s == WVOL_OK) s = wvol_compress_coeffs(&out, &copy, &p, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    out.value_min = h->c.value_min;
    out.value_max = h->c.value_max;
    out.report.energy_dropped = h->c.report.energy_dropped;
    return wvolpy_store_wrap(&out);
}

static PyMethodDef store_methods[] = {
    {"info", store_info, METH_NOARGS, "info() -> dict of the C store's numbers"},
    {"evaluate", store_evaluate, METH_O, "evaluate(points) -> (values, gradients) of f^ at world points"},
    {"reconstruct", store_reconstruct, METH_VARARGS, "reconstruct(level=0) -> (array, spacing, origin)"},
    {"reconstruct_box", store_reconstruct_box, METH_VARARGS, "reconstruct_box(lo_xyz, hi_xyz) -> (array, origin)"},
    {"save", (PyCFunction)(void (*)(void))store_save, METH_VARARGS | METH_KEYWORDS,
     "save(path, quant_share=None, step=None) -> report"},
    {"replace_coeffs", store_replace_coeffs, METH_O, "replace_coeffs(array) -> a new handle over a copy"},
    {NULL, NULL, 0, NULL}};

PyTypeObject wvolpy_store_type = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "wvol._wvol.StoreHandle",
    .tp_basicsize = sizeof(wvolpy_store),
    .tp_dealloc = store_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "What the library's compression pipeline made (coefficients, selection, C store); "
              "made by compress and store_open, held by wvol.Store.",
    .tp_methods = store_methods,
    .tp_getset = store_getset,
};

int wvolpy_store_ready(PyObject *module)
{
    if (PyType_Ready(&wvolpy_store_type) < 0) return -1;
    Py_INCREF(&wvolpy_store_type);
    if (PyModule_AddObject(module, "StoreHandle", (PyObject *)&wvolpy_store_type) < 0) {
        Py_DECREF(&wvolpy_store_type);
        return -1;
    }
    return 0;
}
