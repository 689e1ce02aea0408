/* SPDX-License-Identifier: MIT */
/* The segmentation pipeline of wvol/analysis.h: wavelet features -> PCA -> 3D Kohonen map
 * -> labels and colours (optionally mapped to ground-truth classes and scored). */
#include "pyutil.h"
#include "methods.h"

#include <math.h>
#include <string.h>

/* A private int32 (or bool/uint8 when as_mask) C array of exactly v's shape, or NULL with an
 * exception. None gives NULL without an exception (*none set). */
static PyArrayObject *label_array(PyObject *obj, const wvol_volume *v, int as_mask, const char *what, int *none)
{
    PyArrayObject *a;
    int nd;
    npy_intp *d;
    *none = obj == Py_None;
    if (*none) return NULL;
    {
        /* class ids are integers (a mask also bool): a float is not truncated, an int64 beyond
         * int32 not wrapped */
        PyArrayObject *in = (PyArrayObject *)PyArray_FROM_O(obj);
        if (!in) return NULL;
        if (!(PyArray_ISINTEGER(in) || (as_mask && PyArray_ISBOOL(in)))) {
            PyErr_Format(PyExc_TypeError, "%s must be an array of %s, got dtype %S", what,
                         as_mask ? "bools or integers" : "integer class ids", (PyObject *)PyArray_DESCR(in));
            Py_DECREF(in);
            return NULL;
        }
        if (!as_mask && PyArray_SIZE(in) > 0) {
            /* each step only after the one before succeeded: no NumPy call with an error pending */
            PyObject *mx = PyArray_Max(in, NPY_MAXDIMS, NULL), *mn = mx ? PyArray_Min(in, NPY_MAXDIMS, NULL) : NULL;
            long long hi = mn ? PyLong_AsLongLong(mx) : 0, lo = 0;
            int fits = 0;
            if (mn && !PyErr_Occurred()) lo = PyLong_AsLongLong(mn);
            Py_XDECREF(mx);
            Py_XDECREF(mn);
            if (mn && !PyErr_Occurred()) fits = hi <= INT32_MAX && lo >= INT32_MIN;
            else if (mn && PyErr_ExceptionMatches(PyExc_OverflowError)) PyErr_Clear(); /* beyond 64 bits */
            if (!fits) {
                /* a failure of its own (out of memory) stays the error; a range is named */
                if (!PyErr_Occurred()) PyErr_Format(PyExc_ValueError, "%s: class ids must fit int32", what);
                Py_DECREF(in);
                return NULL;
            }
        }
        /* always a copy: the C side checks the ids in one pass and indexes its tables with them
         * in another, with the GIL released, so an id another thread wrote in between would
         * index past a table */
        a = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)in, as_mask ? NPY_UINT8 : NPY_INT32,
                                              NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST | NPY_ARRAY_ENSURECOPY);
        Py_DECREF(in);
    }
    if (!a) return NULL;
    nd = PyArray_NDIM(a);
    d = PyArray_DIMS(a);
    if (!((nd == 3 && (size_t)d[0] == v->nz && (size_t)d[1] == v->ny && (size_t)d[2] == v->nx) ||
          (nd == 2 && v->nz == 1 && (size_t)d[0] == v->ny && (size_t)d[1] == v->nx))) {
        PyErr_Format(PyExc_ValueError, "%s must have the volume's shape (%zu, %zu, %zu)", what, v->nz, v->ny, v->nx);
        Py_DECREF(a);
        return NULL;
    }
    return a;
}

static PyObject *int_array(int32_t *data, const wvol_volume *v)
{
    npy_intp dims[3] = {(npy_intp)v->nz, (npy_intp)v->ny, (npy_intp)v->nx};
    PyObject *a = PyArray_SimpleNew(3, dims, NPY_INT32);
    if (a) memcpy(PyArray_DATA((PyArrayObject *)a), data, wvol_volume_count(v) * sizeof(int32_t));
    return a;
}

static PyObject *py_segment(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"array", "wavelet", "levels", "smooth", "include_lowpass", "variance", "som",
                             "iterations", "seed", "truth", "train_mask", "boundary", NULL};
    PyObject *arr_obj, *truth_obj = Py_None, *mask_obj = Py_None, *res = NULL, *seed_obj = NULL;
    const char *name = "db2";
    int levels = 3, smooth = 1, lowpass = 1, boundary = -1, none;
    int sd[3] = {4, 4, 4};
    long iters = 20000;
    double variance = 1.0;
    PyArrayObject *holder = NULL, *truth_a = NULL, *mask_a = NULL;
    wvol_volume v;
    const wvol_filter *f;
    wvol_feature_params fp;
    wvol_som_params sp;
    wvol_features *feat = NULL;
    wvol_som *som = NULL;
    int32_t *labels = NULL, *classes = NULL;
    float *rgb = NULL;
    wvol_seg_score score = {0, 0, 0};
    wvol_error err;
    wvol_status s = WVOL_OK;
    int raw_features = 0;
    size_t n;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|siipd(iii)lOOOi", kwlist, &arr_obj, &name, &levels, &smooth,
                                     &lowpass, &variance, &sd[0], &sd[1], &sd[2], &iters, &seed_obj, &truth_obj,
                                     &mask_obj, &boundary))
        return NULL;
    wvol_feature_params_default(&fp);
    wvol_som_params_default(&sp);
    fp.levels = levels;
    fp.smooth = smooth;
    fp.include_lowpass = lowpass;
    for (int a = 0; a < 3; a++) sp.dims[a] = sd[a];
    sp.iterations = iters;
    if (wvolpy_seed(seed_obj, &sp.seed) < 0) return NULL;
    if (!(variance > 0 && variance <= 1))
        return wvolpy_value_error("variance must be in (0, 1], got %g", variance);
    if (wvol_filter_get(&f, name, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (wvolpy_as_volume(arr_obj, &v, &holder, 1) < 0) return NULL;
    n = wvol_volume_count(&v);
    truth_a = label_array(truth_obj, &v, 0, "truth", &none);
    if (!truth_a && !none) goto done;
    mask_a = label_array(mask_obj, &v, 1, "train_mask", &none);
    if (!mask_a && !none) goto done;
    if (mask_a && !truth_a) {
        PyErr_SetString(PyExc_ValueError, "train_mask needs truth");
        goto done;
    }
    labels = PyMem_Malloc(n * sizeof *labels);
    classes = truth_a ? PyMem_Malloc(n * sizeof *classes) : NULL;
    rgb = PyMem_Malloc(3 * n * sizeof *rgb);
    if (!labels || !rgb || (truth_a && !classes)) {
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_features_compute(&feat, &v, f, &fp, &err);
    if (s == WVOL_OK) {
        raw_features = feat->count;
        s = wvol_features_pca(feat, variance, NULL, &err);
    }
    if (s == WVOL_OK) s = wvol_som_train(&som, feat, &sp, &err);
    if (s == WVOL_OK) s = wvol_som_classify(labels, rgb, som, feat, &err);
    if (s == WVOL_OK && truth_a) {
        s = wvol_som_label(som, feat, PyArray_DATA(truth_a), mask_a ? PyArray_DATA(mask_a) : NULL, &err);
        if (s == WVOL_OK) {
            int rad = boundary >= 0 ? boundary : 1 << fp.levels;
            wvol_som_apply_classes(classes, labels, n, som);
            s = wvol_segmentation_score(&score, classes, PyArray_DATA(truth_a), v.nx, v.ny, v.nz, rad, &err);
        }
    }
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) {
        wvolpy_raise(&err);
        goto done;
    }
    {
        npy_intp cd[4] = {(npy_intp)v.nz, (npy_intp)v.ny, (npy_intp)v.nx, 3};
        PyObject *lab = int_array(labels, &v), *cls = classes ? int_array(classes, &v) : Py_NewRef(Py_None);
        PyObject *col = PyArray_SimpleNew(4, cd, NPY_FLOAT32), *sc;
        if (col) memcpy(PyArray_DATA((PyArrayObject *)col), rgb, 3 * n * sizeof(float));
        sc = truth_a ? Py_BuildValue("{s:d,s:d,s:n}", "error_all", score.error_all, "error_interior",
                                     score.error_interior, "interior", (Py_ssize_t)score.interior)
                     : Py_NewRef(Py_None);
        if (lab && cls && col && sc)
            res = Py_BuildValue("{s:N,s:N,s:N,s:N,s:i,s:i,s:i}", "labels", lab, "colors", col, "classes", cls,
                                "score", sc, "features", raw_features, "components", feat->count, "neurons",
                                som->neurons);
        else {
            Py_XDECREF(lab);
            Py_XDECREF(cls);
            Py_XDECREF(col);
            Py_XDECREF(sc);
        }
    }
done:
    Py_XDECREF(holder);
    Py_XDECREF(truth_a);
    Py_XDECREF(mask_a);
    PyMem_Free(labels);
    PyMem_Free(classes);
    PyMem_Free(rgb);
    wvol_features_destroy(feat);
    wvol_som_destroy(som);
    return res;
}

/* features(array, wavelet, levels, smooth, include_lowpass, variance or None) -> (count, z, y, x) */
static PyObject *py_features(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"array", "wavelet", "levels", "smooth", "include_lowpass", "variance", NULL};
    PyObject *arr_obj, *var_obj = Py_None, *res;
    const char *name = "db2";
    int levels = 3, smooth = 1, lowpass = 1;
    double variance = 0;
    PyArrayObject *holder;
    wvol_volume v;
    const wvol_filter *f;
    wvol_feature_params fp;
    wvol_features *feat = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|siipO", kwlist, &arr_obj, &name, &levels, &smooth, &lowpass,
                                     &var_obj))
        return NULL;
    if (var_obj != Py_None) {
        variance = PyFloat_AsDouble(var_obj);
        if (PyErr_Occurred()) return NULL;
        if (!(variance > 0 && variance <= 1))
            return wvolpy_value_error("variance must be in (0, 1], got %g", variance);
    }
    wvol_feature_params_default(&fp);
    fp.levels = levels;
    fp.smooth = smooth;
    fp.include_lowpass = lowpass;
    if (wvol_filter_get(&f, name, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (wvolpy_as_volume(arr_obj, &v, &holder, 1) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_features_compute(&feat, &v, f, &fp, &err);
    if (s == WVOL_OK && variance > 0) s = wvol_features_pca(feat, variance, NULL, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) {
        wvol_features_destroy(feat);
        return wvolpy_raise(&err);
    }
    {
        npy_intp d[4] = {feat->count, (npy_intp)v.nz, (npy_intp)v.ny, (npy_intp)v.nx};
        res = wvolpy_array_take(feat->data, 4, d); /* planar layout = (count, z, y, x): handed over */
        feat->data = NULL;
    }
    wvol_features_destroy(feat);
    return res;
}

PyMethodDef wvolpy_analysis_methods[] = {
    {"segment", (PyCFunction)(void (*)(void))py_segment, METH_VARARGS | METH_KEYWORDS,
     "segment(array, wavelet='db2', levels=3, smooth=1, include_lowpass=True, variance=1.0, som=(4, 4, 4),\n"
     "        iterations=20000, seed=1, truth=None, train_mask=None, boundary=-1) -> dict"},
    {"features", (PyCFunction)(void (*)(void))py_features, METH_VARARGS | METH_KEYWORDS,
     "features(array, wavelet='db2', levels=3, smooth=1, include_lowpass=True, variance=None) -> array"},
    {NULL, NULL, 0, NULL}};
