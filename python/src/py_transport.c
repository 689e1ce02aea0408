/* SPDX-License-Identifier: MIT */
/* transport: wavelet radiative transfer in Nusselt coordinates (wvol/transport.h). Radiance cell
 * arrays are float32 (N, N, N, N, 3) indexed [l, k, v, u, channel] (u fastest, as in the C API). */
#include "pyutil.h"
#include "methods.h"
#include "wvol/transport.h"

#include <math.h>
#include <string.h>

static int parse_quad(PyObject *obj, wvol_transport_quad *q, const char *what)
{
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, 2, 2, NPY_ARRAY_CARRAY);
    if (!a) return -1;
    if (PyArray_DIM(a, 0) != 4 || PyArray_DIM(a, 1) != 3) {
        Py_DECREF(a);
        PyErr_Format(PyExc_ValueError, "%s: 4 vertices of 3 coordinates expected", what);
        return -1;
    }
    memcpy(q->p, PyArray_DATA(a), sizeof q->p);
    Py_DECREF(a);
    return 0;
}

static int parse_params(wvol_transport_params *p, int levels, const char *quad, int samples, unsigned long long seed,
                        int oracle)
{
    int q = wvol_transport_quadrature_find(quad);
    wvol_transport_params_default(p);
    if (q < 0) {
        PyErr_Format(PyExc_ValueError, "unknown quadrature '%s'", quad);
        return -1;
    }
    p->levels = levels;
    p->quadrature = (wvol_transport_quadrature)q;
    p->samples = samples;
    p->seed = seed;
    p->use_oracle = oracle;
    return 0;
}

static PyObject *tree_cells(const wvol_transport_tree *t)
{
    int L = wvol_transport_tree_levels(t);
    npy_intp n = (npy_intp)1 << L, dims[5] = {n, n, n, n, 3};
    size_t cap = 3 * wvol_transport_cells_count(L);
    float *buf = malloc(cap * sizeof *buf);
    wvol_error err;
    if (!buf) return PyErr_NoMemory();
    if (wvol_transport_tree_to_cells(buf, cap, t, &err) != WVOL_OK) {
        free(buf);
        return wvolpy_raise(&err);
    }
    return wvolpy_array_take(buf, 5, dims);
}

/* cells of 4 equal sides of 2^L and 3 channels -> a new tree (caller destroys) or NULL */
static wvol_transport_tree *cells_tree(PyObject *obj, double threshold)
{
    PyArrayObject *a = wvolpy_real_f32(obj);
    wvol_transport_tree *t = NULL;
    wvol_error err;
    int L = -1;
    if (!a) return NULL;
    if (PyArray_NDIM(a) == 5 && PyArray_DIM(a, 4) == 3)
        for (int l = 1; l <= WVOL_TRANSPORT_MAX_LEVELS; l++)
            if (PyArray_DIM(a, 0) == (npy_intp)1 << l && PyArray_DIM(a, 1) == PyArray_DIM(a, 0) &&
                PyArray_DIM(a, 2) == PyArray_DIM(a, 0) && PyArray_DIM(a, 3) == PyArray_DIM(a, 0))
                L = l;
    if (L < 0) {
        Py_DECREF(a);
        PyErr_SetString(PyExc_ValueError, "radiance cells must have shape (N, N, N, N, 3) with N = 2^L, L = 1..6");
        return NULL;
    }
    if (wvol_transport_tree_from_cells(&t, PyArray_DATA(a), L, threshold, &err) != WVOL_OK) {
        Py_DECREF(a);
        wvolpy_raise(&err);
        return NULL;
    }
    Py_DECREF(a);
    return t;
}

/* haar(cells, threshold=0) -> (reconstructed cells, stored nodes, non-zero coefficients) */
static PyObject *py_haar(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"cells", "threshold", NULL};
    PyObject *cells, *out;
    double thr = 0;
    wvol_transport_tree *t;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|d", kwlist, &cells, &thr)) return NULL;
    if (!(t = cells_tree(cells, thr))) return NULL;
    out = tree_cells(t);
    if (out)
        out = Py_BuildValue("Nnn", out, (Py_ssize_t)wvol_transport_tree_nodes(t),
                            (Py_ssize_t)wvol_transport_tree_coefficients(t));
    wvol_transport_tree_destroy(t);
    return out;
}

/* coefficients(src, dst, j, level, quadrature, samples, seed) -> T over all k of the level (k's cell
 * index u fastest) */
static PyObject *py_coefficients(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"src", "dst", "j", "level", "quadrature", "samples", "seed", NULL};
    PyObject *so, *dobj;
    wvol_transport_quad sq, dq;
    wvol_transport_index j, k;
    wvol_transport_params p;
    const char *qn = "trapezoid";
    int level, samples = 16;
    uint64_t seed = 1;
    PyObject *seed_obj = NULL;
    double *T;
    npy_intp n;
    wvol_error err;
    wvol_status s = WVOL_OK;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO(iiiii)i|siO", kwlist, &so, &dobj, &j.level, &j.m[0], &j.m[1], &j.m[2],
                                     &j.m[3], &level, &qn, &samples, &seed_obj) ||
        wvolpy_seed(seed_obj, &seed) < 0)
        return NULL;
    if (parse_quad(so, &sq, "src") < 0 || parse_quad(dobj, &dq, "dst") < 0) return NULL;
    if (parse_params(&p, 1, qn, samples, seed, 0) < 0) return NULL;
    if (level < 0 || level > 4) return PyErr_Format(PyExc_ValueError, "level %d outside 0..4", level);
    n = (npy_intp)1 << (4 * level);
    T = malloc((size_t)n * sizeof *T);
    if (!T) return PyErr_NoMemory();
    Py_BEGIN_ALLOW_THREADS
    for (npy_intp i = 0; i < n && s == WVOL_OK; i++) {
        k.level = level;
        for (int a = 0; a < 4; a++) k.m[a] = (int)(i >> (level * a) & ((1 << level) - 1));
        s = wvol_transport_coefficient(&T[i], &sq, &dq, &j, &k, &p, &err);
    }
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) {
        free(T);
        return wvolpy_raise(&err);
    }
    return wvolpy_array_take_type(T, 1, &n, NPY_DOUBLE);
}

static PyObject *stats_dict(const wvol_transport_stats *st)
{
    return Py_BuildValue("{s:n,s:n,s:n,s:n,s:d}", "evaluated", (Py_ssize_t)st->evaluated, "oracle_zero",
                         (Py_ssize_t)st->oracle_zero, "oracle_exact", (Py_ssize_t)st->oracle_exact, "samples",
                         (Py_ssize_t)st->samples, "seconds", st->seconds);
}

/* run(cells, src, dst, levels, quadrature, samples, seed, oracle) -> (destination cells, stats) */
static PyObject *py_run(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"cells", "src", "dst", "levels", "quadrature", "samples", "seed", "oracle", NULL};
    PyObject *cells, *so, *dobj, *out;
    wvol_transport_quad sq, dq;
    wvol_transport_params p;
    wvol_transport_tree *src, *dst = NULL;
    wvol_transport_stats st;
    const char *qn = "trapezoid";
    int levels = 3, samples = 16, oracle = 1;
    uint64_t seed = 1;
    PyObject *seed_obj = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOO|isiOp", kwlist, &cells, &so, &dobj, &levels, &qn, &samples, &seed_obj,
                                     &oracle) ||
        wvolpy_seed(seed_obj, &seed) < 0)
        return NULL;
    if (parse_quad(so, &sq, "src") < 0 || parse_quad(dobj, &dq, "dst") < 0) return NULL;
    if (parse_params(&p, levels, qn, samples, seed, oracle) < 0) return NULL;
    if (!(src = cells_tree(cells, 0))) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_transport_run(&dst, src, &sq, &dq, &p, &st, &err);
    Py_END_ALLOW_THREADS
    wvol_transport_tree_destroy(src);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    out = tree_cells(dst);
    wvol_transport_tree_destroy(dst);
    return out ? Py_BuildValue("NN", out, stats_dict(&st)) : NULL;
}

/* scene(levels, quadrature, samples, window=None) -> dict of cells (source, incident, reflected),
 * stats and powers */
static PyObject *py_scene(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"levels", "quadrature", "samples", "window", NULL};
    const char *qn = "trapezoid", *path = NULL;
    int levels = 3, samples = 16;
    wvol_transport_params p;
    wvol_transport_scene sc;
    wvol_transport_window w = {0};
    wvol_transport_scene_result r = {0};
    wvol_error err;
    wvol_status s;
    PyObject *a = NULL, *b = NULL, *c = NULL;
    double ps[3], pi[3], po[3];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|isiz", kwlist, &levels, &qn, &samples, &path)) return NULL;
    if (parse_params(&p, levels, qn, samples, 1, 1) < 0) return NULL;
    wvol_transport_scene_default(&sc);
    Py_BEGIN_ALLOW_THREADS
    s = path ? wvol_transport_window_read_png(&w, path, &err) : wvol_transport_window_synthetic(&w, 256, &err);
    if (s == WVOL_OK) s = wvol_transport_scene_run(&r, &sc, &w, &p, &err);
    Py_END_ALLOW_THREADS
    wvol_transport_window_free(&w);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    wvol_transport_tree_power_emitted(ps, r.source, &sc.window, NULL);
    wvol_transport_tree_power(pi, r.incident, &sc.floor, NULL);
    wvol_transport_tree_power(po, r.reflected, &sc.floor, NULL);
    if ((a = tree_cells(r.source)) && (b = tree_cells(r.incident)) && (c = tree_cells(r.reflected))) {
        PyObject *d = Py_BuildValue("{s:N,s:N,s:N,s:N,s:(ddd),s:(ddd),s:(ddd)}", "source", a, "incident", b, "reflected",
                                    c, "stats", stats_dict(&r.transport), "power_window", ps[0], ps[1], ps[2],
                                    "power_floor_in", pi[0], pi[1], pi[2], "power_floor_out", po[0], po[1], po[2]);
        wvol_transport_scene_result_free(&r);
        return d;
    }
    Py_XDECREF(a);
    Py_XDECREF(b);
    wvol_transport_scene_result_free(&r);
    return NULL;
}

/* window(path=None) -> (H, W, 3) float32 linear RGB of the window (built-in when None) */
static PyObject *py_window(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", NULL};
    const char *path = NULL;
    wvol_transport_window w = {0};
    wvol_error err;
    wvol_status s;
    npy_intp dims[3];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|z", kwlist, &path)) return NULL;
    s = path ? wvol_transport_window_read_png(&w, path, &err) : wvol_transport_window_synthetic(&w, 256, &err);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    dims[0] = w.height, dims[1] = w.width, dims[2] = 3;
    return wvolpy_array_take(w.rgb, 3, dims); /* takes w.rgb */
}

PyMethodDef wvolpy_transport_methods[] = {
    {"transport_haar", (PyCFunction)(void (*)(void))py_haar, METH_VARARGS | METH_KEYWORDS, NULL},
    {"transport_coefficients", (PyCFunction)(void (*)(void))py_coefficients, METH_VARARGS | METH_KEYWORDS, NULL},
    {"transport_run", (PyCFunction)(void (*)(void))py_run, METH_VARARGS | METH_KEYWORDS, NULL},
    {"transport_scene", (PyCFunction)(void (*)(void))py_scene, METH_VARARGS | METH_KEYWORDS, NULL},
    {"transport_window", (PyCFunction)(void (*)(void))py_window, METH_VARARGS | METH_KEYWORDS, NULL},
    {NULL, NULL, 0, NULL}};
