/* SPDX-License-Identifier: MIT */
/* radiosity: scenes, the wavelet radiosity solve (stats, samples, point values, an image) and the
 * closed-form point-to-quad form factor, NumPy first. */
#include "pyutil.h"
#include "methods.h"
#include "wvol/radiosity.h"

#include <math.h>
#include <string.h>

/* A scene from a name / .obj path, or from (quads (n,4,3), emission (n,3), reflectance (n,3)). */
static int to_scene(PyObject *obj, wvol_radiosity_scene **out)
{
    wvol_error err;
    wvol_status s;
    *out = NULL;
    if (PyUnicode_Check(obj)) {
        const char *name = wvolpy_utf8(obj, "scene");
        size_t n;
        if (!name) return -1;
        n = strlen(name);
        Py_BEGIN_ALLOW_THREADS
        s = n > 4 && !strcmp(name + n - 4, ".obj") ? wvol_radiosity_scene_load_obj(out, name, &err)
                                                    : wvol_radiosity_scene_builtin(out, name, &err);
        Py_END_ALLOW_THREADS
        if (s != WVOL_OK) {
            wvolpy_raise(&err);
            return -1;
        }
        return 0;
    }
    {
        PyObject *qo, *eo, *ro;
        PyArrayObject *q = NULL, *e = NULL, *r = NULL;
        wvol_radiosity_quad *quads = NULL;
        npy_intp n;
        int rc = -1;
        if (!PyArg_ParseTuple(obj, "OOO;scene must be a name, an .obj path or (quads, emission, reflectance)", &qo,
                              &eo, &ro))
            return -1;
        /* one after the other: a conversion runs Python code, not with an error pending */
        if (!(q = (PyArrayObject *)PyArray_FROM_OTF(qo, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY)) ||
            !(e = (PyArrayObject *)PyArray_FROM_OTF(eo, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY)) ||
            !(r = (PyArrayObject *)PyArray_FROM_OTF(ro, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY)))
            goto done;
        n = PyArray_NDIM(q) == 3 ? PyArray_DIM(q, 0) : -1;
        if (n < 0 || PyArray_DIM(q, 1) != 4 || PyArray_DIM(q, 2) != 3) {
            PyErr_SetString(PyExc_ValueError, "quads must have shape (n, 4, 3)");
            goto done;
        }
        if (PyArray_NDIM(e) != 2 || PyArray_DIM(e, 0) != n || PyArray_DIM(e, 1) != 3 || PyArray_NDIM(r) != 2 ||
            PyArray_DIM(r, 0) != n || PyArray_DIM(r, 1) != 3) {
            PyErr_SetString(PyExc_ValueError, "emission and reflectance must have shape (n, 3)");
            goto done;
        }
        quads = PyMem_Calloc(n ? (size_t)n : 1, sizeof *quads);
        if (!quads) {
            PyErr_NoMemory();
            goto done;
        }
        for (npy_intp i = 0; i < n; i++) {
            memcpy(quads[i].p, (const double *)PyArray_DATA(q) + 12 * i, sizeof quads[i].p);
            memcpy(quads[i].emission, (const double *)PyArray_DATA(e) + 3 * i, sizeof quads[i].emission);
            memcpy(quads[i].reflectance, (const double *)PyArray_DATA(r) + 3 * i, sizeof quads[i].reflectance);
        }
        if (wvol_radiosity_scene_create(out, quads, (size_t)n, &err) != WVOL_OK) {
            wvolpy_raise(&err);
            goto done;
        }
        rc = 0;
    done:
        PyMem_Free(quads);
        Py_XDECREF(q);
        Py_XDECREF(e);
        Py_XDECREF(r);
        return rc;
    }
}

static PyObject *new_f64(int nd, const npy_intp *dims) { return PyArray_ZEROS(nd, (npy_intp *)dims, NPY_DOUBLE, 0); }

/* radiosity_scene(scene) -> (quads (n,4,3), emission (n,3), reflectance (n,3), area (n,), normal (n,3)) */
static PyObject *py_radiosity_scene(PyObject *self, PyObject *args)
{
    PyObject *obj, *q, *e, *r, *a, *nm;
    wvol_radiosity_scene *s;
    npy_intp n, d3[3], d2[2], d1[1];
    (void)self;
    if (!PyArg_ParseTuple(args, "O", &obj) || to_scene(obj, &s) < 0) return NULL;
    n = (npy_intp)wvol_radiosity_scene_count(s);
    d3[0] = n, d3[1] = 4, d3[2] = 3, d2[0] = n, d2[1] = 3, d1[0] = n;
    q = new_f64(3, d3), e = new_f64(2, d2), r = new_f64(2, d2), a = new_f64(1, d1), nm = new_f64(2, d2);
    if (q && e && r && a && nm)
        for (npy_intp i = 0; i < n; i++) {
            const wvol_radiosity_quad *qq = wvol_radiosity_scene_quad(s, (size_t)i);
            memcpy((double *)PyArray_DATA((PyArrayObject *)q) + 12 * i, qq->p, sizeof qq->p);
            memcpy((double *)PyArray_DATA((PyArrayObject *)e) + 3 * i, qq->emission, sizeof qq->emission);
            memcpy((double *)PyArray_DATA((PyArrayObject *)r) + 3 * i, qq->reflectance, sizeof qq->reflectance);
            wvol_radiosity_scene_quad_geometry(s, (size_t)i, (double *)PyArray_DATA((PyArrayObject *)a) + i,
                                               (double *)PyArray_DATA((PyArrayObject *)nm) + 3 * i);
        }
    wvol_radiosity_scene_destroy(s);
    if (!q || !e || !r || !a || !nm) {
        Py_XDECREF(q), Py_XDECREF(e), Py_XDECREF(r), Py_XDECREF(a), Py_XDECREF(nm);
        return NULL;
    }
    return Py_BuildValue("NNNNN", q, e, r, a, nm);
}

/* radiosity_point_form_factor(scene, patch, points (m,3), normal (3,)) -> (m,) */
static PyObject *py_radiosity_point_ff(PyObject *self, PyObject *args)
{
    PyObject *obj, *po, *no, *out;
    Py_ssize_t patch;
    PyArrayObject *pts;
    wvol_radiosity_scene *s;
    double n[3];
    npy_intp m;
    (void)self;
    if (!PyArg_ParseTuple(args, "OnOO", &obj, &patch, &po, &no) || wvolpy_triple(no, n, "normal") < 0) return NULL;
    pts = (PyArrayObject *)PyArray_FROM_OTF(po, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY);
    if (!pts) return NULL;
    if (PyArray_NDIM(pts) != 2 || PyArray_DIM(pts, 1) != 3) {
        Py_DECREF(pts);
        return PyErr_Format(PyExc_ValueError, "points must have shape (m, 3)");
    }
    if (to_scene(obj, &s) < 0) {
        Py_DECREF(pts);
        return NULL;
    }
    if (patch < 0 || (size_t)patch >= wvol_radiosity_scene_count(s)) {
        /* the message reads the scene: formatted before it goes */
        PyErr_Format(PyExc_ValueError, "patch %zd is not a patch of the scene (0..%zd)", patch,
                     (Py_ssize_t)wvol_radiosity_scene_count(s) - 1);
        wvol_radiosity_scene_destroy(s);
        Py_DECREF(pts);
        return NULL;
    }
    if (!(isfinite(n[0]) && isfinite(n[1]) && isfinite(n[2])) || n[0] * n[0] + n[1] * n[1] + n[2] * n[2] == 0) {
        wvol_radiosity_scene_destroy(s);
        Py_DECREF(pts);
        return wvolpy_value_error("normal (%g, %g, %g) must be finite and non-zero", n[0], n[1], n[2]);
    }
    for (npy_intp i = 0; i < 3 * PyArray_DIM(pts, 0); i++)
        if (!isfinite(((const double *)PyArray_DATA(pts))[i])) {
            wvol_radiosity_scene_destroy(s);
            Py_DECREF(pts);
            return wvolpy_value_error("points: non-finite coordinate at point %zd", (Py_ssize_t)(i / 3));
        }
    m = PyArray_DIM(pts, 0);
    out = new_f64(1, &m);
    if (out)
        for (npy_intp i = 0; i < m; i++)
            ((double *)PyArray_DATA((PyArrayObject *)out))[i] = wvol_radiosity_point_form_factor(
                s, (size_t)patch, (const double *)PyArray_DATA(pts) + 3 * i, n);
    wvol_radiosity_scene_destroy(s);
    Py_DECREF(pts);
    return out;
}

static int set_num(PyObject *d, const char *k, PyObject *v)
{
    int rc;
    if (!v) return -1;
    rc = PyDict_SetItemString(d, k, v);
    Py_DECREF(v);
    return rc;
}

static PyObject *triple(const double *v) { return Py_BuildValue("(ddd)", v[0], v[1], v[2]); }

/* radiosity_solve(scene, basis, epsilon, max_level, brightness, full_matrix, max_iterations, tolerance,
 *                 res, uv, camera, size) -> dict */
static PyObject *py_radiosity_solve(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"scene", "basis", "epsilon", "max_level", "brightness", "full_matrix", "max_iterations",
                             "tolerance", "res", "uv", "camera", "size", NULL};
    PyObject *obj, *uvo = Py_None, *sizeo = Py_None, *d = NULL, *arr;
    const char *basis = "haar", *camspec = NULL;
    wvol_radiosity_params p;
    wvol_radiosity_stats st;
    wvol_radiosity_scene *s = NULL;
    wvol_radiosity *sol = NULL;
    wvol_error err;
    wvol_status status;
    int brightness = 0, full = 0, res = 0;
    PyArrayObject *uv = NULL;
    (void)self;
    wvol_radiosity_params_default(&p);
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|sdippidiOzO", kwlist, &obj, &basis, &p.epsilon, &p.max_level,
                                     &brightness, &full, &p.max_iterations, &p.tolerance, &res, &uvo, &camspec,
                                     &sizeo))
        return NULL;
    p.brightness = brightness, p.full_matrix = full;
    if (wvol_radiosity_basis_parse(basis, &p.basis, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (res < 0 || res > 4096) return PyErr_Format(PyExc_ValueError, "res must be in 0..4096");
    if (uvo != Py_None) {
        uv = (PyArrayObject *)PyArray_FROM_OTF(uvo, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY);
        if (!uv) return NULL;
        if (PyArray_NDIM(uv) != 2 || PyArray_DIM(uv, 1) != 2) {
            Py_DECREF(uv);
            return PyErr_Format(PyExc_ValueError, "uv must have shape (m, 2)");
        }
    }
    if (to_scene(obj, &s) < 0) goto fail;
    Py_BEGIN_ALLOW_THREADS
    status = wvol_radiosity_solve(&sol, s, &p, &st, &err);
    Py_END_ALLOW_THREADS
    if (status != WVOL_OK) {
        wvolpy_raise(&err);
        goto fail;
    }
    d = PyDict_New();
    if (!d) goto fail;
    if (set_num(d, "interactions", PyLong_FromSize_t(st.links)) || set_num(d, "link_terms", PyLong_FromSize_t(st.link_terms)) ||
        set_num(d, "nodes", PyLong_FromSize_t(st.nodes)) || set_num(d, "leaves", PyLong_FromSize_t(st.leaves)) ||
        set_num(d, "kernel_evaluations", PyLong_FromSize_t(st.kernel_evals)) ||
        set_num(d, "closed_form_evaluations", PyLong_FromSize_t(st.closed_form_evals)) ||
        set_num(d, "rays", PyLong_FromSize_t(st.rays)) || set_num(d, "iterations", PyLong_FromLong(st.iterations)) ||
        set_num(d, "last_change", PyFloat_FromDouble(st.change)) ||
        set_num(d, "seconds_refine", PyFloat_FromDouble(st.seconds_refine)) ||
        set_num(d, "seconds_solve", PyFloat_FromDouble(st.seconds_solve)) || set_num(d, "emitted", triple(st.emitted)) ||
        set_num(d, "absorbed", triple(st.absorbed)) || set_num(d, "energy_error", PyFloat_FromDouble(st.energy_error)) ||
        set_num(d, "basis", PyUnicode_FromString(wvol_radiosity_basis_name(p.basis))))
        goto fail;
    if (res > 0) {
        npy_intp dims[4] = {(npy_intp)wvol_radiosity_scene_count(s), res, res, 3};
        arr = new_f64(4, dims);
        if (set_num(d, "samples", arr)) goto fail;
        wvol_radiosity_sample(sol, res, (double *)PyArray_DATA((PyArrayObject *)arr), NULL);
    }
    if (uv) {
        npy_intp m = PyArray_DIM(uv, 0), dims[3] = {(npy_intp)wvol_radiosity_scene_count(s), m, 3};
        arr = new_f64(3, dims);
        if (set_num(d, "values", arr)) goto fail;
        for (npy_intp i = 0; i < dims[0]; i++)
            if (wvol_radiosity_eval(sol, (size_t)i, (size_t)m, (const double *)PyArray_DATA(uv),
                                    (double *)PyArray_DATA((PyArrayObject *)arr) + 3 * m * i, &err) != WVOL_OK) {
                wvolpy_raise(&err);
                goto fail;
            }
    }
    if (camspec) {
        wvol_camera cam;
        wvol_geometry g;
        wvol_image *img = NULL;
        int w = 256, h = 256;
        npy_intp dims[3];
        if (sizeo != Py_None && !PyArg_ParseTuple(sizeo, "ii;size must be (width, height)", &w, &h)) goto fail;
        wvol_radiosity_geometry(s, &g);
        if (wvol_camera_parse(&cam, camspec, &g, w, h, &err) != WVOL_OK || wvol_image_create(&img, w, h, &err) != WVOL_OK ||
            wvol_radiosity_render(sol, img, &cam, &err) != WVOL_OK) {
            wvol_image_destroy(img);
            wvolpy_raise(&err);
            goto fail;
        }
        dims[0] = h, dims[1] = w, dims[2] = 4;
        arr = wvolpy_array_take(img->rgba, 3, dims);
        img->rgba = NULL;
        wvol_image_destroy(img);
        if (set_num(d, "image", arr)) goto fail;
    }
    Py_XDECREF(uv);
    wvol_radiosity_destroy(sol);
    wvol_radiosity_scene_destroy(s);
    return d;
fail:
    Py_XDECREF(d);
    Py_XDECREF(uv);
    wvol_radiosity_destroy(sol);
    wvol_radiosity_scene_destroy(s);
    return NULL;
}

PyMethodDef wvolpy_radiosity_methods[] = {
    {"radiosity_scene", py_radiosity_scene, METH_VARARGS,
     "radiosity_scene(scene) -> (quads, emission, reflectance, area, normal)"},
    {"radiosity_point_form_factor", py_radiosity_point_ff, METH_VARARGS,
     "radiosity_point_form_factor(scene, patch, points, normal) -> form factors"},
    {"radiosity_solve", (PyCFunction)(void (*)(void))py_radiosity_solve, METH_VARARGS | METH_KEYWORDS,
     "radiosity_solve(scene, basis, epsilon, max_level, brightness, full_matrix, max_iterations, tolerance, res, uv, "
     "camera, size) -> dict"},
    {NULL, NULL, 0, NULL}};
