/* The store capsule, shared by py_store.c and the renderer's binding. */
#ifndef WVOL_PY_STORE_H
#define WVOL_PY_STORE_H
#include "pyutil.h"

/* The wvol_store inside a capsule made by store_build, or NULL with an exception. */
const wvol_store *wvolpy_store_from(PyObject *cap);
#endif
