/* SPDX-License-Identifier: MIT */
/* wvol._wvol: the extension module. Each py_<area>.c contributes a method table, joined
 * here; py_store.c the StoreHandle type. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define PY_ARRAY_UNIQUE_SYMBOL wvol_ARRAY_API
#include <numpy/arrayobject.h>

#include "methods.h"

static PyMethodDef *tables[] = {WVOLPY_METHOD_TABLES};

static struct PyModuleDef moduledef = {PyModuleDef_HEAD_INIT, "_wvol",
                                       "Compiled core of the wvol package (use the wvol package).", -1,
                                       NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__wvol(void)
{
    PyObject *m;
    import_array();
    m = PyModule_Create(&moduledef);
    if (!m) return NULL;
    for (size_t t = 0; t < sizeof tables / sizeof tables[0]; t++)
        if (PyModule_AddFunctions(m, tables[t]) < 0) {
            Py_DECREF(m);
            return NULL;
        }
    if (wvolpy_store_ready(m) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    PyModule_AddStringConstant(m, "version", WVOL_VERSION_STRING);
    return m;
}
