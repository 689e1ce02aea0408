/* SPDX-License-Identifier: MIT */
/* synth: the deterministic synthetic volumes of datasets-synth/wvol_synth.h. */
#include "pyutil.h"
#include "methods.h"
#include "wvol_synth.h"

#include <math.h>
#include <string.h>

/* synth(kind, shape=(nz, ny, nx) or None, spacing=None, seed=1, noise=0, sigma=0, count=0,
 * variant=None) -> (array, labels or None, spacing, origin) */
static PyObject *py_synth(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"kind", "shape", "spacing", "seed", "noise", "sigma", "count", "variant", NULL};
    PyObject *shape = Py_None, *sp = Py_None, *seed_obj = NULL, *a, *l = NULL;
    const char *kind, *variant = NULL;
    double noise = 0, sigma = 0;
    int count = 0, k;
    wvol_synth_params p;
    wvol_volume *v = NULL, *labels = NULL;
    wvol_error err;
    wvol_status s;
    double spv[3], orv[3];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|OOOddiz", kwlist, &kind, &shape, &sp, &seed_obj, &noise, &sigma,
                                     &count, &variant))
        return NULL;
    k = wvol_synth_kind_find(kind);
    if (k < 0) return PyErr_Format(PyExc_ValueError, "unknown synthetic volume '%s'", kind);
    wvol_synth_params_default(&p);
    wvol_synth_kind_default_dims(k, p.dims);
    if (shape != Py_None) {
        Py_ssize_t d[3];
        if (!PyArg_ParseTuple(shape, "nnn;shape must be (nz, ny, nx)", &d[2], &d[1], &d[0])) return NULL;
        for (int ax = 0; ax < 3; ax++) {
            if (d[ax] < 1) return PyErr_Format(PyExc_ValueError, "shape: every dimension must be >= 1");
            p.dims[ax] = (size_t)d[ax];
        }
    }
    if (sp != Py_None && wvolpy_triple(sp, p.spacing, "spacing") < 0) return NULL;
    if (wvolpy_seed(seed_obj, &p.seed) < 0) return NULL;
    if (!isfinite(noise) || noise < 0) return PyErr_Format(PyExc_ValueError, "noise must be finite and >= 0");
    if (!isfinite(sigma) || sigma < 0) return PyErr_Format(PyExc_ValueError, "sigma must be finite and >= 0");
    p.noise = noise;
    p.sigma = sigma;
    p.count = count;
    p.variant = variant;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_synth_make(&v, &labels, kind, &p, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) return wvolpy_raise(&err);
    memcpy(spv, v->spacing, sizeof spv);
    memcpy(orv, v->origin, sizeof orv);
    a = wvolpy_volume_take(v, 0);
    if (labels) {
        l = wvolpy_volume_take(labels, 0);
        if (!l) {
            Py_XDECREF(a);
            return NULL;
        }
    } else {
        l = Py_NewRef(Py_None);
    }
    if (!a) {
        Py_DECREF(l);
        return NULL;
    }
    return Py_BuildValue("NN(ddd)(ddd)", a, l, spv[0], spv[1], spv[2], orv[0], orv[1], orv[2]);
}

/* synth_kinds() -> list of (name, about, has_labels) */
static PyObject *py_synth_kinds(PyObject *self, PyObject *noargs)
{
    PyObject *list = PyList_New(0);
    (void)self;
    (void)noargs;
    if (!list) return NULL;
    for (int i = 0; i < wvol_synth_kind_count(); i++) {
        PyObject *t = Py_BuildValue("(ssO)", wvol_synth_kind_name(i), wvol_synth_kind_about(i),
                                    wvol_synth_kind_has_labels(i) ? Py_True : Py_False);
        if (!t || PyList_Append(list, t) < 0) {
            Py_XDECREF(t);
            Py_DECREF(list);
            return NULL;
        }
        Py_DECREF(t);
    }
    return list;
}

PyMethodDef wvolpy_synth_methods[] = {
    {"synth", (PyCFunction)(void (*)(void))py_synth, METH_VARARGS | METH_KEYWORDS,
     "synth(kind, shape=None, spacing=None, seed=1, noise=0, sigma=0, count=0, variant=None)\n"
     "-> (array, labels or None, spacing, origin)"},
    {"synth_kinds", py_synth_kinds, METH_NOARGS, "synth_kinds() -> [(name, about, has_labels)]"},
    {NULL, NULL, 0, NULL}};
