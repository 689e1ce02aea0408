/* SPDX-License-Identifier: MIT */
/* filters, dwt3, idwt3. */
#include "pyutil.h"
#include "methods.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
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
        for (int k = 0; k < f->length; k++)
            if (wvolpy_list_set(h, k, PyFloat_FromDouble(f->h[k])) < 0) {
                Py_DECREF(h);
                goto fail;
            }
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

/* ---- dwt3 / idwt3: the transform into a result buffer, handed to NumPy ----
 * When the grid needs no padding (each axis 1 or a multiple of 2^levels), the input is copied
 * into a result buffer (the copy is also its finiteness check) and transformed there in place:
 * the arithmetic of wvol_dwt3 / wvol_idwt3, without their fresh allocations and separate
 * checking passes. Anything else, and anything that could fail (non-finite values, values so
 * large the transform could leave float32's range, bad levels), goes through the library's
 * own call, which says what is wrong. */

static uint32_t copy_absmax(float *restrict dst, const float *restrict src, size_t n)
{
    int32_t m = 0; /* |x|'s bits as a signed integer (sign cleared): vectorises */
    long long count = (long long)n;
#pragma omp parallel for simd reduction(max : m) schedule(static) if (count > (1 << 20))
    for (long long i = 0; i < count; i++) {
        union { float f; int32_t i; } v = {src[i]}; /* not memcpy: clang does not vectorise that */
        const int32_t u = v.i & 0x7fffffff;
        dst[i] = src[i];
        m = u > m ? u : m;
    }
    return (uint32_t)m;
}

/* 1 when `levels` levels of the transform (inverse: of its inverse) over `axes` axes cannot
 * leave float32's range from data of largest |value| absmax: a 1D analysis pass multiplies the
 * largest value by at most sum |h|, a synthesis pass by sum |h| + sum |g| = 2 sum |h|; a factor
 * 2 covers rounding. */
static int stays_in_range(uint32_t absmax_bits, const wvol_filter *f, int levels, int axes, int inverse)
{
    float absmax;
    double s = 0, bound;
    if (absmax_bits >= 0x7f800000u) return 0; /* NaN or Inf */
    memcpy(&absmax, &absmax_bits, sizeof absmax);
    for (int k = 0; k < f->length; k++) s += fabs(f->h[k]);
    bound = 2.0 * absmax * pow(inverse ? 2 * s : s, (double)(axes * levels));
    return bound < FLT_MAX;
}

/* Axes the transform works on (extent > 1) when none needs padding; 0 otherwise (and for
 * levels the library would refuse). */
static int unpadded_axes(const size_t n[3], int levels)
{
    int axes = 0;
    if (levels < 1 || levels > wvol_dwt_max_levels(n[0], n[1], n[2])) return 0;
    for (int a = 0; a < 3; a++) {
        if (wvol_dwt_padded_size(n[a], levels) != n[a]) return 0;
        axes += n[a] > 1;
    }
    return axes;
}

/* The transform of in (n[0] x n[1] x n[2] floats) into a new result buffer; NULL without an
 * exception when the library's own call must decide (see above), NULL with one on failure. */
static PyObject *transform_fast(const float *in, const size_t n[3], const wvol_filter *f, int levels, int inverse)
{
    wvolpy_buffer b;
    npy_intp dims[3] = {(npy_intp)n[2], (npy_intp)n[1], (npy_intp)n[0]};
    int axes = unpadded_axes(n, levels), ok;
    uint32_t absmax;
    wvol_status s = WVOL_OK;
    wvol_error err;
    if (!axes) return NULL;
    if (wvolpy_buffer_alloc(&b, n[0] * n[1] * n[2]) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    absmax = copy_absmax(b.data, in, n[0] * n[1] * n[2]);
    ok = stays_in_range(absmax, f, levels, axes, inverse);
    if (ok)
        s = inverse ? wvol_idwt3_inplace_f32(b.data, n[0], n[1], n[2], f, levels, &err)
                    : wvol_dwt3_inplace_f32(b.data, n[0], n[1], n[2], f, levels, &err);
    Py_END_ALLOW_THREADS
    if (!ok || s != WVOL_OK) {
        wvolpy_buffer_free(&b);
        return s != WVOL_OK ? wvolpy_raise(&err) : NULL;
    }
    return wvolpy_buffer_array(&b, 3, dims);
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
    wvol_error err;
    size_t n[3], pad[3];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|si", kwlist, &arr_obj, &name, &levels)) return NULL;
    if (wvol_filter_get(&f, name, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (wvolpy_as_volume(arr_obj, &v, &holder, 0) < 0) return NULL;
    n[0] = v.nx, n[1] = v.ny, n[2] = v.nz;
    out = transform_fast(v.data, n, f, levels, 0);
    if (!out && !PyErr_Occurred()) {
        wvol_coeffs *c = NULL;
        wvol_status s;
        Py_BEGIN_ALLOW_THREADS
        s = wvol_dwt3(&c, &v, f, levels, &err);
        Py_END_ALLOW_THREADS
        if (s != WVOL_OK) {
            out = wvolpy_raise(&err);
        } else {
            npy_intp dims[3] = {(npy_intp)c->pz, (npy_intp)c->py, (npy_intp)c->px};
            out = wvolpy_array_take(c->data, 3, dims); /* the coefficients are handed over, no copy */
            c->data = NULL;
            wvol_coeffs_destroy(c);
        }
    }
    Py_DECREF(holder);
    if (!out) return NULL;
    for (int a = 0; a < 3; a++) pad[a] = wvol_dwt_padded_size(n[a], levels);
    return Py_BuildValue("N{s:s,s:i,s:(nnn),s:(nnn)}", out, "wavelet", f->name, "levels", levels, "shape",
                         (Py_ssize_t)n[2], (Py_ssize_t)n[1], (Py_ssize_t)n[0], "padded", (Py_ssize_t)pad[2],
                         (Py_ssize_t)pad[1], (Py_ssize_t)pad[0]);
}

static PyObject *py_idwt3(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"coeffs", "wavelet", "levels", "shape", NULL};
    PyObject *arr_obj, *shape, *out;
    const char *name;
    int levels;
    PyArrayObject *holder;
    wvol_coeffs c;
    wvol_error err;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OsiO", kwlist, &arr_obj, &name, &levels, &shape)) return NULL;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, NULL, NULL, &c, &holder, 0) < 0) return NULL;
    {
        size_t n[3] = {c.nx, c.ny, c.nz};
        out = transform_fast(c.data, n, c.filter, levels, 1);
    }
    if (!out && !PyErr_Occurred()) {
        wvol_volume *rec = NULL;
        wvol_status s = wvol_check_finite(c.data, c.px, c.py, c.pz, "array", &err);
        if (s == WVOL_OK) {
            Py_BEGIN_ALLOW_THREADS
            s = wvol_idwt3(&rec, &c, &err);
            Py_END_ALLOW_THREADS
        }
        out = s == WVOL_OK ? wvolpy_volume_take(rec, 0) : wvolpy_raise(&err);
    }
    Py_DECREF(holder);
    return out;
}

PyMethodDef wvolpy_wavelet_methods[] = {
    {"filters", py_filters, METH_NOARGS, "filters() -> list of dicts"},
    {"dwt3", (PyCFunction)(void (*)(void))py_dwt3, METH_VARARGS | METH_KEYWORDS,
     "dwt3(array, wavelet='db2', levels=3) -> (coeffs, info)"},
    {"idwt3", (PyCFunction)(void (*)(void))py_idwt3, METH_VARARGS | METH_KEYWORDS,
     "idwt3(coeffs, wavelet, levels, shape) -> array"},
    {NULL, NULL, 0, NULL}};
