/* SPDX-License-Identifier: MIT */
#include "pyutil.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void free_capsule(PyObject *cap)
{
    free(PyCapsule_GetPointer(cap, "wvol.buffer"));
}

PyObject *wvolpy_array_take(float *data, int nd, const npy_intp *dims)
{
    return wvolpy_array_take_type(data, nd, dims, NPY_FLOAT32);
}

PyObject *wvolpy_array_take_type(void *data, int nd, const npy_intp *dims, int typenum)
{
    PyObject *a, *cap;
    a = PyArray_SimpleNewFromData(nd, (npy_intp *)dims, typenum, data);
    if (!a) {
        free(data);
        return NULL;
    }
    cap = PyCapsule_New(data, "wvol.buffer", free_capsule);
    if (!cap) {
        Py_DECREF(a);
        free(data);
        return NULL;
    }
    if (PyArray_SetBaseObject((PyArrayObject *)a, cap) < 0) { /* steals cap (freed on failure) */
        Py_DECREF(a);
        return NULL;
    }
    return a;
}

/* ---- result buffers ---- */

#define BUFFER_BIG ((size_t)4 << 20)   /* from here on recycled */
#define BUFFER_ROUND ((size_t)1 << 20) /* big capacities in MiB: near sizes share buffers */
#define BUFFER_CACHE_BYTES ((size_t)512 << 20)
#define BUFFER_CAPSULE "wvol.result_buffer"

static wvolpy_buffer buffer_cache[2]; /* freed big buffers, oldest first; guarded by the GIL */

int wvolpy_buffer_alloc(wvolpy_buffer *b, size_t count)
{
    size_t bytes = count * sizeof(float);
    b->data = NULL;
    b->bytes = 0;
    if (count > (SIZE_MAX - BUFFER_ROUND) / sizeof(float)) {
        PyErr_NoMemory();
        return -1;
    }
    if (bytes >= BUFFER_BIG) {
        bytes = (bytes + BUFFER_ROUND - 1) / BUFFER_ROUND * BUFFER_ROUND;
        for (int i = 0; i < 2; i++)
            if (buffer_cache[i].data && buffer_cache[i].bytes == bytes) {
                *b = buffer_cache[i];
                if (i == 0) buffer_cache[0] = buffer_cache[1]; /* slot 1 is taken only when 0 is */
                buffer_cache[1].data = NULL;
                buffer_cache[1].bytes = 0;
                return 0;
            }
    }
    b->data = malloc(bytes ? bytes : 1);
    if (!b->data) {
        PyErr_NoMemory();
        return -1;
    }
    b->bytes = bytes;
    return 0;
}

void wvolpy_buffer_free(wvolpy_buffer *b)
{
    wvolpy_buffer keep = *b;
    b->data = NULL;
    b->bytes = 0;
    if (!keep.data) return;
    if (keep.bytes >= BUFFER_BIG && keep.bytes <= BUFFER_CACHE_BYTES / 2) {
        /* newest last: the oldest goes when both slots are taken */
        if (buffer_cache[0].data && buffer_cache[1].data) {
            free(buffer_cache[0].data);
            buffer_cache[0] = buffer_cache[1];
            buffer_cache[1].data = NULL;
        }
        buffer_cache[buffer_cache[0].data ? 1 : 0] = keep;
        return;
    }
    free(keep.data);
}

static void buffer_capsule_free(PyObject *cap)
{
    wvolpy_buffer b;
    b.data = PyCapsule_GetPointer(cap, BUFFER_CAPSULE);
    b.bytes = (size_t)(uintptr_t)PyCapsule_GetContext(cap);
    wvolpy_buffer_free(&b);
}

PyObject *wvolpy_buffer_array(wvolpy_buffer *b, int nd, const npy_intp *dims)
{
    PyObject *a, *cap = PyCapsule_New(b->data, BUFFER_CAPSULE, buffer_capsule_free);
    float *data = b->data;
    if (!cap) {
        wvolpy_buffer_free(b);
        return NULL;
    }
    (void)PyCapsule_SetContext(cap, (void *)(uintptr_t)b->bytes); /* cannot fail on a new capsule */
    b->data = NULL;
    b->bytes = 0;
    a = PyArray_SimpleNewFromData(nd, (npy_intp *)dims, NPY_FLOAT32, data);
    if (!a) {
        Py_DECREF(cap);
        return NULL;
    }
    if (PyArray_SetBaseObject((PyArrayObject *)a, cap) < 0) { /* steals cap, which frees the buffer */
        Py_DECREF(a);
        return NULL;
    }
    return a;
}

PyObject *wvolpy_volume_take(wvol_volume *v, int squeeze2d)
{
    PyObject *a;
    npy_intp dims[3] = {(npy_intp)v->nz, (npy_intp)v->ny, (npy_intp)v->nx};
    int nd = squeeze2d && v->nz == 1 ? 2 : 3;
    if (!v->owns || !v->data) {
        a = wvolpy_volume_to_array(v, squeeze2d);
        wvol_volume_destroy(v);
        return a;
    }
    {
        float *data = v->data;
        v->data = NULL;
        v->owns = 0;
        wvol_volume_destroy(v);
        return wvolpy_array_take(data, nd, dims + (3 - nd));
    }
}

int wvolpy_as_coeffs(PyObject *arr, const char *wavelet, int levels, PyObject *shape, PyObject *spacing,
                     PyObject *origin, wvol_coeffs *c, PyArrayObject **holder, int check_finite)
{
    wvol_volume v;
    wvol_error err;
    Py_ssize_t sz, sy, sx;
    memset(c, 0, sizeof *c);
    *holder = NULL;
    if (!PyArg_ParseTuple(shape, "nnn;shape must be (nz, ny, nx)", &sz, &sy, &sx)) return -1;
    if (wvol_filter_get(&c->filter, wavelet, &err) != WVOL_OK) {
        wvolpy_raise(&err);
        return -1;
    }
    if (levels < 1 || levels > 30) {
        PyErr_Format(PyExc_ValueError, "levels must be in 1..30, got %d", levels);
        return -1;
    }
    if (sx < 1 || sy < 1 || sz < 1) {
        PyErr_Format(PyExc_ValueError, "shape (%zd, %zd, %zd) must be positive", sz, sy, sx);
        return -1;
    }
    c->spacing[0] = c->spacing[1] = c->spacing[2] = 1.0;
    if (wvolpy_triple(spacing, c->spacing, "spacing") < 0 || wvolpy_triple(origin, c->origin, "origin") < 0)
        return -1;
    if (wvolpy_as_volume(arr, &v, holder, check_finite) < 0) return -1;
    c->levels = levels;
    c->nx = (size_t)sx;
    c->ny = (size_t)sy;
    c->nz = (size_t)sz;
    c->px = v.nx;
    c->py = v.ny;
    c->pz = v.nz;
    c->data = v.data;
    if (c->px != wvol_dwt_padded_size(c->nx, levels) || c->py != wvol_dwt_padded_size(c->ny, levels) ||
        c->pz != wvol_dwt_padded_size(c->nz, levels)) {
        PyErr_Format(PyExc_ValueError,
                     "coefficient array shape (%zu, %zu, %zu) is not the padded size of shape (%zd, %zd, %zd) "
                     "for %d levels", c->pz, c->py, c->px, sz, sy, sx, levels);
        Py_CLEAR(*holder);
        return -1;
    }
    return 0;
}

PyObject *wvolpy_raise(const wvol_error *err)
{
    PyObject *type;
    switch (err->status) {
    case WVOL_ERR_IO:
    case WVOL_ERR_FORMAT: type = PyExc_OSError; break;
    case WVOL_ERR_NOMEM: type = PyExc_MemoryError; break;
    case WVOL_ERR_UNSUPPORTED: type = PyExc_NotImplementedError; break;
    case WVOL_ERR_INTERNAL:
    case WVOL_ERR_NUMERIC: type = PyExc_RuntimeError; break;
    default: type = PyExc_ValueError; break;
    }
    PyErr_SetString(type, err->message[0] ? err->message : wvol_status_string(err->status));
    return NULL;
}

/* The files' rule for arrays (docs/formats.md, "Samples"): a 32- or 64-bit integer that float32
 * cannot hold exactly is refused rather than rounded. f is arr cast to float32, C-ordered; 0, or
 * -1 with a ValueError. */
static int exact_in_f32(PyArrayObject *arr, PyArrayObject *f)
{
    const int is_unsigned = PyArray_DESCR(arr)->kind == 'u';
    PyArrayObject *src =
        (PyArrayObject *)PyArray_FROM_OTF((PyObject *)arr, is_unsigned ? NPY_UINT64 : NPY_INT64, NPY_ARRAY_IN_ARRAY);
    const float *y = PyArray_DATA(f);
    const npy_intp n = PyArray_SIZE(f);
    if (!src) return -1;
    for (npy_intp i = 0; i < n; i++) {
        const unsigned long long u = ((const unsigned long long *)PyArray_DATA(src))[i];
        const long long v = ((const long long *)PyArray_DATA(src))[i];
        if (is_unsigned ? (long double)y[i] != (long double)u : (long double)y[i] != (long double)v) {
            char digits[24];
            if (is_unsigned) snprintf(digits, sizeof digits, "%llu", u);
            else snprintf(digits, sizeof digits, "%lld", v);
            wvolpy_value_error("the array's integer %s at flat index %zd cannot be held exactly by float32 (integers "
                               "above 2^24 in magnitude lose digits); refused",
                               digits, (Py_ssize_t)i);
            Py_DECREF(src);
            return -1;
        }
    }
    Py_DECREF(src);
    return 0;
}

/* A finite float64 beyond float32's range is named as such (the cast would make it Inf, which
 * the finite check would call an Inf in the data). 0, or -1 with a ValueError. */
static int f64_in_range(PyArrayObject *arr)
{
    PyArrayObject *src = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)arr, NPY_FLOAT64, NPY_ARRAY_IN_ARRAY);
    const npy_intp n = src ? PyArray_SIZE(src) : 0;
    if (!src) return -1;
    for (npy_intp i = 0; i < n; i++) {
        const double x = ((const double *)PyArray_DATA(src))[i];
        if (isfinite(x) && fabs(x) > FLT_MAX) {
            wvolpy_value_error("the array's value %g at flat index %zd is beyond float32's range (3.4e38)", x,
                               (Py_ssize_t)i);
            Py_DECREF(src);
            return -1;
        }
    }
    Py_DECREF(src);
    return 0;
}

PyArrayObject *wvolpy_real_f32(PyObject *obj)
{
    PyArrayObject *arr, *f;
    PyArray_Descr *dt;
    arr = (PyArrayObject *)PyArray_FROM_O(obj);
    if (!arr) return NULL;
    dt = PyArray_DESCR(arr);
    if (!(dt->kind == 'f' || dt->kind == 'i' || dt->kind == 'u') || dt->elsize > 8) {
        PyErr_Format(PyExc_TypeError, "expected an array of real numbers (float or integer), got dtype %S",
                     (PyObject *)dt);
        Py_DECREF(arr);
        return NULL;
    }
    if (dt->kind == 'f' && dt->elsize == 8 && f64_in_range(arr) < 0) { /* before the cast, which warns */
        Py_DECREF(arr);
        return NULL;
    }
    f = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)arr, NPY_FLOAT32, NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
    if (f && dt->kind != 'f' && dt->elsize >= 4 && exact_in_f32(arr, f) < 0) Py_CLEAR(f);
    Py_DECREF(arr);
    return f;
}

int wvolpy_as_volume(PyObject *obj, wvol_volume *out, PyArrayObject **holder, int check_finite)
{
    PyArrayObject *arr;
    int nd;
    npy_intp *shape;
    *holder = NULL;
    memset(out, 0, sizeof *out);
    arr = wvolpy_real_f32(obj);
    if (!arr) return -1;
    nd = PyArray_NDIM(arr);
    if (nd != 2 && nd != 3) {
        PyErr_Format(PyExc_ValueError, "expected a 3D (z, y, x) or 2D (y, x) array, got %d dimensions", nd);
        Py_DECREF(arr);
        return -1;
    }
    if (PyArray_SIZE(arr) == 0) {
        PyErr_SetString(PyExc_ValueError, "the array is empty");
        Py_DECREF(arr);
        return -1;
    }
    shape = PyArray_DIMS(arr);
    out->nx = (size_t)shape[nd - 1];
    out->ny = (size_t)shape[nd - 2];
    out->nz = nd == 3 ? (size_t)shape[0] : 1;
    out->spacing[0] = out->spacing[1] = out->spacing[2] = 1.0;
    out->data = (float *)PyArray_DATA(arr);
    out->owns = 0;
    if (check_finite) {
        wvol_error err;
        if (wvol_check_finite(out->data, out->nx, out->ny, out->nz, "array", &err) != WVOL_OK) {
            Py_DECREF(arr);
            wvolpy_raise(&err);
            return -1;
        }
    }
    *holder = arr;
    return 0;
}

PyObject *wvolpy_volume_to_array(const wvol_volume *v, int squeeze2d)
{
    npy_intp dims[3] = {(npy_intp)v->nz, (npy_intp)v->ny, (npy_intp)v->nx};
    PyObject *a;
    if (squeeze2d && v->nz == 1)
        a = PyArray_SimpleNew(2, dims + 1, NPY_FLOAT32);
    else
        a = PyArray_SimpleNew(3, dims, NPY_FLOAT32);
    if (!a) return NULL;
    memcpy(PyArray_DATA((PyArrayObject *)a), v->data, v->nx * v->ny * v->nz * sizeof(float));
    return a;
}

int wvolpy_as_placed_volume(PyObject *obj, PyObject *spacing, PyObject *origin, wvol_volume *out,
                            PyArrayObject **holder, int check_finite)
{
    if (wvolpy_as_volume(obj, out, holder, check_finite) < 0) return -1;
    if (wvolpy_triple(spacing, out->spacing, "spacing") < 0 || wvolpy_triple(origin, out->origin, "origin") < 0) {
        Py_CLEAR(*holder);
        return -1;
    }
    return 0;
}

int wvolpy_conv_budget(PyObject *obj, void *out)
{
    unsigned long long v;
    int negative;
    PyObject *num;
    /* an int or what stands for one (numpy's integers), never a bool or a float */
    if (PyBool_Check(obj) || !PyIndex_Check(obj) || !(num = PyNumber_Index(obj))) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "memory budget must be an int (bytes), got %s", Py_TYPE(obj)->tp_name);
        return 0;
    }
    obj = num;
    {
        PyObject *zero = PyLong_FromLong(0);
        negative = zero ? PyObject_RichCompareBool(obj, zero, Py_LT) : -1;
        Py_XDECREF(zero);
    }
    if (negative) {
        if (negative > 0) PyErr_Format(PyExc_ValueError, "memory budget must be >= 0 bytes, got %S", obj);
        Py_DECREF(num);
        return 0;
    }
    v = PyLong_AsUnsignedLongLong(obj);
    Py_DECREF(num);
    if (PyErr_Occurred()) return 0;
    *(unsigned long long *)out = v;
    return 1;
}

int wvolpy_check_threads(int threads)
{
    if (threads >= 0 && threads <= WVOLPY_MAX_THREADS) return 0;
    PyErr_Format(PyExc_ValueError, "threads must be in 0..%d (0: all), got %d", WVOLPY_MAX_THREADS, threads);
    return -1;
}

Py_ssize_t wvolpy_first_nonfinite3(const float *p, Py_ssize_t n3)
{
    for (Py_ssize_t i = 0; i < n3; i++)
        if (!isfinite(p[i])) return i / 3;
    return -1;
}

int wvolpy_list_set(PyObject *list, Py_ssize_t i, PyObject *item)
{
    if (!item) return -1;
    PyList_SET_ITEM(list, i, item);
    return 0;
}

int wvolpy_seed(PyObject *obj, uint64_t *out)
{
    unsigned long long v;
    if (!obj || obj == Py_None) return 0;
    v = PyLong_AsUnsignedLongLong(obj);
    if (PyErr_Occurred()) {
        if (PyErr_ExceptionMatches(PyExc_OverflowError)) {
            PyErr_Clear();
            PyErr_SetString(PyExc_ValueError, "seed must be an integer in 0..2^64-1");
        }
        return -1;
    }
    *out = (uint64_t)v;
    return 0;
}

PyObject *wvolpy_fast_snapshot(PyObject *o, const char *msg)
{
    PyObject *seq = PySequence_Fast(o, msg), *t;
    if (!seq || !PyList_Check(seq)) return seq; /* a tuple, or a list of its own */
    t = PyList_AsTuple(seq);
    Py_DECREF(seq);
    return t;
}

int wvolpy_triple(PyObject *obj, double out[3], const char *what)
{
    PyObject *seq;
    if (obj == NULL || obj == Py_None) return 0;
    if (PyNumber_Check(obj) && !PySequence_Check(obj)) { /* an array of 3 is a number too */
        double v = PyFloat_AsDouble(obj);
        if (PyErr_Occurred()) return -1;
        out[0] = out[1] = out[2] = v;
        return 0;
    }
    seq = wvolpy_fast_snapshot(obj, "expected a number or a sequence of 3 numbers");
    if (!seq) return -1;
    if (PySequence_Fast_GET_SIZE(seq) != 3) {
        PyErr_Format(PyExc_ValueError, "%s: expected 3 values (x, y, z), got %zd", what,
                     PySequence_Fast_GET_SIZE(seq));
        Py_DECREF(seq);
        return -1;
    }
    for (int a = 0; a < 3; a++) {
        out[a] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, a));
        if (PyErr_Occurred()) {
            Py_DECREF(seq);
            return -1;
        }
    }
    Py_DECREF(seq);
    return 0;
}

int wvolpy_parse_levels(PyObject *obj, int *levels)
{
    long l;
    if (obj == Py_None) return 0;
    l = PyLong_AsLong(obj);
    if (l == -1 && PyErr_Occurred()) return -1;
    if (l < 1 || l > 30) {
        PyErr_Format(PyExc_ValueError, "levels must be in 1..30 (None: default), got %ld", l);
        return -1;
    }
    *levels = (int)l;
    return 0;
}

const char *wvolpy_utf8(PyObject *o, const char *what)
{
    Py_ssize_t n;
    const char *s;
    if (!PyUnicode_Check(o)) {
        PyErr_Format(PyExc_TypeError, "%s must be a string", what);
        return NULL;
    }
    if (!(s = PyUnicode_AsUTF8AndSize(o, &n))) return NULL;
    if ((size_t)n != strlen(s)) {
        PyErr_Format(PyExc_ValueError, "%s: embedded null character", what);
        return NULL;
    }
    return s;
}

PyObject *wvolpy_value_error(const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    PyErr_SetString(PyExc_ValueError, msg);
    return NULL;
}
