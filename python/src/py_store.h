/* SPDX-License-Identifier: MIT */
/* The store handle behind wvol.Store: a Python object that owns what the library's compression
 * pipeline made (wvol_compressed: the coefficients with the dropped ones zeroed, the selection,
 * the C store, the report and the data range), so that every call on a Store passes the handle
 * and nothing is sent again. Made by compress (py_compress.c), store_open (py_codec.c) and
 * StoreHandle.replace_coeffs; read by render and isosurface. */
#ifndef WVOL_PY_STORE_H
#define WVOL_PY_STORE_H
#include "pyutil.h"
#include "wvol/compress.h"

typedef struct wvolpy_store {
    PyObject_HEAD
    wvol_compressed c;  /* c.coeffs and c.store always set */
    wvol_store *by_J[13]; /* [J]: the same kept coefficients with 2^J spline knots per unit, built
                             when a render asks for that J (kept until the handle dies: a render
                             may be reading one without the GIL) */
} wvolpy_store;

extern PyTypeObject wvolpy_store_type;

/* A new handle owning *c (emptied); on failure *c is freed and NULL returned. */
PyObject *wvolpy_store_wrap(wvol_compressed *c);
/* (handle over *c, d): takes *c and the reference d; d NULL (its making failed) frees *c. */
PyObject *wvolpy_store_with(wvol_compressed *c, PyObject *d);
/* The handle's C store with 2^J spline knots per unit (J = 0: the one the pipeline built);
 * another J builds (once) a store of the same kept coefficients. NULL with an exception. */
const wvol_store *wvolpy_store_at(wvolpy_store *h, int J);

#define WVOLPY_IS_STORE(o) PyObject_TypeCheck((o), &wvolpy_store_type)
#endif
